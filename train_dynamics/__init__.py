"""
Longitudinal dynamics of a braking train: a ROS 2 Jazzy package (train_dynamics).

One folder per layer; a layer imports only the layers before it in this list:

- ``topics``: names and types on the wire (standard library only).
- ``physics``: the model (couplers, brakes, train, integrators, parameters, brake valve);
  never rclpy, rosbags or matplotlib.
- ``param_files``: ROS 2 parameter files (``<node>: ros__parameters:``), read alike by the
  nodes and the offline command; never rclpy or rosbags.
- ``simulation``: running the model (the time grid of outputs and inputs shared by node and
  offline command, the inputs of an offline run, the offline run loop); never rclpy, rosbags
  or matplotlib.
- ``recording``: bag reading and writing, output encoding, plots; never rclpy.
- ``ros``: the nodes ``sim_node`` and ``brake_valve``, the only place importing rclpy and
  ROS message packages; ``cli``: the ``train-dynamics`` command and ``make run``.
"""
__version__ = '0.1.0'

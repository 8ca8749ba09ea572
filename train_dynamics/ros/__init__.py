"""
The ROS 2 layer: the nodes ``sim_node`` and ``brake_valve`` and their parts.

Import rule: the only layer that imports rclpy and ROS message packages; it may import
``topics``, ``physics``, ``simulation`` and ``recording``, never ``cli``. The nodes only
declare and wire: the model and the encodings they use live in the lower layers.
"""

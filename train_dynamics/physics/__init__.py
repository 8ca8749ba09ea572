"""
The physics layer: the train model (paper eqs. 2-7, 12-18).

Couplers, brakes, train, the compiled kernel (``kernel/``: the integrators and the compiled
parts of the force laws), the parameter table and the driver's brake valve model; the run loop
that drives them is :mod:`train_dynamics.simulation`. Import rule: the standard library,
numpy, scipy, numba, PyYAML (consist files, the vehicle library) and ``train_dynamics.topics``;
never rclpy, ROS message packages, rosbags or matplotlib, nor the ``simulation``,
``recording``, ``ros`` or ``cli`` layers (nor ``param_files``: the ROS 2 parameter-file form).
"""

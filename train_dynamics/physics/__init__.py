"""
The physics layer: the train model and the offline run loop (paper eqs. 2-7, 12-18).

Couplers, brakes, train, the compiled kernel (``kernel/``: the integrators and the compiled
parts of the force laws), the parameter table, the driver's brake valve model and the run
loop. Import rule: the standard library, numpy, scipy, numba, PyYAML
(parameter files) and ``train_dynamics.topics``; never rclpy, ROS message packages, rosbags
or matplotlib, nor the ``recording``, ``ros`` or ``cli`` layers.
"""

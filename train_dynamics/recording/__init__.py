"""
The recording layer: rosbag2 MCAP reading and writing, the output encoding, the plots.

Import rule: may import ``train_dynamics.topics`` and ``train_dynamics.physics``, rosbags,
numpy and matplotlib; never rclpy or ROS message packages, nor the ``ros`` or ``cli`` layers.
"""

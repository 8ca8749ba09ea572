"""
The command-line layer: ``train-dynamics`` (offline runs) and ``make run`` (the demo).

Import rule: may import ``topics``, ``physics``, ``simulation`` and ``recording``; never
rclpy or ROS message packages, nor ``ros`` (the demo starts the nodes as processes).
"""

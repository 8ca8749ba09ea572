"""train_dynamics: longitudinal dynamics of a braking train (ROS 2 Jazzy package).

The physics core (config, couplers, brakes, train, integrators) never imports rclpy; the
node (sim_node), the brake valve and the offline command (cli) wrap it.
"""
__version__ = '0.1.0'

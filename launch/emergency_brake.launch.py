"""
The paper's emergency braking: sim_node + brake_valve with config/paper_3coach.yaml.

    ros2 launch train_dynamics emergency_brake.launch.py
    ros2 launch train_dynamics emergency_brake.launch.py params_file:=/path/to/file.yaml \
        record_bag:=/tmp/run1

Both nodes read their section of the same parameter file (``train_dynamics`` and
``brake_valve``). Needs ``ros2 launch`` (launch, launch_ros) from a ROS 2 Jazzy install.
"""
import os

from ament_index_python.packages import get_package_share_directory
from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node
from launch_ros.parameter_descriptions import ParameterValue


def generate_launch_description():
    default_params = os.path.join(get_package_share_directory('train_dynamics'), 'config',
                                  'paper_3coach.yaml')
    params_file = LaunchConfiguration('params_file')
    record_bag = LaunchConfiguration('record_bag')
    return LaunchDescription([
        DeclareLaunchArgument('params_file', default_value=default_params,
                              description='ROS 2 parameter file for both nodes'),
        DeclareLaunchArgument('record_bag', default_value='',
                              description='sim_node records a rosbag2 (MCAP) here when set'),
        Node(package='train_dynamics', executable='sim_node', name='train_dynamics',
             output='screen',
             parameters=[params_file,
                         {'record_bag': ParameterValue(record_bag, value_type=str),
                          'publish_clock': True, 'wait_for_input': 30.0}]),
        Node(package='train_dynamics', executable='brake_valve', name='brake_valve',
             output='screen', parameters=[params_file, {'use_sim_time': True}]),
    ])

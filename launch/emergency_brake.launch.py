"""
The paper's emergency braking: sim_node + brake_valve with config/paper_3coach.yaml.

    ros2 launch train_dynamics emergency_brake.launch.py
    ros2 launch train_dynamics emergency_brake.launch.py params_file:=/path/to/file.yaml \
        record_bag:=/tmp/run1 namespace:=train1

Arguments: ``params_file`` (both nodes read their section of it: ``/**/train_dynamics`` and
``/**/brake_valve``, which apply in any namespace), ``namespace`` (both nodes in it; the
simulator publishes its clock relative to it, ``/clock`` without a namespace,
``/<namespace>/clock`` with one, and the valve reads it there, so two launched trains keep
their own simulation times), ``use_sim_time`` (true: the
simulator publishes its clock and the valve runs on it; false: the valve runs on wall time)
and ``record_bag``. Needs ``ros2 launch`` (launch, launch_ros) from a ROS 2 Jazzy install.
"""
import os

from ament_index_python.packages import get_package_share_directory
from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node
from launch_ros.parameter_descriptions import ParameterValue


def generate_launch_description():
    """Return the two nodes and their arguments."""
    default_params = os.path.join(get_package_share_directory('train_dynamics'), 'config',
                                  'paper_3coach.yaml')
    params_file = LaunchConfiguration('params_file')
    namespace = LaunchConfiguration('namespace')
    sim_time = ParameterValue(LaunchConfiguration('use_sim_time'), value_type=bool)
    record_bag = ParameterValue(LaunchConfiguration('record_bag'), value_type=str)
    return LaunchDescription([
        DeclareLaunchArgument('params_file', default_value=default_params,
                              description='ROS 2 parameter file for both nodes'),
        DeclareLaunchArgument('namespace', default_value='',
                              description='namespace of both nodes (and of the clock)'),
        DeclareLaunchArgument('use_sim_time', default_value='true',
                              description='the simulator publishes its clock, the valve '
                                          'runs on it'),
        DeclareLaunchArgument('record_bag', default_value='',
                              description='sim_node records a rosbag2 (MCAP) here when set'),
        # the clock relative to the namespace: /clock without one, /<namespace>/clock with
        Node(package='train_dynamics', executable='sim_node', name='train_dynamics',
             namespace=namespace, output='screen',
             parameters=[params_file,
                         {'record_bag': record_bag, 'publish_clock': sim_time,
                          'namespaced_clock': True, 'wait_for_input': 30.0}]),
        Node(package='train_dynamics', executable='brake_valve', name='brake_valve',
             namespace=namespace, output='screen', remappings=[('/clock', 'clock')],
             parameters=[params_file, {'use_sim_time': sim_time}]),
    ])

"""ament_python build of train_dynamics (colcon build) and pip editable install (make venv)."""
from glob import glob

from setuptools import find_packages, setup

package_name = 'train_dynamics'

setup(
    name=package_name,
    version='0.1.0',
    packages=find_packages(exclude=['test', 'test.*', 'bench']),
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + package_name]),
        ('share/' + package_name, ['package.xml']),
        ('share/' + package_name + '/config', sorted(glob('config/*.yaml'))),
        ('share/' + package_name + '/launch', sorted(glob('launch/*.py'))),
    ],
    install_requires=['setuptools'],
    zip_safe=True,
    maintainer='train_dynamics maintainers',
    maintainer_email='train_dynamics@example.com',
    description='Longitudinal train dynamics with coupler friction and pneumatic brakes '
                '(ROS 2 Jazzy simulator, brake valve and offline command).',
    license='Apache-2.0',
    entry_points={
        'console_scripts': [
            'sim_node = train_dynamics.ros.sim_node:main',
            'brake_valve = train_dynamics.ros.brake_valve_node:main',
            'train-dynamics = train_dynamics.cli.offline:main',
        ],
    },
)

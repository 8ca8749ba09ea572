"""A downstream ament_python package: a brake controller on the typed messages."""
from setuptools import setup

PACKAGE = 'typed_stop_controller'

setup(
    name=PACKAGE,
    version='0.0.1',
    packages=[PACKAGE],
    data_files=[('share/ament_index/resource_index/packages', [f'resource/{PACKAGE}']),
                (f'share/{PACKAGE}', ['package.xml'])],
    install_requires=['setuptools'],
    zip_safe=True,
    description='A brake controller on train_dynamics_msgs (test support)',
    license='Apache-2.0',
    entry_points={'console_scripts': [f'stop_controller = {PACKAGE}.controller:main']},
)

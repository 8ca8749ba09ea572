"""
ament_python build of train_dynamics (colcon build) and pip editable install (make venv).

``build`` also compiles the numba kernels of the default configuration (the variant group
``paper``: fixed step, brake pipe, run metrics; ~57 s of CPU, in two processes, when nothing
is cached)
into the built package (``train_dynamics/physics/kernel/_prebuilt/numba-<code version>``, see
``physics/kernel/compiler.py``), so that the first ``ros2 run`` of such a scenario loads
machine code instead of compiling; the others (``integration_tolerance`` > 0, the pneumatic
brake) compile at their first use, into the user cache.
``develop`` (``colcon build --symlink-install``, which runs the sources) compiles them into
the user cache instead, as ``make venv`` does (``python -m train_dynamics.cli.prebuild``).
``TRAIN_DYNAMICS_PREBUILD``: unset or ``paper`` that group, ``all`` every group, ``0``
nothing (``train_dynamics.cli.prebuild.build_groups``). Each compiled function is printed as it
ends (``colcon build --event-handlers console_direct+`` shows it live). Without numba, or when
it fails, the build goes on and the kernels compile at the first start.
"""
from glob import glob
import os
import shutil
import subprocess
import sys

from setuptools import find_packages, setup
from setuptools.command.build_py import build_py
from setuptools.command.develop import develop
from setuptools.command.install_lib import install_lib

package_name = 'train_dynamics'


def prebuild(lib: str, into: str | None) -> None:
    """Run ``train_dynamics.cli.prebuild`` on the package in ``lib`` (never fails the build)."""
    if os.environ.get('TRAIN_DYNAMICS_PREBUILD') == '0':     # no need to import anything
        print('TRAIN_DYNAMICS_PREBUILD=0: the numba kernels compile at the first start')
        return
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(
        [lib] + [p for p in os.environ.get('PYTHONPATH', '').split(os.pathsep) if p]))
    # --build: the groups TRAIN_DYNAMICS_PREBUILD names (the rule: cli/prebuild.py)
    result = subprocess.run([sys.executable, '-m', f'{package_name}.cli.prebuild', '--build']
                            + (['--into', into] if into else []),
                            cwd=lib, env=env, check=False)
    if result.returncode != 0:
        print('WARNING: the numba kernels were not compiled at build time (see above): '
              'the first start compiles them', file=sys.stderr)


class BuildPyPrebuild(build_py):
    """build_py that then compiles the kernels of the built copy into it."""

    def run(self):
        """Build the package, then compile its kernels into ``physics/kernel/_prebuilt``."""
        super().run()
        if not (getattr(self, 'editable_mode', False) or self.dry_run):
            lib = os.path.abspath(self.build_lib)
            prebuild(lib, os.path.join(lib, package_name, 'physics', 'kernel', '_prebuilt'))


class InstallLibPrebuilt(install_lib):
    """install_lib that drops the kernels of earlier code versions from the install."""

    def run(self):
        """Install the built package, then keep only the ``_prebuilt`` versions just built."""
        super().run()
        sub = os.path.join(package_name, 'physics', 'kernel', '_prebuilt')
        built, installed = (os.path.join(d, sub) for d in (self.build_dir, self.install_dir))
        if os.path.isdir(built) and os.path.isdir(installed) and not self.dry_run:
            keep = set(os.listdir(built))
            for name in os.listdir(installed):
                if name.startswith('numba-') and name not in keep:
                    shutil.rmtree(os.path.join(installed, name), ignore_errors=True)


class DevelopPrebuild(develop):
    """develop (``colcon build --symlink-install``) that then fills the user cache."""

    def run(self):
        """Link the sources, then compile their kernels into the user cache."""
        super().run()
        if not (self.uninstall or self.dry_run):
            prebuild(os.path.dirname(os.path.abspath(__file__)), None)


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
    # colcon test runs pytest only for a package that declares it as a test dependency
    extras_require={'test': ['pytest']},
    zip_safe=False,
    cmdclass={'build_py': BuildPyPrebuild, 'develop': DevelopPrebuild,
              'install_lib': InstallLibPrebuilt},
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

"""
The ROS 2 workspace path: build with colcon, run what ``ros2 run`` runs.

``colcon build`` of the package in a fresh workspace, then ``source install/setup.bash`` and
start the installed executables where ``ros2 run`` looks
(``get_package_prefix('train_dynamics')/lib/train_dynamics/<exe>``).

Uses the colcon of the running virtual environment (requirements.txt pins it). The installed
``sim_node`` and ``brake_valve`` run together over DDS (loopback, the session's domain): the
test sees ``couplers`` and ``brake_pipe/pressure`` messages, then stops both with SIGINT /
SIGTERM and expects a clean exit.

The build compiles the numba kernels of the default configuration into the installed package
(``setup.py build``, see ``physics/kernel/compiler.py``), and no other group: the installed
executables start with an empty user cache (``TRAIN_DYNAMICS_CACHE_DIR``) and must not compile
anything for the paper's scenario, i.e. write nothing there.
"""
from __future__ import annotations

import os
from pathlib import Path
import shutil
import signal
import subprocess
import sys

import pytest

REPO = Path(__file__).resolve().parents[2]
PACKAGE_FILES = ['package.xml', 'setup.py', 'setup.cfg', 'resource', 'train_dynamics',
                 'config', 'launch', 'README.md']
EXECUTABLES = ['sim_node', 'brake_valve', 'train-dynamics']
_IGNORE = shutil.ignore_patterns('__pycache__', '*.pyc', '*.nbi', '*.nbc', '*.egg-info')


def _copy_package(dest: Path) -> None:
    """Copy only the package's own files (no .venv, build, install, tests)."""
    dest.mkdir(parents=True)
    for name in PACKAGE_FILES:
        src = REPO / name
        if src.is_dir():
            shutil.copytree(src, dest / name, ignore=_IGNORE)
        elif src.exists():
            shutil.copy2(src, dest / name)


def _sourced_env(ws: Path, base_env: dict) -> dict:
    """Return the environment after ``source install/setup.bash`` in ``ws``."""
    out = subprocess.run(['bash', '-c', 'source install/setup.bash && env -0'], cwd=ws,
                         env=base_env, capture_output=True, timeout=60)
    assert out.returncode == 0, out.stderr.decode(errors='replace')
    env = {}
    for item in out.stdout.split(b'\0'):
        if b'=' in item:
            key, _, value = item.partition(b'=')
            env[key.decode()] = value.decode(errors='replace')
    return env


def _stop(proc: subprocess.Popen, sig: int, timeout: float = 20.0) -> int:
    if proc.poll() is None:
        proc.send_signal(sig)
    try:
        return proc.wait(timeout=timeout)
    except subprocess.TimeoutExpired:
        proc.kill()
        proc.wait()
        raise


@pytest.fixture(scope='module')
def workspace(tmp_path_factory):
    """Build the package in a colcon workspace, once per module."""
    if shutil.which('bash') is None:
        pytest.skip('bash is needed to source install/setup.bash')
    venv_bin = Path(sys.executable).parent
    colcon = venv_bin / 'colcon'
    assert colcon.exists(), f'colcon not found next to {sys.executable} (see requirements.txt)'
    ws = tmp_path_factory.mktemp('colcon_ws')
    _copy_package(ws / 'src' / 'train_dynamics')
    env = dict(os.environ)
    env['PATH'] = f'{venv_bin}{os.pathsep}{env.get("PATH", "")}'
    env.pop('PYTHONPATH', None)
    env.pop('AMENT_PREFIX_PATH', None)
    env.pop('COLCON_PREFIX_PATH', None)
    env.pop('TRAIN_DYNAMICS_PREBUILD', None)          # the build compiles the kernels
    build = subprocess.run([str(colcon), 'build', '--base-paths', 'src'], cwd=ws, env=env,
                           capture_output=True, text=True, timeout=600)
    assert build.returncode == 0, f'colcon build failed:\n{build.stdout}\n{build.stderr}'
    env = _sourced_env(ws, env)
    # the first start after the install: an empty user cache (whatever the build used)
    env['TRAIN_DYNAMICS_CACHE_DIR'] = str(ws / 'user_cache')
    env.pop('NUMBA_DISABLE_JIT', None)
    return ws, env


def _compiled_at_run_time(ws: Path) -> list[str]:
    """Return the kernel cache files the installed executables wrote (they compiled those)."""
    return sorted(p.name for p in (ws / 'user_cache').rglob('*') if p.is_file())


def test_colcon_build_installs_where_ros2_run_looks(workspace):
    ws, env = workspace
    probe = subprocess.run(
        [sys.executable, '-c',
         'from ament_index_python import get_package_prefix, get_package_share_directory\n'
         'import train_dynamics\n'
         "print(get_package_prefix('train_dynamics'))\n"
         "print(get_package_share_directory('train_dynamics'))\n"
         'print(train_dynamics.__file__)'],
        cwd=ws, env=env, capture_output=True, text=True, timeout=60)
    assert probe.returncode == 0, probe.stderr
    prefix, share, module_file = probe.stdout.split()
    install = (ws / 'install').resolve()
    assert Path(prefix).resolve() == install / 'train_dynamics'
    # the sourced environment imports the installed copy, not the source tree
    assert Path(module_file).resolve().is_relative_to(install), module_file
    assert (Path(share) / 'package.xml').is_file()
    for cfg in (REPO / 'config').glob('*.yaml'):
        assert (Path(share) / 'config' / cfg.name).is_file(), cfg.name
    for launch in (REPO / 'launch').glob('*.py'):
        assert (Path(share) / 'launch' / launch.name).is_file(), launch.name
    for exe in EXECUTABLES:
        path = Path(prefix) / 'lib' / 'train_dynamics' / exe
        assert path.is_file() and os.access(path, os.X_OK), f'{exe} not installed at {path}'


def test_build_prebuilds_the_kernels_of_the_installed_sources(workspace):
    ws, env = workspace
    probe = subprocess.run(
        [sys.executable, '-c',
         'from train_dynamics.physics.kernel import compiler\n'
         'print(compiler.prebuilt_dir())'],
        cwd=ws, env=env, capture_output=True, text=True, timeout=60)
    assert probe.returncode == 0, probe.stderr
    prebuilt = Path(probe.stdout.strip())
    assert prebuilt.resolve().is_relative_to((ws / 'install').resolve()), prebuilt
    # the folder named after the installed sources' digest holds the chain kernel
    assert list(prebuilt.glob('fixed_step.advance_chain-*.nbi')), prebuilt
    assert list(prebuilt.glob('fixed_step.advance_chain-*.nbc')), prebuilt
    # the build compiled (or loaded) only the default configuration's group: the
    # error-controlled driver and the pneumatic brake compile at their first use (a build of
    # every group took 9-29 min on 2 cores); what the user cache already held of this code
    # version is copied along
    log = (ws / 'log' / 'latest_build' / 'train_dynamics' / 'stdout.log').read_text()
    assert 'train_dynamics: kernels (paper) ready in ' in log, log[-2000:]


def test_installed_offline_command_starts_warm(workspace, tmp_path):
    ws, env = workspace
    exe = ws / 'install' / 'train_dynamics' / 'lib' / 'train_dynamics' / 'train-dynamics'
    params = ws / 'install' / 'train_dynamics' / 'share' / 'train_dynamics' / 'config'
    out = subprocess.run([str(exe), 'simulate', '--params', str(params / 'paper_3coach.yaml'),
                          '--duration', '0.2', '--output', str(tmp_path / 'run'), '-q'],
                         cwd=ws, env=env, capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr
    assert (tmp_path / 'run').is_dir()
    assert _compiled_at_run_time(ws) == []


def test_installed_offline_command_runs(workspace):
    ws, env = workspace
    exe = ws / 'install' / 'train_dynamics' / 'lib' / 'train_dynamics' / 'train-dynamics'
    out = subprocess.run([str(exe), '--help'], cwd=ws, env=env, capture_output=True,
                         text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    assert 'simulate' in out.stdout and 'plot' in out.stdout


def _run_installed(ws, env, nodes, spin_until, want_couplers):
    """Start installed executables ``nodes`` {name: args}; wait for their messages; stop them."""
    from rclpy.node import Node
    from rclpy.qos import QoSProfile, ReliabilityPolicy
    from sensor_msgs.msg import FluidPressure, JointState

    lib = ws / 'install' / 'train_dynamics' / 'lib' / 'train_dynamics'
    logs, procs = {}, {}
    listener = Node('colcon_test_listener')
    couplers, pressures = [], []
    qos = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE)
    listener.create_subscription(JointState, 'couplers', couplers.append, qos)
    listener.create_subscription(FluidPressure, 'brake_pipe/pressure', pressures.append, qos)
    try:
        for name, args in nodes.items():
            logs[name] = open(ws / f'{name}.log', 'w+')
            procs[name] = subprocess.Popen([str(lib / name), *args], cwd=ws, env=env,
                                           stdout=logs[name], stderr=subprocess.STDOUT)
        # generous: should the build not have compiled the kernels, sim_node compiles them
        # on its first start (~30 s on a loaded 2-core machine; the test then fails below)
        ok = spin_until(listener, lambda: len(pressures) >= 5 and (
            len(couplers) >= 5 or not want_couplers), timeout=150.0)
        for name, proc in procs.items():
            assert proc.poll() is None, f'{name} exited early ({proc.returncode})'
        assert ok, f'messages: couplers {len(couplers)}, brake_pipe/pressure {len(pressures)}'
        # SIGINT for one, SIGTERM for the other: both must end cleanly (exit code 0)
        for name, sig in zip(procs, (signal.SIGINT, signal.SIGTERM)):
            assert _stop(procs[name], sig) == 0, f'{name} did not stop cleanly on {sig!r}'
        return couplers, pressures
    finally:
        for proc in procs.values():
            if proc.poll() is None:
                proc.kill()
                proc.wait()
        listener.destroy_node()
        for name, fh in logs.items():
            fh.seek(0)
            sys.stdout.write(f'--- {name} output ---\n{fh.read()[-4000:]}\n')
            fh.close()


def test_installed_brake_valve_publishes(workspace, rclpy_context, spin_until):
    ws, env = workspace
    _, pressures = _run_installed(
        ws, env, {'brake_valve': ['--ros-args', '-p', 'atmospheric_pressure:=100000.0']},
        spin_until, want_couplers=False)
    # release position: 5 bar gauge, published absolute with the given atmospheric pressure
    assert all(m.fluid_pressure == 600000.0 for m in pressures)


def test_installed_sim_node_runs_with_brake_valve(workspace, rclpy_context, spin_until):
    ws, env = workspace
    couplers, pressures = _run_installed(ws, env, {
        'sim_node': ['--ros-args', '-p', 'real_time_factor:=0.0', '-p', 'publish_rate:=50.0'],
        'brake_valve': ['--ros-args', '-p', 'schedule:=["0.5:emergency"]'],
    }, spin_until, want_couplers=True)
    msg = couplers[-1]
    assert list(msg.name) == ['coupler_1', 'coupler_2']                # paper's 3 coaches
    # the first start after the install loaded the build's kernels: it compiled nothing
    assert _compiled_at_run_time(ws) == []
    assert len(msg.position) == len(msg.velocity) == len(msg.effort) == 2
    # absolute Pa, between the vented (atmospheric) and the charged pipe, venting only
    values = [m.fluid_pressure for m in pressures]
    assert all(101325.0 - 1e-6 <= v <= 601325.0 + 1e-6 for v in values), values
    assert all(b <= a + 1e-6 for a, b in zip(values, values[1:])), values


def test_launch_files_name_installed_executables():
    """launch/*.py (needs ros2 launch, not in the venv): compiles, starts only our executables."""
    import ast
    import re

    for path in sorted((REPO / 'launch').glob('*.py')):
        source = path.read_text()
        ast.parse(source, filename=str(path))
        executables = re.findall(r"executable='([^']+)'", source)
        assert executables, path.name
        assert set(executables) <= set(EXECUTABLES), executables
        for cfg in re.findall(r"'(\w+\.yaml)'", source):
            assert (REPO / 'config' / cfg).is_file(), cfg

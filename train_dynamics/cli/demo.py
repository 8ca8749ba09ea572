"""
``make run``: the paper's emergency braking through the real ROS 2 nodes.

    python -m train_dynamics.cli.demo [--rtf 1.0] [--duration 60] [--out out] [--no-plot]

Starts ``brake_valve`` and then ``sim_node`` as two processes talking over DDS on loopback
(``ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST``; ``ROS_DOMAIN_ID`` from the environment, else one
in 70..100), both with ``config/paper_3coach.yaml``: three 45 t coaches at 160 km/h, the brake
valve in release and in emergency at t = 1 s. The valve runs on the simulator's clock
(``publish_clock`` / ``use_sim_time``) and the simulator holds t = 0 until the valve is
connected (``wait_for_input``), so the emergency comes at t = 1 s of simulation time whatever
the real-time factor and however long DDS discovery takes. ``sim_node`` records its inputs and
outputs to ``<out>/run_<timestamp>/bag`` and stops by itself after ``--duration`` simulated
seconds (60 s: the train stops after about 50 s); the demo then draws the paper's figures into
``<out>/run_<timestamp>/plots`` and prints where everything is. Ctrl-C stops both nodes cleanly
(the bag is closed and still plotted).
"""
from __future__ import annotations

import argparse
from datetime import datetime
import os
from pathlib import Path
import random
import selectors
import signal
import subprocess
import sys
import threading
import time

PARAM_FILE = 'paper_3coach.yaml'


def param_file() -> Path:
    """Return config/paper_3coach.yaml: from the installed package share, else the source tree."""
    try:
        # only a colcon install has an ament index; the source tree works without it
        from ament_index_python.packages import get_package_share_directory

        path = Path(get_package_share_directory('train_dynamics')) / 'config' / PARAM_FILE
        if path.is_file():
            return path
    except Exception:  # noqa: BLE001 - not installed with colcon / no ament index
        pass
    return Path(__file__).resolve().parents[2] / 'config' / PARAM_FILE


def _node_cmd(module: str, args: list[str]) -> list[str]:
    return [sys.executable, '-m', f'train_dynamics.{module}', '--ros-args', *args]


def _stop(proc: subprocess.Popen, timeout: float = 10.0) -> int | None:
    """SIGINT, then SIGTERM, then SIGKILL; returns the exit status."""
    for sig in (signal.SIGINT, signal.SIGTERM):
        if proc.poll() is not None:
            return proc.returncode
        proc.send_signal(sig)
        try:
            return proc.wait(timeout)
        except subprocess.TimeoutExpired:
            pass
    proc.kill()
    return proc.wait()


def _wait_for_line(proc: subprocess.Popen, needle: str, timeout: float) -> bool:
    """Echo the process's stderr until a line contains ``needle``; False on timeout/exit."""
    sel = selectors.DefaultSelector()
    sel.register(proc.stderr, selectors.EVENT_READ)
    end = time.monotonic() + timeout
    try:
        while time.monotonic() < end:
            if not sel.select(timeout=0.2):
                if proc.poll() is not None:
                    return False
                continue
            line = proc.stderr.readline()
            if not line:
                return False
            sys.stderr.write(line)
            if needle in line:
                return True
        return False
    finally:
        sel.close()


def _pump(proc: subprocess.Popen) -> None:
    """Forward the rest of a process's stderr (a daemon thread)."""
    def run():
        for line in proc.stderr:
            sys.stderr.write(line)
    threading.Thread(target=run, daemon=True).start()


def _arguments(argv: list[str] | None) -> argparse.Namespace:
    ap = argparse.ArgumentParser(prog='python -m train_dynamics.cli.demo',
                                 description="The paper's emergency braking through sim_node "
                                             'and brake_valve (DDS on loopback), recorded and '
                                             'plotted.')
    ap.add_argument('--rtf', type=float, default=1.0,
                    help='real_time_factor of sim_node (default 1: real time; 0: as fast as '
                         'possible)')
    ap.add_argument('--duration', type=float, default=60.0,
                    help='simulated seconds (default 60; the train stops after ~50 s)')
    ap.add_argument('--out', default='out', help='output directory (default ./out)')
    ap.add_argument('--params', default=None,
                    help=f'parameter file for both nodes (default config/{PARAM_FILE})')
    ap.add_argument('--no-plot', action='store_true', help='do not draw the figures')
    args = ap.parse_args(argv)
    if not args.rtf >= 0.0 or not args.duration > 0.0:
        ap.error('--rtf must be >= 0 and --duration > 0')
    return args


def _run_dir(out: str) -> Path:
    """Create and return ``<out>/run_<timestamp>[_k]``."""
    run_dir = Path(out) / f'run_{datetime.now():%Y%m%d_%H%M%S}'
    k = 1
    while run_dir.exists():
        run_dir = Path(out) / f'run_{datetime.now():%Y%m%d_%H%M%S}_{k}'
        k += 1
    run_dir.mkdir(parents=True)
    return run_dir


def _run_nodes(valve_cmd: list[str], sim_cmd: list[str], env: dict,
               args: argparse.Namespace) -> tuple[int, bool, bool]:
    """
    Start the valve, then the simulator; wait for the simulator; stop both.

    Return (exit status, interrupted, whether the simulator was started).
    """
    valve = sim = None
    interrupted = False
    code = 0
    try:
        valve = subprocess.Popen(valve_cmd, env=env, stderr=subprocess.PIPE, text=True)
        if not _wait_for_line(valve, 'brake valve:', 60.0):
            print('run_demo: brake_valve did not start', file=sys.stderr)
            return 1, False, False
        _pump(valve)
        sim = subprocess.Popen(sim_cmd, env=env, stderr=subprocess.PIPE, text=True)
        if not _wait_for_line(sim, 'started:', 60.0):
            print('run_demo: sim_node did not start', file=sys.stderr)
            code = 1
        else:
            _pump(sim)
            wall = args.duration / args.rtf if args.rtf > 0 else None
            print(f'run_demo: simulating {args.duration:g} s'
                  + (f' (about {wall:.0f} s of wall time)' if wall else ' as fast as possible')
                  + '; Ctrl-C stops early', flush=True)
            code = sim.wait()
            if code != 0:
                print(f'run_demo: sim_node exited with status {code}', file=sys.stderr)
    except KeyboardInterrupt:
        interrupted = True
        print('\nrun_demo: interrupted, stopping the nodes', file=sys.stderr)
    finally:
        for proc in (sim, valve):
            if proc is not None:
                _stop(proc)
    return code, interrupted, sim is not None


def _plot(bag: Path, plots: Path) -> int:
    """Draw the paper's figures of ``bag`` into ``plots``; return 1 if that failed."""
    try:
        # optional and heavy (matplotlib): only when plotting
        from train_dynamics.recording.plots import plot_bag
    except ImportError:
        print('plots: train_dynamics.recording.plots is not available')
        return 0
    try:
        paths = plot_bag(bag, plots, title='Emergency braking (sim_node + brake_valve)')
    except Exception as exc:  # noqa: BLE001 - the run itself succeeded
        print(f'plots: failed: {exc}', file=sys.stderr)
        return 1
    print(f'plots: {plots.resolve()}')
    for p in paths:
        print(f'       {Path(p).name}')
    return 0


def main(argv: list[str] | None = None) -> int:
    """Run the demo; return the exit status (130 after Ctrl-C)."""
    args = _arguments(argv)
    params = Path(args.params) if args.params else param_file()
    if not params.is_file():
        print(f'run_demo: parameter file not found: {params}', file=sys.stderr)
        return 2
    run_dir = _run_dir(args.out)
    bag = run_dir / 'bag'

    env = dict(os.environ)
    env['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'     # never discover beyond this host
    env.setdefault('ROS_DOMAIN_ID', str(random.randint(70, 100)))
    env.setdefault('PYTHONUNBUFFERED', '1')
    print(f'run_demo: ROS_DOMAIN_ID={env["ROS_DOMAIN_ID"]}, discovery on localhost only; '
          f'parameters {params}', flush=True)

    valve_cmd = _node_cmd('ros.brake_valve_node',
                          ['--params-file', str(params), '-p', 'use_sim_time:=true'])
    sim_cmd = _node_cmd('ros.sim_node',
                        ['--params-file', str(params), '-p', f'record_bag:={bag}',
                         '-p', f'real_time_factor:={float(args.rtf)!r}',
                         '-p', f'duration:={float(args.duration)!r}',
                         '-p', 'publish_clock:=true', '-p', 'wait_for_input:=30.0'])
    code, interrupted, started = _run_nodes(valve_cmd, sim_cmd, env, args)
    if not started:
        return code or 1

    print(f'\nbag:   {bag.resolve()}')
    if bag.exists() and not args.no_plot:
        code = code or _plot(bag, run_dir / 'plots')
    print(f'\nReplay offline: train-dynamics simulate --params {params} --input {bag} '
          f'--duration {args.duration:g} --output {run_dir / "offline"}')
    return 130 if interrupted else code


if __name__ == '__main__':
    sys.exit(main())

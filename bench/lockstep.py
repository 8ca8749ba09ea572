"""
Lock-step overhead: closed-loop periods per second with the example controller over DDS.

``sim_node`` (100 vehicles, outputs at 100 Hz, ``real_time_factor`` 0) in ``sync_mode``
lockstep beside ``examples/pi_brake_controller.py``, each in its own process, for
:data:`DURATION` s of simulation time; the same node in ``free`` mode without a controller
for comparison (the simulation alone). Figures from the node's log: the wall time from the
controller connected (lock-step) or the start (free) to the end, the periods answered and the
round trip per period (output published -> its answer seen by the simulation thread). Target:
at least 10x real time, i.e. 1000 closed-loop periods per second.

Writes ``bench/results/lockstep_results.md`` (its section of RESULTS.md, between its markers).
"""
from __future__ import annotations

import argparse
import os
from pathlib import Path
import re
import subprocess
import sys

HERE = Path(__file__).resolve().parent
REPO = HERE.parent
sys.path.insert(0, str(REPO))

from results_md import saved_section, splice_section  # noqa: E402

LOCKSTEP_MD = HERE / 'results' / 'lockstep_results.md'
LOCKSTEP_BEGIN = '<!-- lockstep:begin (written by bench/lockstep.py) -->'
LOCKSTEP_END = '<!-- lockstep:end -->'
RESULTS = HERE / 'RESULTS.md'
N_VEHICLES = 100
DURATION = 20.0          # [s simulated]: 2000 periods at 100 Hz
TARGET = 1000.0          # closed-loop periods per wall second
_STAMP = re.compile(r'\[(?:INFO|WARN)\] \[(\d+\.\d+)\] \[[^\]]*\]: (.*)')


def log(msg: str) -> None:
    print(msg, file=sys.stderr, flush=True)


def _node_cmd(mode: str, bag: str = '') -> list[str]:
    cmd = [sys.executable, '-m', 'train_dynamics.ros.sim_node', '--ros-args',
           '-p', f'num_coaches:={N_VEHICLES}', '-p', 'real_time_factor:=0.0',
           '-p', f'duration:={DURATION}', '-p', f'sync_mode:={mode}']
    return cmd + (['-p', f'record_bag:={bag}'] if bag else [])


def _lines(text: str) -> list[tuple[float, str]]:
    return [(float(m.group(1)), m.group(2)) for m in map(_STAMP.search, text.splitlines()) if m]


def _wall(lines: list[tuple[float, str]], start: str) -> float:
    t0 = next(t for t, msg in lines if msg.startswith(start))
    t1 = next(t for t, msg in lines if msg.startswith('duration reached'))
    return t1 - t0


def run_free() -> dict:
    """Return the wall time of the simulation alone (free, rtf 0, no controller)."""
    out = subprocess.run(_node_cmd('free'), capture_output=True, text=True, timeout=600,
                         cwd=REPO, env=dict(os.environ, PYTHONPATH=str(REPO)))
    wall = _wall(_lines(out.stderr + out.stdout), 'started')
    return {'wall_s': wall, 'periods_per_s': DURATION * 100 / wall}


def run_lockstep() -> dict:
    """Return the lock-step closed loop's figures (with the PI controller)."""
    env = dict(os.environ, PYTHONPATH=str(REPO))
    ctl = subprocess.Popen([sys.executable, str(REPO / 'examples' / 'pi_brake_controller.py')],
                           env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        out = subprocess.run(_node_cmd('lockstep'), capture_output=True, text=True,
                             timeout=600, cwd=REPO, env=env)
    finally:
        ctl.terminate()
        ctl.wait(10)
    lines = _lines(out.stderr + out.stdout)
    wall = _wall(lines, 'lockstep: controller connected')
    end = next(msg for _, msg in lines if msg.startswith('duration reached'))
    m = re.search(r'(\d+) periods answered, round trip mean ([\d.]+) ms, max ([\d.]+) ms', end)
    periods = int(m.group(1))
    return {'wall_s': wall, 'periods': periods, 'periods_per_s': periods / wall,
            'round_trip_mean_ms': float(m.group(2)), 'round_trip_max_ms': float(m.group(3))}


def render(res: dict) -> str:
    free, ls = res['free'], res['lockstep']
    ok = ls['periods_per_s'] >= TARGET
    per_period = (ls['wall_s'] - free['wall_s']) / ls['periods'] * 1e3
    return '\n'.join([
        '## Lock-step closed loop over DDS (bench/lockstep.py)', '',
        f'`sim_node` with {N_VEHICLES} vehicles, outputs at 100 Hz, `real_time_factor` 0, '
        f'{DURATION:g} s of simulation time; `examples/pi_brake_controller.py` in its own '
        'process answering every output (lock-step); the free run is the simulation alone. '
        f'Machine: {os.cpu_count()} cores, load {res["load"]:.2f} at the start.', '',
        '| run | periods | wall [s] | periods/s | x real time | round trip mean [ms] | '
        'round trip max [ms] |',
        '| --- | ---: | ---: | ---: | ---: | ---: | ---: |',
        f'| free, no controller | {DURATION * 100:.0f} | {free["wall_s"]:.2f} | '
        f'{free["periods_per_s"]:.0f} | {free["periods_per_s"] / 100:.1f} | - | - |',
        f'| lock-step with the PI controller | {ls["periods"]} | {ls["wall_s"]:.2f} | '
        f'{ls["periods_per_s"]:.0f} | {ls["periods_per_s"] / 100:.1f} | '
        f'{ls["round_trip_mean_ms"]:.3f} | {ls["round_trip_max_ms"]:.3f} |', '',
        f'Lock-step overhead: {per_period:.3f} ms per period. Target >= {TARGET:.0f} closed-loop '
        f'periods/s (10x real time): {"met" if ok else "NOT met"}.'])


def lockstep_section() -> str:
    """Return the lock-step section for RESULTS.md (the last ``bench/lockstep.py`` run)."""
    return saved_section(LOCKSTEP_MD, LOCKSTEP_BEGIN, LOCKSTEP_END,
                         '## Lock-step closed loop over DDS (bench/lockstep.py)')


def run_and_write(log=log, write: bool = True) -> str:
    log(f'lockstep: {N_VEHICLES} vehicles, 100 Hz, free and with the PI controller')
    res = {'load': os.getloadavg()[0], 'free': run_free(), 'lockstep': run_lockstep()}
    text = render(res)
    if write:
        LOCKSTEP_MD.write_text(f'{LOCKSTEP_BEGIN}\n{text}\n{LOCKSTEP_END}\n')
    return text


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.strip().splitlines()[0])
    ap.add_argument('--no-write', action='store_true', help='print only')
    args = ap.parse_args(argv)
    text = run_and_write(write=not args.no_write)
    print(text)
    if not args.no_write:
        splice_section(str(RESULTS), LOCKSTEP_BEGIN, LOCKSTEP_END, text)
    return 0


if __name__ == '__main__':
    sys.exit(main())

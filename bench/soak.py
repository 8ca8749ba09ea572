"""
`make soak`: one hour of simulated time, 30 coaches, free-running, recorded.

``sim_node`` runs as a child process with ``num_coaches:=30 real_time_factor:=0.0
publish_rate:=100.0 duration:=3600.0 record_bag:=<tmp>/soak_bag``; as soon as its first output
arrives this process vents the head brake pipe (emergency, ``brake_pipe/pressure`` =
atmospheric absolute), so the run covers braking, the train at rest held by its brakes, and an
hour of steady output. The node stops by itself at t = duration (its convention: outputs at
t_j = j / publish_rate up to and including t = duration, so duration * rate + 1 messages per
output topic) and closes the bag; this process follows the simulated time through the
``couplers`` stamps it receives and samples the node's RSS every 0.5 s.

Reported (bench/results/soak_results.md, also spliced into bench/RESULTS.md):
- node RSS at the first output, at every 10 min of simulated time and at the end (flat?);
- wall time and the achieved free-running speed; exit status;
- stamps seen by the subscriber: monotonic;
- the bag: per topic, message count and stamps strictly increasing in steps of 1/rate, bag
  times monotonic, and each output topic holding exactly duration * rate + 1 messages
  stamped 0 .. duration.

Usage: ``python bench/soak.py [--hours 1.0] [--coaches 30] [--keep-bag]``.
"""
from __future__ import annotations

import argparse
import datetime
import json
import os
import shutil
import sys
import tempfile
import time

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
sys.path.insert(1, os.path.dirname(HERE))

import nodeutil as U  # noqa: E402
from results_md import splice_section  # noqa: E402

SOAK_MD = os.path.join(HERE, 'results', 'soak_results.md')
SOAK_JSON = os.path.join(HERE, 'results', 'soak_last.json')
RESULTS = os.path.join(HERE, 'RESULTS.md')
SOAK_BEGIN = '<!-- soak:begin (written by bench/soak.py) -->'
SOAK_END = '<!-- soak:end -->'


def log(msg: str) -> None:
    print(f'[soak {time.strftime("%H:%M:%S")}] {msg}', file=sys.stderr, flush=True)


def check_bag(path: str, rate: float) -> dict:
    """Per topic: count, stamps (header) strictly increasing by 1/rate, bag times monotonic."""
    from rosbags.rosbag2 import Reader
    step_ns = int(round(1e9 / rate))
    out = {}
    with Reader(path) as reader:
        for conn in reader.connections:
            out.setdefault(conn.topic, {'type': conn.msgtype, 'count': 0})
        state = {}
        for conn, t_ns, raw in reader.messages():
            d = out[conn.topic]
            d['count'] += 1
            st = state.setdefault(conn.topic, {'last_t': None, 'last_stamp': None,
                                               'first_stamp': None, 'bag_non_monotonic': 0,
                                               'stamp_non_monotonic': 0, 'stamp_bad_step': 0})
            if st['last_t'] is not None and t_ns < st['last_t']:
                st['bag_non_monotonic'] += 1
            st['last_t'] = t_ns
            st.setdefault('first_t', t_ns)
            if conn.msgtype in ('sensor_msgs/msg/JointState', 'sensor_msgs/msg/FluidPressure',
                                'diagnostic_msgs/msg/DiagnosticArray'):
                stamp = U.cdr_stamp_ns(raw)
                if st['first_stamp'] is None:
                    st['first_stamp'] = stamp
                if st['last_stamp'] is not None:
                    if stamp <= st['last_stamp']:
                        st['stamp_non_monotonic'] += 1
                    elif conn.msgtype == 'sensor_msgs/msg/JointState' and \
                            stamp - st['last_stamp'] != step_ns:
                        st['stamp_bad_step'] += 1
                st['last_stamp'] = stamp
        for topic, st in state.items():
            out[topic].update(st)
    return out


def run(hours: float = 1.0, coaches: int = 30, rate: float = 100.0, keep_bag: bool = False,
        extra_params: dict | None = None) -> dict:
    U.ros_env()
    sim_end = hours * 3600.0
    tmpdir = tempfile.mkdtemp(prefix='td_soak_')
    bag = os.path.join(tmpdir, 'soak_bag')
    params = {'num_coaches': coaches, 'publish_rate': float(rate), 'real_time_factor': 0.0,
              'duration': float(sim_end), 'record_bag': bag}
    params.update(extra_params or {})
    lst = U.Listener('bench_soak_listener', record=False, qos_depth=100)
    lst.start()
    proc, t_popen = U.start_node(params, os.path.join(tmpdir, 'sim_node.log'))
    res = {'hours': hours, 'coaches': coaches, 'rate': rate, 'params': params,
           'domain': os.environ.get('ROS_DOMAIN_ID'), 'tmpdir': tmpdir,
           'date': datetime.datetime.now(datetime.timezone.utc).strftime('%Y-%m-%d %H:%M UTC'),
           'load_before': os.getloadavg()[0]}
    samples = []          # (wall since first output [s], sim time [s], RSS [KiB], cpu [s])
    try:
        deadline = time.monotonic() + 60.0
        while lst.first_arrival is None:
            if proc.poll() is not None:
                raise RuntimeError(f'sim_node exited with {proc.returncode}: '
                                   + open(os.path.join(tmpdir, 'sim_node.log')).read()[-3000:])
            if time.monotonic() > deadline:
                raise RuntimeError('no output within 60 s')
            time.sleep(0.001)
        w0 = time.monotonic()
        res['startup_s'] = w0 - t_popen
        lst.publish_head_pressure(0.0)
        log(f'first output after {res["startup_s"]:.2f} s; emergency sent; '
            f'running to {sim_end:.0f} s of simulated time')
        next_log = 0.0
        end_seen = None
        cpu_last = 0.0
        while True:
            sim_t = max(lst.last_stamp_ns, 0) * 1e-9
            rss = U.proc_rss_kib(proc.pid)
            cpu = U.proc_cpu_seconds(proc.pid)
            if rss is not None:
                backlog = lst.diag.get('train_dynamics: simulation/record_backlog')
                samples.append((time.monotonic() - w0, sim_t, rss, cpu, backlog))
                res['hwm_kib'] = max(U.proc_rss_kib(proc.pid, 'VmHWM') or 0,
                                     res.get('hwm_kib') or 0, rss)
                cpu_last = cpu if cpu is not None else cpu_last
            if sim_t >= next_log:
                log(f'sim t = {sim_t:7.0f} s, RSS {(rss or 0) / 1024:.1f} MiB, '
                    f'received {lst.count}')
                next_log += 600.0
            if proc.poll() is not None:      # the node stops by itself at t = duration
                break
            if sim_t >= sim_end and end_seen is None:
                end_seen = time.monotonic()
            if end_seen is not None and time.monotonic() - end_seen > 60.0:
                log('the node did not stop by itself 60 s after t = duration: SIGINT')
                break
            time.sleep(0.5)
        res['wall_s'] = time.monotonic() - w0
        res['cpu_s'] = cpu_last
        res['rss_end_kib'] = samples[-1][2] if samples else None
        time.sleep(0.5)
        res['diagnostics'] = dict(lst.diag)
    finally:
        res['exit_code'] = U.stop_node(proc)
        lst.close()
    try:
        from train_dynamics.ros import sim_node
        res['max_backlog'] = getattr(sim_node, 'MAX_RECORD_BACKLOG', None)
    except Exception:  # noqa: BLE001 - informative only
        res['max_backlog'] = None
    res['received'] = lst.count
    res['received_non_monotonic'] = lst.non_monotonic
    res['last_received_stamp_s'] = lst.last_stamp_ns * 1e-9
    res['load_after'] = os.getloadavg()[0]
    # RSS at every 10 min of simulated time (the first sample at or after each mark), and
    # the last sample (the node has finished: closing the bag, shutting down)
    marks = []
    k = 0
    for wall, sim_t, rss, cpu, backlog in samples:
        if sim_t >= k * 600.0 and sim_t <= sim_end:
            marks.append({'sim_s': sim_t, 'wall_s': wall, 'rss_kib': rss, 'backlog': backlog})
            k = int(sim_t // 600.0) + 1
    if samples and samples[-1][0] > marks[-1]['wall_s']:
        marks.append({'sim_s': samples[-1][1], 'wall_s': samples[-1][0],
                      'rss_kib': samples[-1][2], 'backlog': samples[-1][4], 'end': True})
    res['rss_max_running_kib'] = max(s[2] for s in samples) if samples else None
    res['rss_marks'] = marks
    log('reading the bag')
    t0 = time.monotonic()
    try:
        res['bag'] = check_bag(bag, rate)
    except Exception as exc:  # noqa: BLE001 - report
        res['bag'] = {'error': f'{type(exc).__name__}: {exc}'}
    res['bag_read_s'] = time.monotonic() - t0
    res['bag_bytes'] = sum(os.path.getsize(os.path.join(dp, f))
                           for dp, _, fs in os.walk(bag) for f in fs) if os.path.isdir(bag) else 0
    expect = int(round(sim_end * rate)) + 1
    res['expected_per_topic'] = expect
    res['exact'] = {}
    for topic in ('couplers', 'coaches', 'brake_cylinders'):
        d = res['bag'].get(topic)
        res['exact'][topic] = bool(
            d and d['count'] == expect and d.get('first_stamp') == 0
            and d.get('last_stamp') == int(round(sim_end * 1e9))
            and d.get('stamp_bad_step') == 0 and d.get('stamp_non_monotonic') == 0
            and d.get('bag_non_monotonic') == 0)
    if not keep_bag:
        shutil.rmtree(tmpdir, ignore_errors=True)
    return res


def render(res: dict) -> str:
    marks = res['rss_marks']
    running = [m for m in marks if not m.get('end')]

    def at(t):      # RSS [MiB] at the first mark at or after t
        return next((m['rss_kib'] for m in running if m['sim_s'] >= t),
                    running[-1]['rss_kib']) / 1024.0
    rss0 = running[0]['rss_kib'] / 1024.0
    rss10 = at(600.0)
    rss_end = running[-1]['rss_kib'] / 1024.0
    half = at(running[-1]['sim_s'] / 2.0)
    lines = ['## Soak (`make soak`)', '',
             f"{res['date']}; load average before / after {res['load_before']:.2f} / "
             f"{res['load_after']:.2f}. `sim_node` with "
             + ' '.join(f'`{k}:={v}`' for k, v in res['params'].items() if k != 'record_bag')
             + ' and `record_bag` set; emergency braking sent at the first output; the node '
               'stops by itself at t = duration.', '',
             f"- simulated {res['last_received_stamp_s']:.2f} s in {res['wall_s']:.0f} s wall "
             f"({res['last_received_stamp_s'] / res['wall_s']:.1f}x real time), node CPU "
             f"{res['cpu_s']:.0f} s; start-up to first output {res['startup_s']:.2f} s; "
             f"node exit status {res['exit_code']}",
             f'- memory (node RSS): {rss0:.1f} MiB at the first output, {rss10:.1f} MiB at '
             f'10 min, {rss_end:.1f} MiB at t = duration: {rss_end - rss10:+.1f} MiB from 10 min '
             f'to the end, {rss_end - half:+.2f} MiB over the second half of the run; peak '
             f"{res['hwm_kib'] / 1024:.1f} MiB", '',
             '| simulated time [s] | wall [s] | node RSS [MiB] | recorder backlog (last '
             '/diagnostics) |', '| ---: | ---: | ---: | ---: |']
    for m in marks:
        label = ' (node finished, closing the bag)' if m.get('end') else ''
        lines.append(f"| {m['sim_s']:.0f}{label} | {m['wall_s']:.0f} | "
                     f"{m['rss_kib'] / 1024:.1f} | {m.get('backlog') or '-'} |")
    dg = res.get('diagnostics', {})
    lines += ['', f"- node's last /diagnostics: achieved real-time factor "
              f"{dg.get('train_dynamics: simulation/achieved_real_time_factor', '?')}, "
              f"recorded messages {dg.get('train_dynamics: simulation/recorded_messages', '?')}, "
              f"recorder backlog {dg.get('train_dynamics: simulation/record_backlog', '?')}"
              + (f" (the node's recorder queue holds at most {res['max_backlog']} messages; "
                 'free-running, the simulation outruns the bag writer and then waits for it)'
                 if res.get('max_backlog') else '')]
    lines += [f"- subscriber (depth 100, reliable): {res['received']} `couplers` received, "
              f"{res['received_non_monotonic']} non-monotonic stamps (a free-running publisher "
              'may outrun a Python subscriber; the bag is the complete record)']
    bag = res['bag']
    if 'error' in bag:
        lines.append(f"- bag: could not be read: {bag['error']}")
    else:
        lines += [f"- bag ({res['bag_bytes'] / 1e6:.0f} MB, read in {res['bag_read_s']:.0f} s):",
                  '', '| topic | type | messages | bag time first / last [s] | header stamp '
                  'first / last [s] | stamps non-monotonic | stamp steps != 1/rate | bag times '
                  'non-monotonic |',
                  '| --- | --- | ---: | --- | --- | ---: | ---: | ---: |']
        for topic, d in sorted(bag.items()):
            fs = d.get('first_stamp')
            ls = d.get('last_stamp')
            span = f'{fs * 1e-9:.2f} / {ls * 1e-9:.2f}' if fs is not None else '-'
            if fs is not None and fs > 1e18:
                span = 'wall clock'
            bspan = f"{d['first_t'] * 1e-9:.2f} / {d['last_t'] * 1e-9:.2f}" if 'first_t' in d \
                else '-'
            step = d.get('stamp_bad_step', '-') if d['type'].endswith('JointState') else '-'
            lines.append(f"| {topic} | {d['type']} | {d['count']} | {bspan} | {span} | "
                         f"{d.get('stamp_non_monotonic', '-')} | {step} | "
                         f"{d.get('bag_non_monotonic', '-')} |")
        lines += ['', '- expected per output topic: duration x rate + 1 = '
                  f"{res['expected_per_topic']} messages stamped 0 .. duration in 10 ms steps: "
                  + ', '.join(f"`{t}` {'EXACT' if ok else 'MISMATCH'}"
                              for t, ok in res['exact'].items())]
    return '\n'.join(lines)


def splice_results(section: str) -> None:
    """Write the soak section into RESULTS.md."""
    splice_section(RESULTS, SOAK_BEGIN, SOAK_END, section)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument('--hours', type=float, default=1.0)
    ap.add_argument('--coaches', type=int, default=30)
    ap.add_argument('--rate', type=float, default=100.0)
    ap.add_argument('--keep-bag', action='store_true')
    ap.add_argument('--no-write', action='store_true', help='print only')
    args = ap.parse_args(argv)
    res = run(args.hours, args.coaches, args.rate, args.keep_bag)
    text = render(res)
    print(text)
    if not args.no_write:
        with open(SOAK_MD, 'w') as fh:
            fh.write(text + '\n')
        with open(SOAK_JSON, 'w') as fh:
            json.dump(res, fh, indent=1, default=str)
        splice_results(text)
        log(f'wrote {SOAK_MD}, {SOAK_JSON} and the soak section of {RESULTS}')
    ok = all(res['exact'].values()) and res['received_non_monotonic'] == 0 \
        and res['exit_code'] == 0
    return 0 if ok else 1


if __name__ == '__main__':
    sys.exit(main())

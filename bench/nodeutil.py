"""
Shared helpers of the node benchmarks (bench/node.py, bench/soak.py).

- start ``sim_node`` as a child process (``python -m train_dynamics.ros.sim_node --ros-args ...``)
  on loopback-only DDS in this process's ROS domain;
- a subscriber in THIS process that timestamps every ``couplers`` message with
  ``time.monotonic()`` on arrival. It subscribes raw (no deserialisation in Python: the
  header stamp is read from the first bytes of the CDR payload), so the subscriber's own
  cost barely disturbs the arrival times;
- CPU time and RSS of the child from ``/proc/<pid>/stat`` and ``/proc/<pid>/status``.
"""
from __future__ import annotations

import os
import signal
import struct
import subprocess
import sys
import threading
import time

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.dirname(HERE)
ATMOSPHERIC = 101325.0


def ros_env() -> dict:
    """Environment for rclpy processes: loopback discovery, a private domain."""
    env = dict(os.environ)
    env['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
    if not env.get('ROS_DOMAIN_ID'):
        env['ROS_DOMAIN_ID'] = str(70 + os.getpid() % 31)
    os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
    os.environ['ROS_DOMAIN_ID'] = env['ROS_DOMAIN_ID']
    return env


def start_node(params: dict, log_path: str) -> tuple[subprocess.Popen, float]:
    """Start sim_node with ``params``; returns (process, time.monotonic() just before)."""
    args = [sys.executable, '-m', 'train_dynamics.ros.sim_node', '--ros-args']
    for k, v in params.items():
        if isinstance(v, bool):
            v = 'true' if v else 'false'
        elif isinstance(v, str):
            v = v if v else '""'
        args += ['-p', f'{k}:={v}']
    log = open(log_path, 'w')
    t0 = time.monotonic()
    proc = subprocess.Popen(args, cwd=REPO, env=ros_env(), stdout=log,
                            stderr=subprocess.STDOUT, start_new_session=True)
    proc.wall_start = time.time() - (time.monotonic() - t0)   # epoch of t0
    return proc, t0


def first_log_time(log_path: str, needle: str = 'started') -> float | None:
    """Epoch time [s] of the first rclpy log line containing ``needle`` (``[INFO] [epoch]``)."""
    try:
        with open(log_path) as fh:
            for line in fh:
                if needle in line and line.startswith('['):
                    try:
                        return float(line.split('] [', 1)[1].split(']', 1)[0])
                    except (IndexError, ValueError):
                        return None
    except OSError:
        return None
    return None


def stop_node(proc: subprocess.Popen, sig=signal.SIGINT, timeout: float = 30.0) -> int:
    if proc.poll() is None:
        proc.send_signal(sig)
        try:
            proc.wait(timeout)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()
    return proc.returncode


_CLK_TCK = os.sysconf('SC_CLK_TCK')


def proc_cpu_seconds(pid: int) -> float | None:
    """Return utime + stime of a process [s] (all its threads), or None once it has gone."""
    try:
        with open(f'/proc/{pid}/stat') as fh:
            fields = fh.read().rsplit(')', 1)[1].split()
    except OSError:
        return None
    return (int(fields[11]) + int(fields[12])) / _CLK_TCK


def proc_rss_kib(pid: int, field: str = 'VmRSS') -> int | None:
    try:
        with open(f'/proc/{pid}/status') as fh:
            for line in fh:
                if line.startswith(field + ':'):
                    return int(line.split()[1])
    except OSError:
        return None
    return None


def cdr_stamp_ns(raw: bytes) -> int:
    """header.stamp of a CDR-serialised message whose first field is a std_msgs/Header."""
    little = raw[1] & 1
    sec, nsec = struct.unpack('<iI' if little else '>iI', raw[4:12])
    return sec * 1_000_000_000 + nsec


class Listener:
    """
    An rclpy node in this process that listens to the simulator's outputs.

    Records (arrival monotonic [s], stamp [ns]) of every ``couplers`` message and the last
    /diagnostics, and can publish the head pipe pressure.
    """

    def __init__(self, name: str = 'bench_listener', qos_depth: int = 10,
                 record: bool = True, message_info: bool = False, priority: int = 0):
        import rclpy
        from rclpy.qos import QoSProfile, ReliabilityPolicy, HistoryPolicy
        from sensor_msgs.msg import FluidPressure, JointState
        from diagnostic_msgs.msg import DiagnosticArray

        ros_env()
        # ``priority`` > 0: the DDS threads of this process (created with its context and node,
        # they inherit the creating thread's policy) run at SCHED_FIFO ``priority`` where
        # permitted, so that the load of other processes does not delay the receptions this
        # probe records; its Python threads stay at normal priority
        self.scheduling = 'normal'
        if priority > 0:
            try:
                os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(priority))
                self.scheduling = f'SCHED_FIFO {priority} (DDS threads)'
            except (AttributeError, OSError) as exc:
                self.scheduling = f'normal (SCHED_FIFO not granted: {exc})'
        self._rclpy = rclpy
        self.context = rclpy.Context()
        rclpy.init(context=self.context)
        self.node = rclpy.create_node(name, context=self.context)
        qos = QoSProfile(depth=qos_depth, reliability=ReliabilityPolicy.RELIABLE,
                         history=HistoryPolicy.KEEP_LAST)
        self.arrivals: list[float] = []
        self.stamps: list[int] = []
        #: per message, from the rmw's message info [ns, system clock]: when the node's DDS
        #: writer sent it, and when this process's DDS reader received it (before any Python)
        self.sources: list[int] = []
        self.receptions: list[int] = []
        self.record = record
        self.count = 0
        self.last_stamp_ns = -1
        self.first_arrival: float | None = None
        self.non_monotonic = 0
        self._diag_raw: bytes | None = None
        self.diag_count = 0
        self.message_info = message_info
        self.node.create_subscription(
            JointState, 'couplers', self._on_couplers_info if message_info else self._on_couplers,
            qos, raw=True)
        self.node.create_subscription(DiagnosticArray, '/diagnostics', self._on_diag, 10,
                                      raw=True)
        self._DiagnosticArray = DiagnosticArray
        self.pub = self.node.create_publisher(FluidPressure, 'brake_pipe/pressure', 10)
        self._FluidPressure = FluidPressure
        # a lean subscriber: the C++ EventsExecutor, raw messages, no Python deserialisation
        # on the hot path (a Python executor adds its own millisecond jitter to what it sees).
        # ``message_info``: the rmw's timestamps of each message (its DDS reception in this
        # process, taken before any executor sees it): rclpy 7.1's EventsExecutor cannot pass
        # them (SystemError), the SingleThreadedExecutor can, and its own delay then does not
        # enter the reception times
        from rclpy.executors import SingleThreadedExecutor
        from train_dynamics.ros.sim_node import make_executor
        self.executor = (SingleThreadedExecutor(context=self.context) if message_info
                         else make_executor(self.context))
        self.executor.add_node(self.node)
        if self.scheduling.startswith('SCHED_FIFO'):
            os.sched_setscheduler(0, os.SCHED_OTHER, os.sched_param(0))
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None

    def _on_couplers_info(self, raw: bytes, info: dict) -> None:
        self._on_couplers(raw, info)

    def _on_couplers(self, raw: bytes, info: dict | None = None) -> None:
        now = time.monotonic()
        stamp = cdr_stamp_ns(raw)
        if self.first_arrival is None:
            self.first_arrival = now
        if stamp <= self.last_stamp_ns:
            self.non_monotonic += 1
        self.last_stamp_ns = stamp
        self.count += 1
        if self.record:
            self.arrivals.append(now)
            self.stamps.append(stamp)
            if info is not None:
                self.sources.append(int(info['source_timestamp']))
                self.receptions.append(int(info['received_timestamp']))

    def _on_diag(self, raw: bytes) -> None:
        self.diag_count += 1
        self._diag_raw = raw          # decoded only when read (:attr:`diag`)

    @property
    def diag(self) -> dict[str, str]:
        """Return the last /diagnostics as {'<status name>/<key>': value}."""
        from rclpy.serialization import deserialize_message
        out: dict[str, str] = {}
        raw = self._diag_raw
        if raw is None:
            return out
        msg = deserialize_message(raw, self._DiagnosticArray)
        for status in msg.status:
            for kv in status.values:
                out[f'{status.name}/{kv.key}'] = kv.value
            out[f'{status.name}/_message'] = status.message
            out[f'{status.name}/_level'] = str(int.from_bytes(status.level, 'little')
                                               if isinstance(status.level, bytes)
                                               else status.level)
        return out

    def publish_head_pressure(self, gauge_pa: float) -> None:
        msg = self._FluidPressure()
        msg.header.stamp = self.node.get_clock().now().to_msg()
        msg.fluid_pressure = ATMOSPHERIC + gauge_pa
        self.pub.publish(msg)

    def matched_couplers(self) -> int:
        return self.node.count_publishers('couplers')

    def start(self) -> None:
        def spin():
            while not self._stop.is_set() and self.context.ok():
                self.executor.spin_once(timeout_sec=0.05)
        self._thread = threading.Thread(target=spin, daemon=True)
        self._thread.start()

    def close(self) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join(5.0)
        self.executor.shutdown()
        self.node.destroy_node()
        self._rclpy.shutdown(context=self.context)


def percentile(values, q: float) -> float:
    import numpy as np
    return float(np.percentile(np.asarray(values, float), q)) if len(values) else float('nan')

"""
Test support for sim_node tests (no tests here): an in-process harness with real rclpy.

The harness spins one executor (the one ``sim_node``'s ``main`` uses) in the test thread; the
nodes under test run their own simulation threads as in production.
"""
from __future__ import annotations

import math
import time
from typing import Any, Callable

import numpy as np
from rcl_interfaces.srv import SetParameters
import rclpy
from rclpy.parameter import Parameter
from rclpy.qos import QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import FluidPressure
from std_srvs.srv import Trigger

from train_dynamics.ros.executor import make_executor
from train_dynamics.ros.sim_node import SimNode

TEST_NODE = 'sim_node_test_probe'


class Harness:
    """Nodes under test, a probe node (subscriptions, publishers, clients) and an executor."""

    def __init__(self) -> None:
        self.executor = make_executor()
        self.probe = rclpy.create_node(TEST_NODE)
        self.executor.add_node(self.probe)
        self.nodes: list[Any] = []

    # -- nodes -------------------------------------------------------------------------
    def start(self, **params: Any):
        """Start a SimNode with these parameter overrides, added to the executor."""
        node = SimNode(parameter_overrides=[Parameter(k, value=v) for k, v in params.items()])
        self.add(node)
        return node

    def add(self, node) -> None:
        self.executor.add_node(node)
        self.nodes.append(node)

    def stop(self, node) -> None:
        """Remove and destroy a node (a SimNode finishes its bag)."""
        if node in self.nodes:
            self.nodes.remove(node)
            self.executor.remove_node(node)
        node.destroy_node()

    def close(self) -> None:
        for node in list(self.nodes):
            self.stop(node)
        self.executor.remove_node(self.probe)
        self.probe.destroy_node()
        self.executor.shutdown()

    # -- spinning ------------------------------------------------------------------------
    def spin_for(self, seconds: float) -> None:
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            self.executor.spin_once(timeout_sec=min(0.01, max(end - time.monotonic(), 0.0)))

    def wait(self, predicate: Callable[[], bool], timeout: float = 10.0) -> bool:
        end = time.monotonic() + timeout
        while True:
            if predicate():
                return True
            if time.monotonic() >= end:
                return False
            self.executor.spin_once(timeout_sec=0.01)

    @staticmethod
    def every(period: float, action: Callable[[], Any]) -> Callable[[], None]:
        """
        Return a function that runs ``action`` when ``period`` [s wall] passed since it last did.

        For a predicate that keeps a controller sending while :meth:`wait` polls: a publisher
        at a controller's rate, not at the executor loop's. Publishing on every poll floods the
        node with thousands of messages a second, which starves its simulation thread of CPU
        on a 2-core machine.
        """
        last = [-math.inf]

        def run() -> None:
            now = time.monotonic()
            if now - last[0] >= period:
                last[0] = now
                action()
        return run

    # -- topics ----------------------------------------------------------------------------
    def collect(self, msg_type, topic: str, qos=None) -> list:
        """Every message received on ``topic`` (reliable, deep queue unless ``qos``)."""
        out: list = []
        qos = qos or QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE)
        self.probe.create_subscription(msg_type, topic, out.append, qos)
        return out

    def publisher(self, topic: str, reliable: bool = True):
        qos = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE if reliable
                         else ReliabilityPolicy.BEST_EFFORT)
        return self.probe.create_publisher(FluidPressure, topic, qos)

    def wait_for_subscriber(self, pub, timeout: float = 5.0) -> bool:
        return self.wait(lambda: pub.get_subscription_count() > 0, timeout)

    # -- services ----------------------------------------------------------------------------
    def call(self, srv_type, name: str, request, timeout: float = 10.0):
        client = self.probe.create_client(srv_type, name)
        try:
            assert self.wait(client.service_is_ready, timeout), f'service {name} not available'
            future = client.call_async(request)
            assert self.wait(future.done, timeout), f'service {name} did not answer'
            return future.result()
        finally:
            self.probe.destroy_client(client)

    def reset(self, node_name: str = 'train_dynamics'):
        return self.call(Trigger, f'/{node_name}/reset', Trigger.Request())

    def set_remote(self, node_name: str, params: dict[str, Any]):
        """Set parameters over the parameter service (what ``ros2 param set`` does)."""
        req = SetParameters.Request(
            parameters=[Parameter(k, value=v).to_parameter_msg() for k, v in params.items()])
        return self.call(SetParameters, f'/{node_name}/set_parameters', req).results


def fluid(abs_pa: float):
    return FluidPressure(fluid_pressure=float(abs_pa), variance=0.0)


def stamp_s(msg) -> float:
    return msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9


def diag_values(msgs: list, status_name: str) -> dict[str, str] | None:
    """Key-values of the newest status ``status_name`` in DiagnosticArray messages."""
    for msg in reversed(msgs):
        for st in msg.status:
            if st.name == status_name:
                d = {kv.key: kv.value for kv in st.values}
                d['_level'] = int.from_bytes(st.level, 'little') if isinstance(st.level, bytes) \
                    else int(st.level)
                d['_message'] = st.message
                return d
    return None


def joint_arrays(msgs: list) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(t, position, velocity, effort) of JointState messages, as arrays."""
    t = np.array([stamp_s(m) for m in msgs])
    pos = np.array([list(m.position) for m in msgs])
    vel = np.array([list(m.velocity) for m in msgs])
    eff = np.array([list(m.effort) for m in msgs])
    return t, pos, vel, eff


def all_finite(*arrays) -> bool:
    return all(np.all(np.isfinite(a)) for a in arrays)


def first_time(t: np.ndarray, cond: np.ndarray) -> float:
    idx = np.nonzero(cond)[0]
    return float(t[idx[0]]) if idx.size else math.inf

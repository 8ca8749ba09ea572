"""
The executor and the ``main`` of both nodes: start, spin, and a clean shutdown on any path.

:func:`run_node` is the try/finally around a node that ``sim_node`` and ``brake_valve``
share (the shape of ros2/demos' ``demo_nodes_py``): SIGINT/SIGTERM (rclpy's signal handlers
shut the context down) end it with status 0; the exceptions a node declares (invalid
parameters, ...) print one line and end it with their status; anything else is a crash,
unless a signal shut the context down under a callback (then it is a clean stop too).
"""
from __future__ import annotations

from dataclasses import dataclass
import os
import sys
from typing import Callable

import rclpy
from rclpy.executors import Executor, ExternalShutdownException, SingleThreadedExecutor
from rclpy.node import Node

try:   # rclpy >= 7 (Jazzy); the single-threaded executor otherwise
    from rclpy.experimental import EventsExecutor
except ImportError:   # pragma: no cover - older rclpy
    EventsExecutor = None

SPIN_PERIOD = 0.1     # [s wall] longest spin_once between two checks of ``node.finished``


def make_executor(context=None) -> Executor:
    """
    Return the executor ``main`` spins.

    rclpy's (experimental) EventsExecutor where available, else (or with
    ``TRAIN_DYNAMICS_EXECUTOR=single``) a SingleThreadedExecutor.

    Measured here: the SingleThreadedExecutor rebuilds its wait set in Python on every wake-up,
    so with the 300 subscriptions of a 300-coach per-coach input it manages ~30 callbacks/s;
    the EventsExecutor's cost does not grow with the number of entities. Spin it from one
    thread with ``spin_once`` (its ``spin()`` in a background thread deadlocks with entity
    creation in another thread in rclpy 7.1).
    """
    single = os.environ.get('TRAIN_DYNAMICS_EXECUTOR', '').lower() == 'single'
    if EventsExecutor is not None and not single:
        return EventsExecutor(context=context)
    return SingleThreadedExecutor(context=context)


@dataclass(frozen=True)
class ExitOn:
    """Exceptions that end ``main`` with one line on stderr (``<prog>: <what>: <exc>``)."""

    errors: tuple[type[BaseException], ...]
    what: str
    code: int


def run_node(prog: str, create: Callable[[], Node], args: list[str] | None = None, *,
             exits: tuple[ExitOn, ...] = (),
             executor_factory: Callable[[], Executor] = make_executor) -> int:
    """
    Create the node, spin it until it is ``finished`` or shut down; return the exit status.

    A node may have ``finished`` (bool: stop spinning) and ``exit_code`` (int) attributes.
    """
    rclpy.init(args=args)
    node = None
    executor = None
    code = 0
    try:
        node = create()
        executor = executor_factory()
        executor.add_node(node)
        while not getattr(node, 'finished', False):
            executor.spin_once(timeout_sec=SPIN_PERIOD)
        code = getattr(node, 'exit_code', 0)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except Exception as exc:
        if not rclpy.ok():     # a signal shut the context down mid-callback or mid-start
            return code
        exit_on = next((e for e in exits if isinstance(exc, e.errors)), None)
        if exit_on is None:
            raise
        print(f'{prog}: {exit_on.what}: {exc}', file=sys.stderr)
        code = exit_on.code
    finally:
        _shut_down(executor, node)
    return code


def _shut_down(executor: Executor | None, node: Node | None) -> None:
    """Release the node from the executor, destroy it, shut rclpy down (never raises)."""
    # the executor lets go of the node's callbacks first: the EventsExecutor aborts the
    # process ("Destroying callback manager with callbacks remaining") otherwise
    if executor is not None:
        if node is not None:
            try:
                executor.remove_node(node)
            except Exception:   # noqa: BLE001 - shutting down anyway
                pass
        executor.shutdown()
    if node is not None:
        node.destroy_node()
    try:
        rclpy.try_shutdown()
    except Exception:  # noqa: BLE001 - a signal handler shut the context down first
        pass

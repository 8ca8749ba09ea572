"""
The executor and the ``main`` of both nodes: start, spin, and a clean shutdown on any path.

:func:`run_node` is the try/finally around a node that ``sim_node`` and ``brake_valve``
share (the shape of ros2/demos' ``demo_nodes_py``): SIGINT/SIGTERM end it with status 0 (they
stop the spin loop; the node is destroyed and rclpy shut down in order); the exceptions a node
declares (invalid parameters, ...) print one line ``<prog>: error: ...`` and end it with their
status; anything else is a crash, unless the context went down under a callback (then it is a
clean stop too). A missing or malformed ``--params-file`` is one line and status 2 before rclpy
starts, and so is one with no section for the node (its values would be ignored); ``-h`` /
``--help`` print the usage (:mod:`train_dynamics.ros.usage`) and exit 0 without starting;
timer callbacks wrapped in :func:`shutdown_safe` stay quiet when a signal shuts the context
down under them.
"""
from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
import functools
import os
import re
import signal
import sys
import threading
import time
from typing import Any, Callable, Mapping

import rclpy
from rclpy.executors import Executor, ExternalShutdownException, SingleThreadedExecutor
from rclpy.node import Node
from rclpy.signals import SignalHandlerOptions

from train_dynamics.param_files import (node_sections, read_param_sections,
                                        ROS_BUILTIN_PARAMETERS, unknown_sections,
                                        unknown_sections_message)
from train_dynamics.physics.config import ConfigError
from train_dynamics.physics.config.files import resolve_file_inputs
from train_dynamics.ros.usage import usage_text, wants_help

try:   # rclpy >= 7 (Jazzy); the single-threaded executor otherwise
    from rclpy.experimental import EventsExecutor
except ImportError:   # pragma: no cover - older rclpy
    EventsExecutor = None

EXIT_BAD_PARAMETERS = 2
SHUTDOWN_GRACE = 0.5  # [s wall] how long a failed timer callback waits for a shutdown to show
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


def params_files(args: Sequence[str]) -> list[str]:
    """Return the ``--params-file`` paths among the ``--ros-args`` of ``args``."""
    out, inside = [], False
    for k, arg in enumerate(args):
        if arg == '--ros-args':
            inside = True
        elif arg == '--':
            inside = False
        elif inside and arg == '--params-file' and k + 1 < len(args):
            out.append(args[k + 1])
    return out


def check_params_files(prog: str, args: Sequence[str], node_name: str,
                       specs: Mapping[str, Any]) -> int:
    """
    Check the ``--params-file`` files before rclpy reads them; return 0 or the exit status 2.

    A missing or malformed file: one line ``<prog>: error: ...`` (rclpy would raise an
    ``RCLError`` traceback). Sections for no node of this package (a typo) and keys of the
    node's own section that it does not declare (rclpy ignores both): a warning each.
    """
    for path in params_files(args):
        try:
            sections = read_param_sections(path)
        except ConfigError as exc:
            print(f'{prog}: error: {exc}', file=sys.stderr)
            return EXIT_BAD_PARAMETERS
        unknown = unknown_sections(sections)
        if unknown:
            print(f'{prog}: warning: {unknown_sections_message(path, unknown)}',
                  file=sys.stderr)
        _, own = node_sections(sections, node_name)
        extra = sorted(k for k in own if k not in specs and k not in ROS_BUILTIN_PARAMETERS)
        if extra:
            print(f'{prog}: warning: {path}: {node_name} has no parameter(s) '
                  f'{", ".join(extra)}; ignored', file=sys.stderr)
    return 0


def section_matches(key: str, full_name: str) -> bool:
    """
    Return True if the parameter-file section ``key`` applies to the node ``full_name``.

    rcl's rule: a key without a leading '/' is taken from the root namespace; ``/**`` stands
    for any number of namespace levels (none too), ``*`` for one name.
    """
    parts = [p for p in key.strip().strip('/').split('/') if p]
    pattern = ''
    for part in parts:
        pattern += {'**': '(/[^/]+)*', '*': '/[^/]+'}.get(part, '/' + re.escape(part))
    return re.fullmatch(pattern or '/', full_name) is not None


def unmatched_params_files(args: Sequence[str], full_name: str) -> list[str]:
    """Return a complaint for each ``--params-file`` of ``args`` with no section for the node."""
    out = []
    for path in params_files(args):
        try:
            keys = list(read_param_sections(path))
        except ConfigError:
            continue                      # reported before the start
        if not any(section_matches(k, full_name) for k in keys):
            name = full_name.rsplit('/', 1)[-1]
            out.append(f'parameter file {path}: no section applies to {full_name} (sections: '
                       f'{", ".join(keys) or "none"}): rclpy would ignore it; a section '
                       f'/**/{name} applies to the node in any namespace')
    return out


def file_input_args(args: Sequence[str], node_name: str,
                    specs: Mapping[str, Any]) -> list[str]:
    """
    Return ``args`` with each ``--params-file`` followed by its file inputs made absolute.

    rclpy hands the node a parameter file's values as written; a relative file input of
    ``node_name`` (own or ``/**`` section; ``file_input`` in ``specs``) is resolved by the path
    rule of :mod:`train_dynamics.physics.config.files` against the file's folder, as the
    offline command does, and given right after the file as ``-p name:='<absolute path>'``:
    later ``--params-file`` or ``-p`` arguments still win, as rcl applies them in order.
    Raises :class:`ConfigError` (naming the parameter file) when such a file is not found.
    """
    out, inside = [], False
    for k, arg in enumerate(args):
        out.append(arg)
        if arg == '--ros-args':
            inside = True
        elif arg == '--':
            inside = False
        elif inside and k > 0 and args[k - 1] == '--params-file':
            wildcard, own = node_sections(read_param_sections(arg), node_name)
            try:
                found = resolve_file_inputs({**wildcard, **own},
                                            os.path.dirname(os.path.abspath(arg)), specs)
            except ConfigError as exc:
                raise ConfigError(f'{arg}: {exc}') from None
            for name, path in found.items():
                quoted = path.replace("'", "''")
                out += ['-p', f"{name}:='{quoted}'"]
    return out


def shutdown_safe(node: Node, callback: Callable[..., Any]) -> Callable[..., Any]:
    """
    Return ``callback`` (a timer's) made quiet when the context is shut down under it.

    SIGINT/SIGTERM shut the context down from the signal handler, possibly while a timer
    callback runs; what it calls then raises (publish, clock, graph queries), and the
    executor would report ``Exception in 'timers' callback``. Not a failure: the node stops.
    """
    @functools.wraps(callback)
    def call(*args: Any) -> Any:
        if not node.context.ok():
            return None
        try:
            return callback(*args)
        except Exception:
            if _shutting_down(node.context):
                return None
            raise
    return call


def _shutting_down(context: Any, wait: float = SHUTDOWN_GRACE) -> bool:
    """
    Return True if ``context`` is shut down, or goes down within ``wait`` [s wall].

    rclpy's signal handler shuts the context down from another thread: the rosout publisher
    and the node's publishers are invalid a moment before ``context.ok()`` turns False.
    """
    end = time.monotonic() + wait
    while context.ok():
        if time.monotonic() >= end:
            return False
        time.sleep(0.005)
    return True


def run_node(prog: str, create: Callable[[], Node], args: list[str] | None = None, *,
             exits: tuple[ExitOn, ...] = (),
             executor_factory: Callable[[], Executor] = make_executor,
             node_name: str = '', specs: Mapping[str, Any] | None = None,
             summary: str = '') -> int:
    """
    Create the node, spin it until it is ``finished`` or shut down; return the exit status.

    A node may have ``finished`` (bool: stop spinning) and ``exit_code`` (int) attributes.
    ``node_name`` and ``specs`` (its parameters): check the ``--params-file`` files first
    (:func:`check_params_files`, :func:`check_sections_apply`); ``summary``: the node in one
    line, for ``--help``.
    """
    argv = list(sys.argv if args is None else args)
    if wants_help(argv):
        try:
            print(usage_text(prog, node_name or prog, summary, specs or {}))
        except BrokenPipeError:    # `sim_node --help | head`
            pass
        return 0
    if node_name:
        status = check_params_files(prog, argv, node_name, specs or {})
        if status:
            return status
        try:      # relative file inputs: the parameter file's folder (the path rule)
            argv = file_input_args(argv, node_name, specs or {})
        except ConfigError as exc:
            print(f'{prog}: error: {exc}', file=sys.stderr)
            return EXIT_BAD_PARAMETERS
    main_thread = threading.current_thread() is threading.main_thread()
    try:
        # In the main thread SIGINT/SIGTERM only ask the loop below to stop (_stop_on_signals):
        # rclpy's own handlers shut the context down under running callbacks, and the
        # KeyboardInterrupt they chain to is raised inside a timer callback, where the
        # executor reports it as a FATAL exception.
        rclpy.init(args=argv,
                   signal_handler_options=SignalHandlerOptions.NO if main_thread else None)
    except Exception as exc:  # noqa: BLE001 - RCLError: bad --ros-args
        text = ' '.join(str(exc).split(', at ')[0].split())
        print(f'{prog}: error: cannot start: {text}', file=sys.stderr)
        return EXIT_BAD_PARAMETERS
    if node_name and check_sections_apply(prog, argv, node_name):
        rclpy.try_shutdown()
        return EXIT_BAD_PARAMETERS
    stop, previous = _stop_on_signals() if main_thread else (threading.Event(), {})
    node = None
    executor = None
    code = 0
    try:
        node = create()
        executor = executor_factory()
        executor.add_node(node)
        while not getattr(node, 'finished', False) and not stop.is_set():
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
        text = ' '.join(str(exc).split())
        print(f'{prog}: error: {exit_on.what}: {text}', file=sys.stderr)
        code = exit_on.code
    finally:
        # a SIGINT that arrives (or is still pending) while the bag is being finished would
        # raise KeyboardInterrupt in the middle of it: we are stopping already
        _ignore_sigint()
        try:
            _shut_down(executor, node)
        finally:
            for signum, handler in previous.items():
                signal.signal(signum, handler)
    if not code and node is not None:
        code = getattr(node, 'exit_code', 0)      # e.g. the bag failed as it was finished
    return code


def check_sections_apply(prog: str, args: Sequence[str], node_name: str) -> int:
    """
    Refuse a ``--params-file`` with no section for the node; return 0 or the exit status 2.

    rclpy ignores such a file: the node would run its defaults where the user meant the
    file's values (a section ``train_dynamics:`` applies in the root namespace only). The
    node's full name (namespace and name after the ``--ros-args`` remappings, rcl's rules) is
    taken from a probe node of the initialised context, created and destroyed at once, so
    that the check runs before the node starts anything. Prints one line on stderr.
    """
    if not params_files(args):
        return 0
    probe = rclpy.create_node(node_name, enable_rosout=False, start_parameter_services=False)
    try:
        full_name = probe.get_fully_qualified_name()
    finally:
        probe.destroy_node()
    for complaint in unmatched_params_files(args, full_name):
        print(f'{prog}: error: {complaint}', file=sys.stderr)
        return EXIT_BAD_PARAMETERS
    return 0


def _stop_on_signals() -> tuple[threading.Event, dict[int, Any]]:
    """
    Make SIGINT and SIGTERM set the returned event (a second one: KeyboardInterrupt).

    Return the event and the previous handlers. Main thread only.
    """
    stop = threading.Event()

    def handler(signum: int, frame: Any) -> None:
        if stop.is_set():
            raise KeyboardInterrupt
        stop.set()

    return stop, {s: signal.signal(s, handler) for s in (signal.SIGINT, signal.SIGTERM)}


def _ignore_sigint():
    """Ignore SIGINT (main thread only); return the previous handler, or None."""
    if threading.current_thread() is not threading.main_thread():
        return None
    try:
        return signal.signal(signal.SIGINT, signal.SIG_IGN)
    except (ValueError, OSError):
        return None


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

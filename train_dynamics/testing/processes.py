"""
The harness's processes: each command in its own session (process group), ended as a whole.

A controller started through a wrapper (``sh -c '...'``, ``ros2 run``, a launch script) is a
tree of processes; signalling only the direct child leaves the others running, parented to
init and still publishing on the ROS domain. :class:`ProcessGroup` starts a command with
``start_new_session`` (its process id is the id of its new process group) and
:meth:`ProcessGroup.stop` signals the whole group: SIGINT (a ROS 2 node shuts down cleanly),
then SIGTERM after a grace period, then SIGKILL, until no process of the group is left (a
zombie waiting for a parent that does not reap it counts as gone: it runs nothing).

Waiting is event-based where Linux allows it (a pidfd per process, :func:`wait_any`), with a
polling fallback. Linux-only details (``/proc``) are looked up defensively; on other systems
the group is signalled all the same.
"""
from __future__ import annotations

import os
from pathlib import Path
import selectors
import signal
import subprocess
import time
from typing import Mapping, Sequence

#: [s wall] a stopping process group gets this long after SIGINT before SIGKILL
STOP_GRACE = 5.0
#: [s wall] after SIGTERM (a group that did not end on SIGINT), the wait before SIGKILL
TERM_WAIT = 2.0
#: [s wall] after SIGKILL, the longest wait for the group's processes to disappear
KILL_WAIT = 5.0
#: [s wall] polling period where no event can be waited on (group members, no pidfd)
POLL = 0.05


class ProcessGroup:
    """A command run in its own session; ``pid`` is also its process group id."""

    def __init__(self, name: str, cmd: Sequence[str], *, log: Path,
                 env: Mapping[str, str], cwd: str | os.PathLike | None = None) -> None:
        """Start ``cmd`` (stdout and stderr to ``log``); raise OSError if it cannot start."""
        self.name = name
        self.log_path = log
        self._log = open(log, 'wb')
        try:
            self.proc = subprocess.Popen(list(cmd), env=dict(env), cwd=cwd, stdout=self._log,
                                         stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL,
                                         start_new_session=True)
        except BaseException:
            self._log.close()
            raise
        self.pid = self.proc.pid
        self.started = time.monotonic()
        self.exited_at: float | None = None
        self.interrupted = False          # SIGINT sent
        self.fd = _pidfd(self.pid)

    @property
    def returncode(self) -> int | None:
        """Return the exit status of the command's own process (None while it runs)."""
        code = self.proc.poll()
        if code is not None and self.exited_at is None:
            self.exited_at = time.monotonic()
        return code

    def members(self) -> list[int]:
        """Return the running processes of the group (the leader too while it runs)."""
        return group_members(self.pid)

    def alive(self) -> bool:
        """Return True while the command or any process it started in its group runs."""
        return self.returncode is None or bool(self.members())

    def signal(self, sig: int) -> None:
        """Send ``sig`` to every process of the group (nothing if none is left)."""
        self.interrupted |= sig == signal.SIGINT
        try:
            os.killpg(self.pid, sig)
        except (ProcessLookupError, PermissionError):
            pass

    def stop(self, grace: float = STOP_GRACE) -> None:
        """
        End the whole group: SIGINT (unless sent before), SIGTERM after ``grace`` [s wall].

        Then SIGKILL after :data:`TERM_WAIT` more, as ``ros2 launch`` does (SIGTERM reaches a
        process that ignores SIGINT: a child of a shell's background job). Returns when no
        process of the group runs (or :data:`KILL_WAIT` after SIGKILL); the command's own
        process is reaped.
        """
        if self.alive():
            if not self.interrupted:
                self.signal(signal.SIGINT)
            for sig, wait in ((signal.SIGTERM, grace), (signal.SIGKILL, TERM_WAIT)):
                if _wait_until(lambda: not self.alive(), wait, self):
                    break
                self.signal(sig)
            else:
                _wait_until(lambda: not self.alive(), KILL_WAIT, self)
        try:
            self.proc.wait(KILL_WAIT)
        except subprocess.TimeoutExpired:      # pragma: no cover - SIGKILL was sent
            pass
        if self.exited_at is None and self.proc.returncode is not None:
            self.exited_at = time.monotonic()

    def close(self) -> None:
        """Release the log file and the pidfd (after :meth:`stop`)."""
        self._log.close()
        if self.fd is not None:
            os.close(self.fd)
            self.fd = None

    def tail(self, lines: int = 3) -> str:
        """Return the last ``lines`` lines of the log, joined by `` | ``."""
        try:
            text = self.log_path.read_text(errors='replace')
        except OSError:
            return ''
        return ' | '.join(line.strip() for line in text.strip().splitlines()[-lines:])

    def describe_exit(self) -> str:
        """Return e.g. ``exited with status 1`` or ``was killed by SIGSEGV``."""
        code = self.returncode
        if code is None:
            return 'is running'
        if code < 0:
            try:
                return f'was killed by {signal.Signals(-code).name}'
            except ValueError:
                return f'was killed by signal {-code}'
        return f'exited with status {code}'


def group_members(pgid: int) -> list[int]:
    """Return the processes of process group ``pgid`` that still run (zombies excluded)."""
    proc = Path('/proc')
    if not proc.is_dir():                       # not Linux: ask the kernel whether any is left
        try:
            os.killpg(pgid, 0)
        except (ProcessLookupError, PermissionError):
            return []
        return [pgid]
    out = []
    for entry in proc.iterdir():
        if not entry.name.isdigit():
            continue
        try:
            stat = (entry / 'stat').read_text()
        except OSError:
            continue                            # gone meanwhile
        # "pid (comm) state ppid pgrp ...": comm may hold spaces and parentheses
        fields = stat[stat.rfind(')') + 2:].split()
        if len(fields) > 2 and fields[0] not in ('Z', 'X') and int(fields[2]) == pgid:
            out.append(int(entry.name))
    return out


def wait_any(groups: Sequence[ProcessGroup], timeout: float) -> None:
    """Return when a command of ``groups`` exits or after ``timeout`` [s wall]."""
    if any(g.returncode is not None for g in groups):
        return
    fds = [g.fd for g in groups]
    if timeout <= 0.0:
        return
    if None in fds:
        time.sleep(min(timeout, POLL))
        return
    with selectors.DefaultSelector() as sel:
        for fd in fds:
            sel.register(fd, selectors.EVENT_READ)
        sel.select(timeout)


def _wait_until(done, timeout: float, group: ProcessGroup) -> bool:
    """Wait up to ``timeout`` [s wall] for ``done()``; the leader's exit wakes it at once."""
    end = time.monotonic() + timeout
    while not done():
        left = end - time.monotonic()
        if left <= 0.0:
            return False
        if group.returncode is None:
            wait_any([group], min(left, 1.0))
        else:
            time.sleep(min(left, POLL))
    return True


def _pidfd(pid: int) -> int | None:
    """Return a pidfd of ``pid`` (readable when it exits), None where Linux has none."""
    try:
        return os.pidfd_open(pid)
    except (AttributeError, OSError):
        return None

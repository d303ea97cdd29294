"""The last resort for a case stuck in one C call that holds the interpreter: a sentinel process.

A case past its time limit is interrupted by SIGALRM (:class:`~pytest_avscenario.runner.TimeLimit`),
and one that does not stop is ended by a watchdog thread that reports its row first
(:func:`.stopping.stuck_case_handler`). Both need the interpreter: code inside one long C call
that never lets go of it (``sum(range(10**10))``, a C extension's loop) gives neither a chance,
nor the SIGTERM watcher. Only a thread that needs no interpreter can act then —
``faulthandler.dump_traceback_later(exit=True)``, pytest-timeout's last resort, is one — but it
cannot write the case's row first, and a row must never be lost.

So the row goes out *before* the case runs: while a case with a time limit runs, a small
sentinel process (this file run as a script: standard library only, one per pytest process,
started on the first such case) holds the error row the case would get and a deadline. When
the case ends in time, it is told so (one short write on a pipe). When the deadline passes
first, the sentinel appends the row to the error table (``errors.jsonl``, flushed and
fsynced), says on the terminal what happened, asks the process for its Python traceback
(SIGUSR2, a C-level ``faulthandler`` handler that needs no interpreter) and ends it with
SIGKILL, and the AV stacks it spawned (``osi+spawn:``) with SIGTERM. The run's status is
then that of a killed process (-9, 137 to a shell): not zero. An xdist worker has no table:
its sentinel leaves the row in a folder of the controller's (``workerinput["avs_lastwords"]``),
where the controller finds it when it handles the worker's crash (``pytest_handlecrashitem``)
and records it instead of the generic row of a worker that died. The sentinel ends by
itself when its pytest process does (its pipe closes).

Should the sentinel be gone, ``faulthandler.dump_traceback_later(exit=True)`` takes over:
the process still ends, without the row.
"""

from __future__ import annotations

import json
import os
import select
import signal
import subprocess
import sys
import time
from typing import Any

#: [s] the sentinel waits after asking for the traceback before it ends the process
TRACEBACK_WAIT_S = 0.5


class Sentinel:
    """The pytest process's side: the sentinel process, started on the first :meth:`arm`."""

    def __init__(self, terminal_fd: int | None = None):
        self.terminal_fd = terminal_fd if terminal_fd is not None else 2
        self.proc: subprocess.Popen | None = None
        self.broken = False  # the sentinel could not be started or died: faulthandler instead
        self.fallback = False  # faulthandler's timer is armed
        self.armed = False
        self.dump = False

    def _start(self) -> bool:
        if self.broken:
            return False
        if self.proc is not None and self.proc.poll() is None:
            return True
        try:
            self.proc = subprocess.Popen(
                [sys.executable, "-I", "-S", os.path.abspath(__file__)], stdin=subprocess.PIPE,
                stdout=subprocess.DEVNULL, stderr=self.terminal_fd, start_new_session=True, bufsize=0)
        except OSError:
            self.broken = True
            return False
        if hasattr(signal, "SIGUSR2") and signal.getsignal(signal.SIGUSR2) is signal.SIG_DFL:
            import faulthandler

            try:  # the traceback the sentinel asks for before it ends this process
                faulthandler.register(signal.SIGUSR2, file=self.terminal_fd, all_threads=True)
                self.dump = True
            except (ValueError, OSError, RuntimeError):
                self.dump = False
        return True

    def _send(self, message: dict[str, Any]) -> bool:
        try:
            self.proc.stdin.write(json.dumps(message).encode() + b"\n")  # type: ignore[union-attr]
            return True
        except (OSError, ValueError):  # the sentinel died: from now on, faulthandler
            self.broken = True
            return False

    def arm(self, after_s: float, row_line: str | None, path: str | None, say: str) -> None:
        """End this process ``after_s`` seconds from now unless :meth:`disarm` comes first;
        ``row_line`` (one JSON line) is appended to ``path`` before (both None: no table here)."""
        self.armed = True
        if self._start() and self._send({"after_s": after_s, "row": row_line, "path": path,
                                         "say": say, "dump": self.dump, "groups": _stack_groups()}):
            return
        import faulthandler

        faulthandler.dump_traceback_later(after_s, exit=True, file=self.terminal_fd)
        self.fallback = True

    def disarm(self) -> None:
        if not self.armed:
            return
        self.armed = False
        if self.fallback:
            import faulthandler

            faulthandler.cancel_dump_traceback_later()
            self.fallback = False
        elif self.proc is not None and not self.broken:
            self._send({})


    def close(self) -> None:
        """The run is over: the sentinel ends (its pipe closes), the SIGUSR2 handler goes."""
        self.disarm()
        proc, self.proc = self.proc, None
        if proc is not None:
            try:
                proc.stdin.close()  # type: ignore[union-attr]
                proc.wait(timeout=5)
            except (OSError, subprocess.TimeoutExpired):
                proc.kill()
        if self.dump:
            import faulthandler

            faulthandler.unregister(signal.SIGUSR2)
            self.dump = False


def last_words_path(folder: str, nodeid: str) -> str:
    """Where an xdist worker's sentinel leaves the row of the stuck case ``nodeid``."""
    import hashlib

    return os.path.join(folder, hashlib.sha1(nodeid.encode()).hexdigest()[:20] + ".jsonl")


def last_words(folder: str | None, nodeid: str) -> Any:
    """The row (a ``CaseRow``) a worker's sentinel left for ``nodeid`` before it killed the
    worker, or None."""
    if folder is None:
        return None
    try:
        with open(last_words_path(folder, nodeid), encoding="utf-8") as fh:
            line = fh.readline()
    except OSError:
        return None
    from ..outcome import CaseRow

    try:
        return CaseRow.from_json(json.loads(line))
    except ValueError:  # a torn write (the sentinel killed meanwhile): the generic row then
        return None


def _stack_groups() -> list[int]:
    """The process groups of the AV stacks this process spawned (each leads its own): the
    sentinel ends them with it, since a killed process cannot stop them itself."""
    stacks = sys.modules.get("pytest_avscenario.stack.client")
    if stacks is None:
        return []
    return [sp.proc.pid for sp in list(stacks._SPAWNED.values())
            if sp.proc is not None and sp.proc.poll() is None]


# -- the sentinel process -------------------------------------------------------------------
def _fire(parent: int, message: dict[str, Any]) -> None:
    path, row = message.get("path"), message.get("row")
    said = message.get("say", "")
    if path and row:
        try:
            with open(path, "a", encoding="utf-8") as fh:
                fh.write(row)
                fh.flush()
                os.fsync(fh.fileno())
        except OSError as exc:
            said += f" (the row could not be written to {path}: {exc})"
    try:
        os.write(2, f"\navscenario: {said}\n".encode())
    except OSError:
        pass
    if os.getppid() != parent:
        return  # the pytest process is gone already
    if message.get("dump"):
        os.kill(parent, signal.SIGUSR2)
        time.sleep(TRACEBACK_WAIT_S)
    try:
        os.kill(parent, signal.SIGKILL)
    except ProcessLookupError:
        pass
    for group in message.get("groups") or ():
        try:
            os.killpg(group, signal.SIGTERM)
        except (ProcessLookupError, PermissionError):
            pass


def main() -> None:
    parent = os.getppid()
    buf = b""
    armed: tuple[float, dict[str, Any]] | None = None
    while True:
        wait = None if armed is None else max(0.0, armed[0] - time.monotonic())
        ready, _, _ = select.select([0], [], [], wait)
        if ready:
            chunk = os.read(0, 1 << 16)
            if not chunk:
                return  # the pytest process ended
            buf += chunk
            *lines, buf = buf.split(b"\n")
            for line in lines:
                message = json.loads(line)
                # a message that arrived with the deadline wins: a case that ended is not ended
                armed = (time.monotonic() + float(message["after_s"]), message) if message else None
            continue
        if armed is not None:
            _fire(parent, armed[1])
            return


if __name__ == "__main__":
    main()

"""Ending the run when a case will not end, or when the run is told to stop.

* :func:`stuck_case_handler` — what happens to a case that ran past its time limit and did not
  stop when told to (it swallows every interrupt, or sits in one long C call): its row is
  reported through pytest's own report hook — the error table writes and flushes it, an
  xdist worker sends it to the controller — and the process ends. Under pytest-xdist the
  controller replaces the worker and the run goes on; alone, the run ends with status 1.
  A case stuck in one C call that holds the interpreter lets no watchdog thread run: for
  it, the row is handed to a sentinel process before the case starts (:mod:`.lastresort`),
  which writes it and kills the process if the case is still running GRACE_S +
  LAST_RESORT_S after its limit.
* :class:`TermGuard` — SIGTERM read as Ctrl-C while scenario work runs (from the first
  scenario item to the last one of a row of them, and the report at the end), so pytest
  finishes the session and the partial report is written; while the report is written, a
  SIGTERM waits for it. Outside that work — a run with no scenario test, plain tests after the
  scenario ones — SIGTERM is left as it was. A watcher thread sees every
  SIGTERM at once, even while the main thread is stuck in C where no Python handler can run:
  a second SIGTERM, or the first one unanswered for :data:`TERM_GRACE_S`, ends the process
  as the default action would.
* :func:`signals_held` — one piece of work (one report's handling by every plugin, one event
  of an xdist controller) happens whole: a SIGTERM or Ctrl-C arriving meanwhile is raised when
  it ends, so the error table and the JUnit file never hold different parts of a run.
* :func:`end_workers` — an interrupted xdist controller ends its workers, says in one line per
  worker where it stopped, reports what they sent until they ended, and lets each exit as soon
  as its end is read (the controller's report and the workers' exits overlap; the controller
  waits for their processes at its own end). The controller's end-of-run imports are made
  while the workers run (:mod:`.preload`), so the report after a Ctrl-C loads nothing.
* :func:`shorten_interrupt` — a Ctrl-C's traceback cut to its last frame before pytest renders
  it (unless ``--full-trace``), in the controller and each worker.
* :class:`ExitGuard` — ``os._exit()`` in an item of a serial run with scenario items (in a
  scenario item or a plain test beside them): a process that
  ends that way writes nothing afterwards (no JUnit file, no summary) and its status is the
  one the body chose (0: "all passed"). While a scenario item runs in the process that started
  the run, ``os._exit`` raises :class:`ProcessExitCalled` instead (a ``SystemExit``: the case is
  an error row saying so) and the session stops after that item, so the rows, JUnit file and
  report describe every case that ran and the run ends as interrupted (status 2). In a
  process the body forked, ``os._exit`` is the real one — and such a child that returns into
  pytest instead is ended at the end of the item, so it neither writes rows nor runs the rest
  of the session a second time. Under pytest-xdist nothing is wrapped: the controller already
  gives a worker that ends this way an error row and replaces it.
* :func:`crash_row` — the row of an item whose xdist worker died while running it.
"""

from __future__ import annotations

import contextlib
import functools
import json
import os
import re
import signal
import sys
import threading
from typing import TYPE_CHECKING, Any, Callable, Iterator

import pytest

if TYPE_CHECKING:  # loading the plugin must stay light (bench/bench_load.py)
    from ..outcome import CaseRow

#: seconds the main thread has to answer a SIGTERM before the watcher ends the process
TERM_GRACE_S = 5.0

#: the plugin's own ways out end the process for real, even while :class:`ExitGuard` wraps it
_REAL_EXIT = os._exit
_SIGINT = int(signal.SIGINT)
try:  # signal's C core (CPython): handlers set and read without signal's enum wrapping
    import _signal
except ImportError:  # pragma: no cover - another interpreter: signal itself
    _signal = signal


def stuck_case_handler(item: pytest.Item, limit_s: float | None, make_row: Callable[[Any], CaseRow],
                       info: Callable[[], dict[str, Any]], during: str = "") -> Callable[[float], None]:
    """``on_stuck`` for the runner's time limit of one simulation of ``item`` (called from a
    thread). ``make_row(outcome)`` is the item's row for an outcome; ``info()`` its test's
    summary data; ``during`` says which simulation it was when not the item's case itself
    ("while it was being minimized", "while the careful reference driver replayed it")."""

    def arm(after_s: float) -> None:
        # the last resort (a case stuck in C holding the interpreter): its row, made now
        from ..outcome import CaseOutcome
        from .stash import controller_key

        state = item.config.stash.get(controller_key, None)
        path = state.table_path() if state is not None else None
        lastwords = getattr(item.config, "workerinput", {}).get("avs_lastwords")
        if lastwords is not None:  # an xdist worker: the row goes to the controller's folder
            from .lastresort import last_words_path

            path = last_words_path(lastwords, item.nodeid)
        line = None
        if path is not None:
            message = (f"CaseTimeout: {what} past its time limit of {limit_s:g} s and never returned "
                       f"to Python (stuck in one C call that holds the interpreter: no interrupt and "
                       f"no watchdog could run); the process running it was killed after {after_s:g} s")
            row = make_row(CaseOutcome(params={}, verdict="error", error=message, sim_time_s=after_s))
            line = json.dumps(row.to_json(), allow_nan=False, ensure_ascii=False) + "\n"
        where = "this xdist worker" if hasattr(item.config, "workerinput") else "the test run"
        say = (f"{item.nodeid}: the case ran past its time limit of {limit_s:g} s and did not return "
               f"to Python within {after_s:g} s (stuck in one C call?): "
               f"{'its error row is written; ' if line else ''}killing {where}")
        _sentinel(item.config).arm(after_s, line, path, say)

    def disarm() -> None:
        _sentinel(item.config).disarm()

    what = f"a simulation {during} ran" if during else "the case ran"

    def on_stuck(ran_s: float) -> None:
        from ..outcome import CaseOutcome
        from .stash import row_key

        disarm()  # the row goes out from here: the last resort must not write it again

        message = (f"CaseTimeout: {what} past its time limit of {limit_s:g} s and did not "
                   f"stop when interrupted (it swallows the interrupt, or is stuck in a long C "
                   f"call); the process running it was ended after {ran_s:.1f} s")
        capman = item.config.pluginmanager.getplugin("capturemanager")
        try:
            if capman is not None:  # what follows is for the terminal, not the test's capture
                capman.suspend_global_capture(in_=False)
        except Exception:  # noqa: BLE001 - capture in an odd state: write where we can
            pass
        try:
            if row_key not in item.stash:
                row = make_row(CaseOutcome(params={}, verdict="error", error=message, sim_time_s=ran_s))
                report = pytest.TestReport(
                    nodeid=item.nodeid, location=item.location, keywords={}, outcome="failed",
                    longrepr=f"{item.nodeid}: {message}", when="setup", duration=ran_s)
                report.avs_row = row.to_json()
                report.avs_shrink_rows = []
                report.avs_pictures = {}
                report.avs_test = info()
                item.ihook.pytest_runtest_logreport(report=report)
        finally:
            where = "this xdist worker" if hasattr(item.config, "workerinput") else "the test run"
            sys.stderr.write(f"\navscenario: {item.nodeid}: the case ran past its time limit of "
                             f"{limit_s:g} s and would not stop (ran {ran_s:.1f} s): its error "
                             f"row is reported; ending {where}\n")
            _end_children()
            _flush_streams()
            _REAL_EXIT(1)

    on_stuck.arm = arm  # type: ignore[attr-defined]  (TimeLimit arms and disarms it per case)
    on_stuck.disarm = disarm  # type: ignore[attr-defined]
    return on_stuck


def _sentinel(config: pytest.Config) -> Any:
    """This process's :class:`.lastresort.Sentinel` (made on first use)."""
    from .lastresort import Sentinel
    from .stash import guard_key, sentinel_key

    sentinel = config.stash.get(sentinel_key, None)
    if sentinel is None:
        guard = config.stash.get(guard_key, None)
        sentinel = config.stash[sentinel_key] = Sentinel(getattr(guard, "terminal_fd", None))
        config.add_cleanup(sentinel.close)
    return sentinel


class ProcessExitCalled(SystemExit):
    """``os._exit(status)`` called by a scenario item in the process that runs the session."""

    def __init__(self, status: Any, what: str = "case"):
        super().__init__(status)
        self.status = status
        self.what = what

    def __str__(self) -> str:
        return (f"os._exit({self.status!r}) called while the {self.what} ran; the process was not "
                "ended (it would have lost the JUnit file and the report) and the run stops after "
                f"this {self.what} as interrupted")


class ExitGuard:
    """``os._exit`` while the scenario items of a serial run run (see the module's text)."""

    def __init__(self, config: pytest.Config):
        self.config = config
        self.pid = os.getpid()  # the process that runs the session; rows are written only here
        self.real_exit = os._exit
        self.called: Any = None  # the status of the first os._exit a scenario item called
        self.item: str | None = None
        self.what = "case"
        self.session: pytest.Session | None = None
        self.scenarios = False  # the session holds scenario items: then every item is guarded

    def _exit(self, status: int = 0) -> None:
        if os.getpid() != self.pid or self.item is None:
            self.real_exit(status)  # a forked child, or no scenario item running: the real thing
        if threading.current_thread() is not threading.main_thread():
            # a thread of the test's (a watchdog of its own, say) means to end a process whose
            # main thread may be stuck: end it, but never with "all passed"; the finished rows
            # are on disk already (the error table is flushed per row)
            _flush_streams()
            self.real_exit(status if status else int(pytest.ExitCode.INTERRUPTED))
        if self.called is None:
            self.called = status
        if self.session is not None:
            self.session.shouldstop = f"os._exit({status!r}) called in {self.item}"
        raise ProcessExitCalled(status, self.what)

    def pytest_collection_finish(self, session: pytest.Session) -> None:
        # a plain test's os._exit ends the scenario items' run as surely as a case's: in a
        # session with scenario items every item is guarded (a run without any is left alone)
        self.scenarios = any(i.get_closest_marker("scenario") is not None for i in session.items)

    @pytest.hookimpl(wrapper=True)
    def pytest_runtest_protocol(self, item: pytest.Item, nextitem: pytest.Item | None) -> Any:
        scenario = item.get_closest_marker("scenario") is not None
        if not (scenario or self.scenarios) or os.getpid() != self.pid:
            return (yield)
        wrap = not hasattr(item.config, "workerinput")  # xdist gives a dead worker's case its row
        if wrap:
            self.session, self.item, os._exit = item.session, item.nodeid, self._exit
            self.what = "case" if scenario else "test"
        try:
            return (yield)
        finally:
            if wrap:
                os._exit = self.real_exit
                self.item = None
            if os.getpid() != self.pid:
                self._end_child(item)

    # The earliest the child of a body that forked is back in pytest: at the end of the phase
    # it forked in, before that phase's report is made (a scenario's case runs as the last
    # step of the setup). An xdist worker's child would otherwise send that report through
    # the worker's channel: a second row and a second "passed" for one item.
    @pytest.hookimpl(wrapper=True, tryfirst=True)
    def pytest_runtest_setup(self, item: pytest.Item) -> Any:
        return (yield from self._phase(item))

    @pytest.hookimpl(wrapper=True, tryfirst=True)
    def pytest_runtest_call(self, item: pytest.Item) -> Any:
        return (yield from self._phase(item))

    @pytest.hookimpl(wrapper=True, tryfirst=True)
    def pytest_runtest_teardown(self, item: pytest.Item, nextitem: pytest.Item | None) -> Any:
        return (yield from self._phase(item))

    def _phase(self, item: pytest.Item) -> Any:
        try:
            return (yield)
        finally:
            if os.getpid() != self.pid and (self.scenarios or item.get_closest_marker("scenario") is not None):
                self._end_child(item)

    def _end_child(self, item: pytest.Item) -> None:
        # the body forked and the child returned into pytest instead of ending: it must not
        # run the rest of the session a second time, nor write or send its reports
        try:
            sys.stderr.write(f"\navscenario: {item.nodeid}: a process the test forked "
                             f"(pid {os.getpid()}) returned into pytest; it is ended here\n")
        except Exception:  # noqa: BLE001 - a closed stream: nothing left to say
            pass
        _flush_streams()
        self.real_exit(0)

    @pytest.hookimpl(trylast=True)
    def pytest_sessionfinish(self, session: pytest.Session) -> None:
        if self.called is not None and session.exitstatus in (pytest.ExitCode.OK, pytest.ExitCode.TESTS_FAILED):
            session.exitstatus = pytest.ExitCode.INTERRUPTED


class TermGuard:
    """SIGTERM as KeyboardInterrupt while scenario work runs (see the module's text)."""

    def __init__(self) -> None:
        try:  # the terminal, for a last word while pytest captures the test's output
            self.terminal_fd = os.dup(2)
        except OSError:
            self.terminal_fd = None
        self.installed = False
        self.used = False  # scenario work ran in this process
        self.terminated = False  # a SIGTERM ended the run: the next one ends the process
        self.previous: Any = None
        self.deferred = False  # while the report is written: remember, raise nothing
        self.pending = False  # a SIGTERM arrived while deferred
        self.int_pending = False  # a Ctrl-C arrived while the report was written
        self.answered = threading.Event()
        self.seen = 0
        self._wakeup: tuple[int, int] | None = None

    def usable(self) -> bool:
        return threading.current_thread() is threading.main_thread() and hasattr(signal, "SIGTERM")

    def install(self, deferred: bool = False) -> None:
        """Scenario work runs (only in the main thread, only over SIGTERM's default action)."""
        self.deferred = deferred
        self.used = True  # scenario work ran here: its report is written whole (SIGINT too)
        if self.installed or self.terminated or not self.usable():
            return
        if signal.getsignal(signal.SIGTERM) is not signal.SIG_DFL:
            return  # somebody else handles SIGTERM: leave it to them
        self.previous = signal.signal(signal.SIGTERM, self._handle)
        self.installed = True
        self._watch()

    def uninstall(self) -> None:
        """Scenario work is over: SIGTERM is what it was before."""
        self.deferred = False
        if not self.installed or not self.usable():
            return
        self.installed = False
        signal.signal(signal.SIGTERM, self.previous)
        self._unwatch()

    # -- hooks (this object is registered as a plugin of its config) ------------------------
    @pytest.hookimpl(wrapper=True)
    def pytest_runtest_protocol(self, item: pytest.Item, nextitem: pytest.Item | None) -> Any:
        if item.get_closest_marker("scenario") is None:
            return (yield)
        self.install()
        try:
            return (yield)
        finally:
            if nextitem is not None and nextitem.get_closest_marker("scenario") is None:
                self.uninstall()  # plain tests next: SIGTERM is theirs again

    @pytest.hookimpl(wrapper=True, tryfirst=True)
    def pytest_runtest_logreport(self, report: pytest.TestReport) -> Any:
        """Every plugin's handling of one report (the error table's, JUnit's, the terminal's)
        happens whole: a SIGTERM or Ctrl-C arriving meanwhile waits until they all have it, so
        the error table and the JUnit file hold the same cases. (tryfirst: the outermost
        wrapper, so a conftest's wrapper is inside too.)"""
        with signals_held(self):
            return (yield)

    @pytest.hookimpl(wrapper=True, tryfirst=True)
    def pytest_sessionfinish(self, session: pytest.Session) -> Any:
        # the report is written whole: a SIGTERM meanwhile waits for it, then the run ends
        # as interrupted (a second SIGTERM still ends the process at once). Ctrl-C likewise:
        # it raised KeyboardInterrupt wherever the report was, and the run ended with a raw
        # traceback and no summary, index or JUnit file; a second Ctrl-C still aborts
        hold_int = False
        if self.used:
            self.install(deferred=True)
            hold_int = self.usable() and signal.getsignal(signal.SIGINT) is signal.default_int_handler
            if hold_int:
                signal.signal(signal.SIGINT, self._handle_int)
        try:
            return (yield)
        finally:
            if hold_int:
                signal.signal(signal.SIGINT, signal.default_int_handler)
            self.uninstall()
            if self.pending or self.int_pending:
                session.exitstatus = pytest.ExitCode.INTERRUPTED

    def _handle_int(self, signum: int, frame: Any) -> None:
        if self.int_pending:  # a second Ctrl-C: the user means it
            signal.signal(signal.SIGINT, signal.default_int_handler)
            raise KeyboardInterrupt
        self.int_pending = True
        try:
            os.write(self.terminal_fd if self.terminal_fd is not None else 2,
                     b"\navscenario: Ctrl-C: finishing the report first (Ctrl-C again to abort it)\n")
        except OSError:
            pass

    def pytest_unconfigure(self, config: pytest.Config) -> None:
        self.uninstall()
        if self.terminal_fd is not None:
            os.close(self.terminal_fd)
            self.terminal_fd = None

    def release(self) -> None:
        """End a deferral: a SIGTERM that arrived meanwhile is answered now (raises)."""
        self.deferred = False
        if self.pending:
            self.pending = False
            self._handle(signal.SIGTERM, None)

    def _handle(self, signum: int, frame: Any) -> None:
        self.answered.set()
        if self.deferred:
            self.pending = True
            return
        signal.signal(signal.SIGTERM, signal.SIG_DFL)  # a second SIGTERM ends the process
        self.installed, self.terminated = False, True
        self._unwatch()
        raise KeyboardInterrupt("SIGTERM")

    # -- the watcher: sees each SIGTERM through the wakeup fd, whatever the main thread does
    def _watch(self) -> None:
        if self._wakeup is not None:
            return
        read, write = os.pipe()
        os.set_blocking(write, False)
        try:
            old = signal.set_wakeup_fd(write, warn_on_full_buffer=False)
        except (ValueError, OSError):
            os.close(read)
            os.close(write)
            return
        if old != -1:  # somebody else's wakeup fd (an event loop): keep theirs, no watcher
            signal.set_wakeup_fd(old)
            os.close(read)
            os.close(write)
            return
        self._wakeup = (read, write)
        self.answered.clear()
        self.seen = 0
        threading.Thread(target=self._watcher, args=(read,), name="avscenario-sigterm",
                         daemon=True).start()

    def _unwatch(self) -> None:
        if self._wakeup is None:
            return
        read, write = self._wakeup
        self._wakeup = None
        try:
            signal.set_wakeup_fd(-1)
        except ValueError:  # not the main thread: cannot happen here, keep it harmless
            pass
        os.close(write)  # the watcher's read returns b"" and it ends; it closes `read`

    def _watcher(self, read: int) -> None:
        try:
            while True:
                data = os.read(read, 64)
                if not data:
                    return
                if signal.SIGTERM in data:
                    self.seen += data.count(signal.SIGTERM)
                    if self.seen >= 2:
                        _die_by_sigterm()
                    threading.Thread(target=self._await_answer, daemon=True).start()
        except OSError:
            return
        finally:
            try:
                os.close(read)
            except OSError:
                pass

    def _await_answer(self) -> None:
        if not self.answered.wait(TERM_GRACE_S):
            text = (f"\navscenario: SIGTERM not answered for {TERM_GRACE_S:g} s (the test is stuck "
                    "in a call that cannot be interrupted); ending the process: the rows of the "
                    "finished cases are on disk\n")
            try:
                os.write(self.terminal_fd if self.terminal_fd is not None else 2, text.encode())
            except OSError:
                pass
            _die_by_sigterm()


@contextlib.contextmanager
def signals_held(guard: TermGuard | None) -> Iterator[None]:
    """What runs inside happens whole: a SIGTERM (while the guard reads it as Ctrl-C) or a
    Ctrl-C arriving meanwhile is raised as KeyboardInterrupt when it has ended. Only while
    scenario work runs and in the main thread (where signal handlers run: another thread's
    work, a watchdog's report, is not cut by them); inside an outer hold, the outer one's.

    Raised anywhere, the interrupt can cut one report's handling between two plugins (pytest's
    JUnit writer has the report, the error table not), or drop an xdist controller's event it
    took from its queue and had not handled yet."""
    hold = (guard is not None and guard.installed and not guard.deferred
            and threading.get_ident() == threading.main_thread().ident)
    if hold:
        guard.deferred = True
    # Ctrl-C likewise: pytest's own SIGINT handling (KeyboardInterrupt) resumes afterwards.
    # Through _signal, signal's C core: the same calls without the wrapping of handlers and
    # numbers into enums, ~2/3 of a hold's cost (an xdist controller holds once per event, six
    # events an item)
    interrupted: list[int] = []
    hold_int = hold and _signal.getsignal(_SIGINT) is _signal.default_int_handler
    if hold_int:
        _signal.signal(_SIGINT, lambda signum, frame: interrupted.append(signum))
    try:
        yield
    finally:
        if hold_int:
            _signal.signal(_SIGINT, _signal.default_int_handler)
        if hold:
            guard.release()
            if interrupted:
                raise KeyboardInterrupt


@contextlib.contextmanager
def whole_xdist_events(config: pytest.Config) -> Iterator[None]:
    """An xdist controller's run loop, where a stop lands only while it waits for an event,
    never between taking one from its queue and handling it (that event would be lost: an
    item's setup report, say, whose call report then reaches JUnit without its row)."""
    from .stash import guard_key

    guard = config.stash.get(guard_key, None)
    dsession = config.pluginmanager.getplugin("dsession")
    events = getattr(dsession, "queue", None)
    loop_once = getattr(dsession, "loop_once", None)
    if loop_once is None or not hasattr(events, "not_empty") or not hasattr(dsession, "_active_nodes"):
        yield  # an xdist this was not written for: its own loop, unguarded
        return

    def loop_once_whole() -> None:
        with events.not_empty:  # waiting (interruptible): nothing is in hand yet
            while not len(events.queue) and dsession._active_nodes:
                events.not_empty.wait(2.0)
        with signals_held(guard):
            loop_once()  # takes the queued event at once and handles it

    dsession.loop_once = loop_once_whole
    try:
        yield
    finally:
        del dsession.loop_once  # the class's own again


def _end_children() -> None:
    """Stop the AV stacks this process spawned (the hard exits below skip atexit)."""
    stacks = sys.modules.get("pytest_avscenario.stack.client")
    if stacks is not None:
        try:
            stacks.stop_processes()
        except Exception:  # noqa: BLE001 - on the way out: the process ends regardless
            pass


def _flush_streams() -> None:
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except Exception:  # noqa: BLE001 - a closed stream: nothing left to flush
            pass


def _die_by_sigterm() -> None:
    """End the process as SIGTERM's default action would (status 143 to a shell); every
    finished row is on disk already (the error table is flushed per row)."""
    _end_children()
    _flush_streams()
    _REAL_EXIT(128 + signal.SIGTERM)


def shorten_interrupt(config: pytest.Config, excinfo: Any) -> None:
    """A Ctrl-C's traceback, cut to the frame it landed in, unless ``--full-trace``.

    pytest's terminal renders the whole traceback of an interrupt (each frame's source, found
    by parsing its whole file, and its arguments) only to print the last frame's location
    without ``--full-trace``: 60-odd frames deep in pytest, pluggy and xdist that took seconds
    in the controller and in every worker at once — most of the ~12 s a Ctrl-C under ``-n 2``
    took to stop."""
    if hasattr(config, "workerinput"):
        # an xdist worker's terminal is nobody's (the controller prints the run): its summary
        # is skipped, and with it the imports other plugins' summary hooks make — hypothesis's
        # imports Hypothesis whole — which the controller would wait for, as it waits for each
        # worker's end to be sure no report of the stopped run is still on its way
        try:
            config.pluginmanager.unregister(name="terminalreporter")
        except Exception:  # noqa: BLE001 - already gone, or never there
            pass
    if getattr(config.option, "fulltrace", False):
        return
    try:
        traceback = excinfo.traceback
        if len(traceback) > 1:
            excinfo.traceback = traceback[-1:]
        # and rendered as Python renders it: pytest prints only its crash line (file, line,
        # "KeyboardInterrupt"), the same either way, but its own rendering of even one frame
        # parses that frame's whole file first (threading.py or this module: 0.1-0.2 s of
        # CPU in the controller and in each worker at once)
        excinfo.getrepr = functools.partial(type(excinfo).getrepr, excinfo, style="native")
    except Exception:  # noqa: BLE001 - an ExceptionInfo of another shape: render it as it is
        pass


def _running_items(dsession: Any, nodes: list[Any]) -> dict[Any, str]:
    """The item each worker runs (the first of those the scheduler sent it and it has not
    finished), where the scheduler says so (``--dist load``/``worksteal``/``each``)."""
    sched = getattr(dsession, "sched", None)
    pending = getattr(sched, "node2pending", None)
    collection = getattr(sched, "collection", None)
    if not isinstance(pending, dict):
        return {}
    out = {}
    for node in nodes:
        try:
            first = pending.get(node)
            if first:
                out[node] = collection[first[0]] if collection is not None else ""
        except Exception:  # noqa: BLE001 - a scheduler of another shape: say less
            pass
    return out


def end_workers(config: pytest.Config, wait_s: float = 5.0) -> None:
    """An interrupted xdist controller ends its workers at once — SIGTERM reaches each as it
    reaches a run of its own, so none goes on running, and storing counterexamples for, cases
    this run will not report — and then reports what they sent until they ended.

    A worker's end is its last event ("workerfinished", or "errordown" when its connection
    closed), queued after everything it sent: reading until then, not until its process
    exits, is what makes sure no report is still in the connection's reading thread. (An
    xdist worker does not exit by itself: it waits for the controller to close it.)"""
    import queue
    import time

    dsession = config.pluginmanager.getplugin("dsession")
    # the workers whose end the controller has not handled yet
    nodes = list(getattr(dsession, "_active_nodes", ()) or ())
    _say_where_workers_stopped(config, nodes, _running_items(dsession, nodes))
    for node in nodes:
        popen = getattr(getattr(getattr(node, "gateway", None), "_io", None), "popen", None)
        if popen is not None and popen.poll() is None:
            try:
                popen.send_signal(signal.SIGTERM)
            except OSError:
                pass
    events = getattr(dsession, "queue", None)
    report = getattr(dsession, "worker_testreport", None)
    if events is None or report is None:
        return
    running = set(nodes)
    deadline = time.monotonic() + wait_s
    while True:
        left = deadline - time.monotonic()
        try:  # once all have ended (or the time is up), what is queued, then no more
            name, kwargs = events.get(timeout=left) if running and left > 0 else events.get_nowait()
        except queue.Empty:
            break
        if name in ("workerfinished", "errordown"):
            node = kwargs.get("node")
            running.discard(node)
            if name == "workerfinished":
                # what xdist does first with a worker's end: plugins take its output (the
                # coverage data pytest-cov's workers collected, say). Its "node down" lines
                # and worker restarts are left out: the run is stopping
                try:
                    config.hook.pytest_testnodedown(node=node, error=None)
                except Exception:  # noqa: BLE001 - one plugin's trouble: the others still end
                    pass
            _let_go(config, node)
        elif name == "testreport":
            try:
                report(**kwargs)
            except Exception:  # noqa: BLE001 - one report we cannot read: the others still count
                pass


def _let_go(config: pytest.Config, node: Any) -> None:
    """A worker whose end the controller has read exits now, while the controller writes the
    report (xdist would let it go only after the report: its interpreter's end, a second or
    so on a busy machine, was one more wait after a Ctrl-C); the controller still waits for
    its process at its own end (:func:`_wait_let_go`), as xdist does."""
    from .stash import let_go_key

    gateway = getattr(node, "gateway", None)
    if gateway is None or not hasattr(gateway, "exit"):
        return
    try:
        gateway.exit()  # execnet: the worker is told to exit; waiting for it is left to us
    except Exception:  # noqa: BLE001 - a gateway gone already: xdist's teardown copes
        return
    gone = config.stash.get(let_go_key, None)
    if gone is None:
        gone = config.stash[let_go_key] = []
        config.add_cleanup(lambda: _wait_let_go(gone))
    gone.append(gateway)


def _wait_let_go(gateways: list[Any], wait_s: float = 10.0) -> None:
    """Wait for the workers let go early (what xdist's teardown waits for, and with its
    time limit: one still running then is killed)."""
    import time

    deadline = time.monotonic() + wait_s
    for gateway in gateways:
        popen = getattr(getattr(gateway, "_io", None), "popen", None)
        try:
            gateway.join(max(0.0, deadline - time.monotonic()))  # its receiving thread
            if popen is not None:
                popen.wait(max(0.0, deadline - time.monotonic()))
        except Exception:  # noqa: BLE001 - past the time limit, or an odd gateway
            if popen is not None and popen.poll() is None:
                try:
                    popen.kill()
                    popen.wait()
                except OSError:
                    pass


def _say_where_workers_stopped(config: pytest.Config, nodes: list[Any], running: dict[Any, str]) -> None:
    """One line per worker (their own tracebacks are not shown: a worker's Ctrl-C is the
    run's, not a fault of the worker)."""
    terminal = config.pluginmanager.getplugin("terminalreporter")
    if terminal is None:
        return
    for node in nodes:
        name = getattr(getattr(node, "gateway", None), "id", None) or str(node)
        at = running.get(node)
        try:
            terminal.write_line(f"avscenario: worker {name} interrupted " + (f"at {at}" if at else "between tests"))
        except Exception:  # noqa: BLE001 - a closed terminal: nothing left to say
            return


_CASE_ID = re.compile(r"(?:^|-)([A-Za-z_][A-Za-z0-9_]*)-(\d+)(?=-|$)")


def crash_row(nodeid: str, names: set[str]) -> CaseRow | None:
    """The error row of scenario item ``nodeid`` whose xdist worker died running it, or None
    when the id names no case (``names``: sampler names and case origins)."""
    test, bracket, rest = nodeid.partition("[")
    if not bracket or not rest.endswith("]"):
        return None
    for match in _CASE_ID.finditer(rest[:-1]):
        name, index = match.group(1), int(match.group(2))
        if name in names:
            from ..outcome import CaseRow

            origin = name if name in ("replay", "example") else "sampled"
            return CaseRow(
                test=test, item=nodeid, sampler=name, index=index, seed=None, origin=origin,
                params={}, rho={}, verdict="error",
                error="the xdist worker running this case died (it crashed, or was ended by a "
                      "signal or os._exit); its parameters were not reported — run the item "
                      "alone to see them")
    return None


def unknown_test_info(sampler: str) -> dict[str, Any]:
    """What the summary needs of a test none of whose cases reported (every worker running
    one died): no metrics, no parameters known."""
    from ..acceptance import Criteria
    from ..space import FeatureSpace

    return {"metrics": [], "space": FeatureSpace({}).describe(), "accept": Criteria().to_json(),
            "samplers": [sampler], "unknown": True}

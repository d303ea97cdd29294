"""Running one concrete case of a scenario test and judging it.

The plugin calls :func:`run_case` for every scenario item (and again for each candidate
while shrinking): it calls the test function with the case's ``case`` and ``world``,
takes the trajectory the test recorded (``world.trajectory``, or one the test returned),
evaluates the declared monitors and returns a :class:`~.outcome.CaseOutcome` — plain data,
no pytest report objects. A test body that raises ``AssertionError`` is a failure like a violated
monitor; any other exception (a driver that raised, a bad scene) makes the case an error.
"""

from __future__ import annotations

import signal
import threading
import time
from typing import Any, Callable, Mapping

from .case import Case
from .outcome import CaseOutcome


class CaseTimeout(BaseException):
    """Raised inside a case that ran past its time limit.

    A BaseException, so that a scenario body or driver catching ``Exception`` cannot swallow it.
    """


#: seconds a case may go on past its time limit before ``on_stuck`` ends it the hard way
GRACE_S = 3.0
#: seconds after GRACE_S before a case that never returned to Python (one C call holding the
#: interpreter: no watchdog thread runs) is ended from outside, by ``on_stuck.arm``'s sentinel
LAST_RESORT_S = 2.0
#: after the limit, CaseTimeout is raised again this often (a body or driver that swallows it
#: with a bare ``except:`` meets it again at once)
RETRY_S = 0.25


class TimeLimit:
    """Ends the code between :meth:`start` and :meth:`stop` with :class:`CaseTimeout` after
    ``seconds`` of wall time.

    Uses SIGALRM (it interrupts pure-Python loops and sleeps alike) in the main thread of a
    POSIX process — where pytest, and pytest-xdist's workers, run tests — and raises again
    every :data:`RETRY_S` until the code ends. Code that still does not end (it swallows every
    interrupt, or is stuck in one long C call that no signal handler can enter) is handed to
    ``on_stuck(ran_s)`` from a watchdog thread :data:`GRACE_S` seconds after the limit; the
    plugin's ``on_stuck`` records the case and ends the process. Code that holds the
    interpreter in one C call lets no thread run: an ``on_stuck`` with ``arm(after_s)`` and
    ``disarm()`` is armed for :data:`LAST_RESORT_S` more at the start and disarmed at the end
    (the plugin's hands the case's row to a process outside, which ends this one). Elsewhere (no ``seconds``,
    another thread, no SIGALRM) it does nothing: executors that run cases in threads or
    remotely bound them themselves.

    :meth:`stop` always ends the limit, even when an alarm lands while it runs: the handler
    raises only while the limit is live, and ``stop`` retries until it has made it not live,
    under a lock the watchdog takes too (a case that ends as the watchdog fires is either
    stuck or done, never both).
    """

    def __init__(self, seconds: float | None, on_stuck: Callable[[float], None] | None = None):
        self.seconds = seconds
        self.on_stuck = on_stuck
        self.usable = (seconds is not None and hasattr(signal, "setitimer")
                       and threading.current_thread() is threading.main_thread())
        self.live = False
        self.lock = threading.Lock()
        self.t0 = 0.0
        self.previous: Any = None
        self.watchdog: threading.Timer | None = None

    def _expire(self, signum: int, frame: Any) -> None:
        if self.live:
            raise CaseTimeout(f"the case ran longer than its time limit of {self.seconds:g} s")

    def _stuck(self) -> None:
        with self.lock:  # held while on_stuck ends the process: stop() waits, or was first
            if self.live:
                self.on_stuck(time.monotonic() - self.t0)  # type: ignore[misc]

    def start(self) -> None:
        if not self.usable:
            return
        self.t0 = time.monotonic()
        self.live = True
        self.previous = signal.signal(signal.SIGALRM, self._expire)
        signal.setitimer(signal.ITIMER_REAL, float(self.seconds), RETRY_S)  # type: ignore[arg-type]
        if self.on_stuck is not None:
            self.watchdog = threading.Timer(float(self.seconds) + GRACE_S, self._stuck)  # type: ignore[arg-type]
            self.watchdog.daemon = True
            self.watchdog.name = "avscenario-case-watchdog"
            self.watchdog.start()
            arm = getattr(self.on_stuck, "arm", None)
            if arm is not None:
                arm(float(self.seconds) + GRACE_S + LAST_RESORT_S)  # type: ignore[arg-type]

    def stop(self) -> None:
        if not self.usable:
            return
        while True:
            try:  # an alarm may still land here: retry until the limit is not live
                with self.lock:
                    self.live = False
                break
            except CaseTimeout:
                continue
        signal.setitimer(signal.ITIMER_REAL, 0)
        if self.watchdog is not None:
            self.watchdog.cancel()
            disarm = getattr(self.on_stuck, "disarm", None)
            if disarm is not None:
                disarm()
        if self.previous is not None:
            signal.signal(signal.SIGALRM, self.previous)


def run_case(
    func: Callable[..., Any],
    argnames: tuple[str, ...],
    fixtures: Mapping[str, Any],
    case: Case,
    monitor_set: Any,
    make_world: Callable[[Case], Any] | None,
    timeout_s: float | None = None,
    on_stuck: Callable[[float], None] | None = None,
) -> CaseOutcome:
    """Call the test body for ``case`` and judge what it recorded.

    ``fixtures`` holds the values of the test's other fixtures; ``case`` replaces the
    ``case`` argument and, when the test requests ``world``, ``make_world(case)`` builds a
    fresh one (``None`` means: use ``fixtures["world"]`` as it is). ``timeout_s`` bounds the
    body (see :class:`TimeLimit`, which hands a case that will not stop to ``on_stuck``); a
    case that runs past it is an error saying how long it ran.

    Whatever the body raises becomes the outcome, except what must end the run or belongs to
    pytest's own flow: ``KeyboardInterrupt``, ``pytest.exit()``, ``pytest.skip()`` and
    ``pytest.xfail()`` go on up. ``pytest.fail()`` is a failure like ``AssertionError``;
    ``sys.exit()`` in the body or the driver is an error that says so.
    """
    from .trajectory import Trajectory

    args = dict(fixtures)
    args["case"] = case
    world = None
    if "world" in argnames:
        world = make_world(case) if make_world is not None else args["world"]
        args["world"] = world
    outcome = CaseOutcome(params=dict(case.params), verdict="pass")
    t0 = time.perf_counter()
    ret = None
    limit = TimeLimit(timeout_s, on_stuck)
    try:
        try:
            limit.start()
            ret = func(**{a: args[a] for a in argnames})
        finally:
            limit.stop()  # whatever happens here: no alarm outlives the body
    except CaseTimeout as exc:
        ran = time.perf_counter() - t0
        outcome.verdict, outcome.exc = "error", exc
        outcome.error = f"CaseTimeout: {exc} (ran {ran:.2f} s)"
    except AssertionError as exc:
        outcome.verdict, outcome.exc = "fail", exc
        outcome.error = _one_line(exc)
    except KeyboardInterrupt:
        raise
    except BaseException as exc:  # the body, the driver or the scene failed: an error, not a pass
        kind = _pytest_outcome(exc)
        if kind in ("Exit", "Skipped", "XFailed"):
            raise
        if kind == "Failed":  # pytest.fail(...): the body judged the case a failure
            outcome.verdict, outcome.exc = "fail", exc
            outcome.error = _one_line(exc)
        elif isinstance(exc, SystemExit):
            outcome.verdict, outcome.exc = "error", exc
            # a subclass says itself what was called (os._exit, through the plugin's guard)
            outcome.error = (f"SystemExit: the test body or its driver called sys.exit({exc.code!r}); "
                             "a scenario case cannot end the test run") if type(exc) is SystemExit \
                else f"{type(exc).__name__}: {exc}"
        else:
            outcome.verdict, outcome.exc = "error", exc
            outcome.error = f"{type(exc).__name__}: {_one_line(exc)}"
    finally:
        outcome.sim_time_s = time.perf_counter() - t0
        log = getattr(case.rng, "log", None)
        outcome.drawn = log() if callable(log) else None

    traj = ret if isinstance(ret, Trajectory) else getattr(world, "trajectory", None)
    outcome.trajectory = traj
    outcome.world = world
    if traj is not None:
        outcome.score = _driving_score(traj)
    if monitor_set is None or not monitor_set.names:
        return outcome
    if traj is None:
        if outcome.exc is None:
            outcome.verdict = "error"
            outcome.error = (
                "the scenario declares monitors but produced no trajectory: request the "
                "`world` fixture and call world.run(...), or return a Trajectory"
            )
        return outcome
    from .monitors import MonitorError

    try:
        verdict = monitor_set.evaluate(traj)
    except MonitorError as exc:
        if outcome.exc is None:
            outcome.verdict, outcome.exc = "error", exc
            outcome.error = f"MonitorError: {exc}"
        return outcome
    outcome.results = dict(verdict.results)
    outcome.rho = {k: float(v) for k, v in verdict.rho.items()}
    outcome.violated = list(verdict.violated)
    from .monitors.base import first_violation

    for monitor in monitor_set:  # when each violated requirement first failed (for reports)
        res = outcome.results.get(monitor.name)
        if res is not None and res.rho < 0:
            try:
                outcome.first[monitor.name] = first_violation(monitor, traj, res)
            except Exception:  # a convenience of the report: never the verdict's business
                pass
    if outcome.verdict == "pass" and outcome.violated:
        outcome.verdict = "fail"
    return outcome


def _driving_score(traj: Any) -> dict[str, Any] | None:
    """The run's driving score as JSON data; a convenience of the report, never the
    verdict's business (a recording it cannot score has none)."""
    from .monitors.score import driving_score

    try:
        got = driving_score(traj)
    except Exception:  # noqa: BLE001 - a hand-built trajectory may carry anything in meta
        return None
    return None if got is None else got.to_json()


def _pytest_outcome(exc: BaseException) -> str | None:
    """``Failed``, ``Skipped``, ``XFailed`` or ``Exit`` for pytest's flow-control exceptions
    (``pytest.fail()`` and friends), else None. Known by their module (nothing below the
    plugin imports pytest); pytest shows some of them as ``builtins``, but their base is its own."""
    mro = type(exc).__mro__
    if not any(cls.__module__ == "_pytest.outcomes" for cls in mro):
        return None
    for name in ("Exit", "XFailed", "Skipped", "Failed"):
        if any(cls.__name__ == name for cls in mro):
            return name
    return None


def _one_line(exc: BaseException) -> str:
    text = str(exc).strip().splitlines()
    return text[0] if text else type(exc).__name__

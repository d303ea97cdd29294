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
from contextlib import contextmanager
from typing import Any, Callable, Mapping

from .case import Case
from .outcome import CaseOutcome


class CaseTimeout(BaseException):
    """Raised inside a case that ran past its time limit.

    A BaseException, so that a scenario body or driver catching ``Exception`` cannot swallow it.
    """


@contextmanager
def time_limit(seconds: float | None):
    """End the enclosed code with :class:`CaseTimeout` after ``seconds`` of wall time.

    Uses SIGALRM (it interrupts pure-Python loops and sleeps alike) in the main thread of a
    POSIX process — where pytest, and pytest-xdist's workers, run tests. Elsewhere the limit
    is not enforced here; executors that run cases in threads or remotely bound them themselves.
    """
    usable = (seconds is not None and hasattr(signal, "setitimer")
              and threading.current_thread() is threading.main_thread())
    if not usable:
        yield
        return

    def expire(signum: int, frame: Any) -> None:
        raise CaseTimeout(f"the case ran longer than its time limit of {seconds:g} s")

    previous = signal.signal(signal.SIGALRM, expire)
    signal.setitimer(signal.ITIMER_REAL, float(seconds))
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, previous)


def run_case(
    func: Callable[..., Any],
    argnames: tuple[str, ...],
    fixtures: Mapping[str, Any],
    case: Case,
    monitor_set: Any,
    make_world: Callable[[Case], Any] | None,
    timeout_s: float | None = None,
) -> CaseOutcome:
    """Call the test body for ``case`` and judge what it recorded.

    ``fixtures`` holds the values of the test's other fixtures; ``case`` replaces the
    ``case`` argument and, when the test requests ``world``, ``make_world(case)`` builds a
    fresh one (``None`` means: use ``fixtures["world"]`` as it is). ``timeout_s`` bounds the
    body (see :func:`time_limit`); a case that runs past it is an error saying how long it ran.
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
    try:
        with time_limit(timeout_s):
            ret = func(**{a: args[a] for a in argnames})
    except CaseTimeout as exc:
        ran = time.perf_counter() - t0
        outcome.verdict, outcome.exc = "error", exc
        outcome.error = f"CaseTimeout: {exc} (ran {ran:.2f} s)"
    except AssertionError as exc:
        outcome.verdict, outcome.exc = "fail", exc
        outcome.error = _one_line(exc)
    except Exception as exc:  # the body, the driver or the scene failed: an error, not a pass
        outcome.verdict, outcome.exc = "error", exc
        outcome.error = f"{type(exc).__name__}: {_one_line(exc)}"
    finally:
        outcome.sim_time_s = time.perf_counter() - t0

    traj = ret if isinstance(ret, Trajectory) else getattr(world, "trajectory", None)
    outcome.trajectory = traj
    outcome.world = world
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
    if outcome.verdict == "pass" and outcome.violated:
        outcome.verdict = "fail"
    return outcome


def _one_line(exc: BaseException) -> str:
    text = str(exc).strip().splitlines()
    return text[0] if text else type(exc).__name__

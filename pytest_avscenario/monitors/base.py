"""The monitor contract: what every monitor returns, the base class, and plain functions.

A monitor turns one recorded :class:`~pytest_avscenario.trajectory.Trajectory` into a
robustness value ``rho`` (``rho >= 0`` the requirement holds, ``rho < 0`` it is violated,
``|rho|`` says by how much, in the unit of the metric) plus where and when the worst value
happened. This module holds the result type, the :class:`Monitor` base class (which refuses
NaN verdicts), :func:`as_monitor` for plain ``trajectory -> float`` functions, and the small
helpers the concrete monitors share. It knows nothing of highway-env or pytest.
"""

from __future__ import annotations

import abc
import copy
import inspect
import math
import numbers
import weakref
from dataclasses import dataclass
from typing import Any, Callable

import numpy as np

from ..trajectory import Trajectory

__all__ = ["MonitorError", "MonitorResult", "Monitor", "FunctionMonitor", "as_monitor", "first_violation"]


class MonitorError(ValueError):
    """A monitor was built with bad arguments, or could not give a verdict on a trajectory.

    Raised at construction for bad arguments (becomes a collection error naming the test)
    and at evaluation for NaN or undefined values (becomes an error for that case, never a
    pass).
    """


@dataclass(frozen=True)
class MonitorResult:
    """The verdict of one monitor on one trajectory.

    ``rho`` is the robustness in the metric's unit (m, s, ...), may be ``±inf`` and is never
    NaN; ``threshold`` the requirement's bound in the same unit (None when the monitor has
    none); ``t`` [s] the time of the worst (deciding) value and ``agent`` the name of the
    agent involved, both None when no single step or agent decided; ``detail`` short text
    for humans.
    """

    name: str
    rho: float
    threshold: float | None = None
    t: float | None = None
    agent: str | None = None
    detail: str = ""

    @property
    def ok(self) -> bool:
        """True when the requirement holds (``rho >= 0``)."""
        return self.rho >= 0

    def to_json(self) -> dict[str, Any]:
        """A JSON-safe dict; ``±inf`` become the strings ``"inf"``/``"-inf"``."""
        from ..codec import rho_to_json

        return {
            "name": self.name,
            "rho": rho_to_json(self.rho),
            "threshold": None if self.threshold is None else rho_to_json(self.threshold),
            "t": self.t,
            "agent": self.agent,
            "detail": self.detail,
        }

    @classmethod
    def from_json(cls, data: dict[str, Any]) -> "MonitorResult":
        from ..codec import rho_from_json

        thr = data.get("threshold")
        return cls(
            name=str(data["name"]),
            rho=rho_from_json(data["rho"]),
            threshold=None if thr is None else rho_from_json(thr),
            t=None if data.get("t") is None else float(data["t"]),
            agent=data.get("agent"),
            detail=str(data.get("detail", "")),
        )


class Monitor(abc.ABC):
    """Base of every monitor: a name used in reports and ``evaluate(trajectory)``.

    Subclasses implement :meth:`_evaluate`; :meth:`evaluate` checks the input type and turns
    a NaN robustness into a :class:`MonitorError` naming the monitor, so a broken trajectory
    can never pass. Calling a monitor returns its ``rho`` alone.
    """

    name: str = "monitor"
    threshold: float | None = None

    def evaluate(self, trajectory: Trajectory) -> MonitorResult:
        if not isinstance(trajectory, Trajectory):
            raise MonitorError(
                f"monitor {self.name!r} needs a Trajectory, got {type(trajectory).__name__}; "
                "build one with Trajectory.from_arrays(t, agents={...})"
            )
        result = self._evaluate(trajectory)
        rho = float(result.rho)
        if math.isnan(rho):
            raise MonitorError(
                f"monitor {self.name!r} produced NaN robustness"
                + (f" ({result.detail})" if result.detail else "")
                + "; the trajectory has undefined values where the monitor needs them"
            )
        if result.name != self.name or rho is not result.rho:
            result = MonitorResult(self.name, rho, result.threshold, result.t, result.agent,
                                   result.detail)
        return result

    @abc.abstractmethod
    def _evaluate(self, trajectory: Trajectory) -> MonitorResult:
        """Compute the result; may return NaN rho (evaluate turns it into an error)."""

    def series(self, trajectory: Trajectory) -> np.ndarray | None:
        """This monitor's robustness at every step, ``(n_steps,)`` in its unit, for pictures
        and the card's recording (ρ(t) beside the run's ρ); ``None`` for a metric of the
        whole run (progress, lane keeping: no value belongs to one step). A monitor that
        has one overrides this; the base has none."""
        return None

    def named(self, name: str) -> "Monitor":
        """A copy of this monitor reported under ``name`` (e.g. two distance thresholds)."""
        clone = copy.copy(self)
        clone.name = check_name(name)
        return clone

    def __call__(self, trajectory: Trajectory) -> float:
        return self.evaluate(trajectory).rho

    def __repr__(self) -> str:
        thr = "" if self.threshold is None else f", threshold={self.threshold:g}"
        return f"<{type(self).__name__} {self.name!r}{thr}>"


class FunctionMonitor(Monitor):
    """A plain function ``trajectory -> float`` (or ``-> MonitorResult``) used as a monitor."""

    def __init__(self, fn: Callable[[Trajectory], Any], name: str | None = None):
        self.fn = fn
        self.name = check_name(name) if name is not None else _callable_name(fn)

    def _evaluate(self, trajectory: Trajectory) -> MonitorResult:
        out = self.fn(trajectory)
        if isinstance(out, MonitorResult):
            return out
        if isinstance(out, (bool, np.bool_)):
            raise MonitorError(
                f"monitor {self.name!r} returned a bool; a monitor returns a robustness float "
                "(>= 0 holds, < 0 violated, magnitude = margin), e.g. `return gap_m - 5.0`"
            )
        if isinstance(out, np.ndarray) and out.ndim == 0:
            out = out.item()
        if not isinstance(out, numbers.Real):
            raise MonitorError(
                f"monitor {self.name!r} returned {type(out).__name__}, expected a float "
                "robustness (>= 0 holds, < 0 violated)"
            )
        return MonitorResult(self.name, float(out), detail=f"{self.name} returned {float(out):g}")


def _callable_name(fn: Any) -> str:
    name = getattr(fn, "__name__", None)
    if name is None and hasattr(fn, "func"):  # functools.partial
        name = getattr(fn.func, "__name__", None)
    if name is None:
        name = type(fn).__name__
    return "lambda" if name == "<lambda>" else name


def as_monitor(obj: Any, name: str | None = None) -> Monitor:
    """Accept a :class:`Monitor` or a plain callable ``trajectory -> float``.

    A callable is named after the function (``name`` overrides; lambdas are named
    ``"lambda"``). Anything else, a monitor factory passed without calling it (``distance``
    instead of ``distance()``), or a callable that cannot take one positional argument raises
    :class:`MonitorError`.
    """
    if isinstance(obj, Monitor):
        return obj.named(name) if name else obj
    if getattr(obj, "_avs_monitor_factory", False):
        fname = getattr(obj, "__name__", "monitor")
        raise MonitorError(
            f"{fname} is a monitor factory; call it to build a monitor, e.g. {fname}()"
        )
    if isinstance(obj, type):
        raise MonitorError(
            f"expected a monitor or a function trajectory -> float, got the class "
            f"{obj.__name__}; pass an instance"
        )
    if not callable(obj):
        raise MonitorError(
            f"expected a monitor (e.g. distance(5.0)) or a function trajectory -> float, "
            f"got {type(obj).__name__}: {obj!r:.80}"
        )
    try:
        sig = inspect.signature(obj)
    except (TypeError, ValueError):  # builtins without a signature: trust the caller
        sig = None
    if sig is not None:
        try:
            sig.bind(None)
        except TypeError:
            raise MonitorError(
                f"monitor function {_callable_name(obj)!r} must take exactly one argument "
                f"(the trajectory); its signature is {sig}"
            ) from None
    return FunctionMonitor(obj, name)


def factory(fn: Callable[..., Monitor]) -> Callable[..., Monitor]:
    """Mark a function as a monitor factory so ``as_monitor(distance)`` can say what to do."""
    fn._avs_monitor_factory = True  # type: ignore[attr-defined]
    return fn


# -- shared helpers -------------------------------------------------------------------------

def check_threshold(name: str, value: Any, what: str = "threshold") -> float:
    """A finite float, else MonitorError naming the monitor and the argument."""
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, numbers.Real):
        raise MonitorError(f"{name}: {what} must be a number, got {value!r}")
    value = float(value)
    if not math.isfinite(value):
        raise MonitorError(f"{name}: {what} must be finite, got {value!r}")
    return value


def check_name(name: Any) -> str:
    """A monitor name for reports: a non-empty string."""
    if not isinstance(name, str) or not name.strip():
        raise MonitorError(f"a monitor name must be a non-empty string, got {name!r}")
    return name


def check_positive(name: str, value: Any, what: str, *, allow_zero: bool = False) -> float:
    value = check_threshold(name, value, what)
    if value < 0 or (value == 0 and not allow_zero):
        bound = ">= 0" if allow_zero else "> 0"
        raise MonitorError(f"{name}: {what} must be {bound}, got {value!r}")
    return value


#: fields already found finite per trajectory (a run's monitors check the same ones; a
#: trajectory is immutable, so once is enough)
_CHECKED: "weakref.WeakKeyDictionary[Trajectory, set]" = weakref.WeakKeyDictionary()


#: the kinematic fields the monitors check first, all at once
_KINEMATIC = ("x", "y", "vx", "vy", "heading")
_KINEMATIC_SET = frozenset(_KINEMATIC)
#: in a trajectory's checked set: all of them are finite wherever their agent is present
_ALL_KINEMATIC = ("*kinematic", "all")


def check_present_finite(traj: Trajectory, monitor: str, fields: tuple[str, ...],
                         agents: slice | list[int] | None = None) -> None:
    """Raise MonitorError when a field is NaN/inf at a step where its agent is present.

    Absent steps are NaN by contract and are ignored; a non-finite value while present is a
    broken recording, and the message says which agent, field and time.
    """
    done = _CHECKED.get(traj)
    if done is None:
        done = _CHECKED[traj] = set()
        # most monitors read these: one pass over all of them for every agent, and a
        # field-by-field search below only when something is not finite
        # (their sum is finite only where every one is; a sum that overflows only sends
        # the check the long way)
        total = traj.x + traj.y
        for f in _KINEMATIC[2:]:
            total += getattr(traj, f)
        if not (traj.present & ~np.isfinite(total)).any():
            done.update((f, "all") for f in _KINEMATIC)
            done.add(_ALL_KINEMATIC)
    if _ALL_KINEMATIC in done and _KINEMATIC_SET.issuperset(fields):
        return
    key = "all" if agents is None else repr(agents)
    todo = [f for f in fields if (f, "all") not in done and (f, key) not in done]
    if not todo:
        return
    sel = slice(None) if agents is None else agents
    present = traj.present[sel]
    for f in todo:
        arr = getattr(traj, f)[sel]
        bad = present & ~np.isfinite(arr)
        if bad.any():
            a, k = np.argwhere(bad)[0]
            idx = np.arange(traj.n_agents)[sel][a]
            raise MonitorError(
                f"monitor {monitor!r}: {f} of agent {traj.names[idx]!r} is "
                f"{arr[a, k]} at t={traj.t[k]:.3f} s while the agent is present"
            )
        done.add((f, key))


#: values derived from a trajectory that several monitors read (lane projections, the pairs
#: ahead of the ego, the ego's speed...), computed once per trajectory object
_MEMO: "weakref.WeakKeyDictionary[Trajectory, dict]" = weakref.WeakKeyDictionary()


#: the trajectory :func:`memo` answered last (a weak reference) and its dict: a run's monitors
#: ask for one trajectory's dict some forty times in a row
_LAST: tuple = (lambda: None, None)


def memo(traj: Trajectory) -> dict:
    """A dict that lives as long as ``traj``, for values the monitors derive from it once and
    share (a trajectory is immutable; a prefix or a copy is a new object, with a new dict)."""
    global _LAST
    last = _LAST
    if last[0]() is traj:
        return last[1]
    got = _MEMO.get(traj)
    if got is None:
        got = _MEMO[traj] = {}
    _LAST = (weakref.ref(traj), got)
    return got


def fmt_t(traj: Trajectory, step: int | None) -> float | None:
    return None if step is None else float(traj.t[step])


def first_violation(monitor: "Monitor", traj: Trajectory,
                    result: MonitorResult | None = None) -> tuple[float | None, str | None] | None:
    """When and with whom ``monitor``'s requirement was first violated on ``traj``.

    For an invariant (a monitor with ``invariant = True``: the requirement must hold at every
    step, so ρ of a prefix never rises as the prefix grows) this is exact: the shortest prefix
    whose ρ is below zero, found by bisection (about log2(steps) evaluations), at its last
    step's time, or at the moment the monitor names between that step and the one before
    (a collision found between recorded steps). For any other monitor it is the result's own
    deciding moment. None when the requirement holds."""
    result = result if result is not None else monitor.evaluate(traj)
    if not result.rho < 0:
        return None
    if not getattr(monitor, "invariant", False) or traj.n_steps < 2:
        return result.t, result.agent
    lo, hi = 1, traj.n_steps  # ρ(prefix hi) < 0; find the smallest such length
    found = result
    while lo < hi:
        mid = (lo + hi) // 2
        try:
            r = monitor.evaluate(traj.prefix(mid))
        except Exception:
            return result.t, result.agent  # a prefix it cannot judge: keep its own moment
        if r.rho < 0:
            hi, found = mid, r
        else:
            lo = mid + 1
    first = float(traj.t[hi - 1])
    # a contact found between the last two recorded steps of that prefix (a swept collision)
    # happened at its own moment, before the step that records it
    if found.t is not None and hi >= 2 and traj.t[hi - 2] < found.t < first:
        first = float(found.t)
    return first, found.agent if found.agent is not None else result.agent

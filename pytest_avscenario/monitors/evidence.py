"""What a counterexample's pictures and recording show beside the scene, computed in one place.

The time-series figure, the card's recording and the annotated still all show the same
evidence: who the *critical agent* is, the centre distance, footprint gap and time to
collision between it and the ego at every step, the thresholds of the test's distance and
TTC monitors, and ρ(t) of each violated monitor that has a value per step
(:meth:`~pytest_avscenario.monitors.base.Monitor.series`). Only this package knows which
concrete monitor it holds; the report and the simulator receive plain arrays.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Iterable, Mapping, Sequence

import numpy as np

from ..trajectory import Trajectory
from .metrics import (
    TTC_RADIUS_M,
    CollisionMonitor,
    DistanceMonitor,
    TTCMonitor,
    critical_agent,
    footprint_gap,
    pairwise_distance,
    pairwise_ttc,
)

__all__ = ["Evidence", "case_evidence", "critical_hint", "ttc_radius", "threshold_lines", "TTC_RADIUS_M",
           "reads_crash_flags", "critical_agent"]


@dataclass(frozen=True)
class Evidence:
    """Per-step values between the ego and the critical agent, and ρ(t) of violated monitors.

    ``critical``: the critical agent's index in the trajectory (None: the ego is alone);
    ``distance_m``, ``gap_m``, ``ttc_s``: ``(n_steps,)`` toward it (None without one; TTC
    +inf where the pair is on no collision course); ``radius_m``: the TTC circle they use;
    ``rho_t``: per violated monitor name with a series, its ρ at every step."""

    critical: int | None
    radius_m: float
    distance_m: np.ndarray | None = None
    gap_m: np.ndarray | None = None
    ttc_s: np.ndarray | None = None
    rho_t: dict[str, np.ndarray] = field(default_factory=dict)


def ttc_radius(monitors: Iterable[Any]) -> float:
    """The TTC circle [m] of the test's first circle TTC monitor (``ttc(kind="centre")``),
    else the paper's 5 m."""
    return next((m.radius for m in monitors if isinstance(m, TTCMonitor) and m.radius is not None),
                TTC_RADIUS_M)


def critical_hint(violations: Mapping[str, Mapping[str, Any]] | None) -> str | None:
    """The agent a row's ``violations`` name first: the earliest timed violation's, else the
    first that names one (None: nobody)."""
    timed = sorted(((float(w["t"]), w.get("agent")) for w in (violations or {}).values()
                    if w.get("t") is not None), key=lambda ta: ta[0])
    if timed:
        return timed[0][1]
    return next((w.get("agent") for w in (violations or {}).values() if w.get("agent")), None)


def case_evidence(traj: Trajectory, monitors: Sequence[Any] = (), *, agent: str | None = None,
                  t: float | None = None, violated: Iterable[str] = ()) -> Evidence:
    """The evidence of one run: the critical agent (``agent`` when it is another road user,
    else the nearest to the ego at ``t`` [s]), the values toward it, and ρ(t) of the monitors
    named in ``violated`` that have one."""
    radius = ttc_radius(monitors)
    # the TTC the test judges by (footprints in the ego's path, or the paper's circle)
    ttc_monitor = next((m for m in monitors if isinstance(m, TTCMonitor)), None)
    if traj.n_agents < 2:
        return Evidence(critical=None, radius_m=radius)
    k = critical_agent(traj, agent, t)
    violated = set(violated)
    rho_t: dict[str, np.ndarray] = {}
    for m in monitors:
        series = getattr(m, "series", None)  # a user's duck-typed monitor may have none
        if getattr(m, "name", None) in violated and series is not None:
            per = _per_step(series(traj), traj)
            if per is not None:
                rho_t[m.name] = per
    return Evidence(critical=k, radius_m=radius,
                    distance_m=pairwise_distance(traj)[k - 1], gap_m=footprint_gap(traj)[k - 1],
                    ttc_s=(ttc_monitor._values(traj) if ttc_monitor is not None
                           else pairwise_ttc(traj, radius))[k - 1], rho_t=rho_t)


def _per_step(per: Any, traj: Trajectory) -> np.ndarray | None:
    """A monitor's series as ``(n_steps,)``: an STL formula's ``series`` gives ``(ρ, times)``
    over the steps it keeps (the ego present), placed here on their steps (NaN elsewhere);
    anything else of the wrong shape is left out rather than drawn wrong."""
    if per is None:
        return None
    if isinstance(per, tuple) and len(per) == 2:
        rho, times = (np.asarray(a, dtype=float) for a in per)
        if rho.shape != times.shape or rho.ndim != 1:
            return None
        out = np.full(traj.n_steps, np.nan)
        steps = np.searchsorted(traj.t, times)
        ok = (steps < traj.n_steps) & np.isclose(traj.t[np.minimum(steps, traj.n_steps - 1)], times)
        out[steps[ok]] = rho[ok]
        return out
    arr = np.asarray(per, dtype=float)
    return arr if arr.shape == (traj.n_steps,) else None


def threshold_lines(monitors: Iterable[Any]) -> list[tuple[str, float, str]]:
    """``(quantity, threshold, label)`` of each monitor whose threshold a time-series panel
    draws: ``"distance"`` [m] (centre or footprint gap) and ``"ttc"`` [s]."""
    out = []
    for m in monitors:
        if isinstance(m, DistanceMonitor):
            out.append(("distance", m.threshold,
                        f"{m.name} threshold ({'gap' if m.footprint else 'centre'}) {m.threshold:g} m"))
        elif isinstance(m, TTCMonitor):
            out.append(("ttc", m.threshold, f"{m.name} threshold {m.threshold:g} s"))
    return out


def reads_crash_flags(monitor: Any) -> bool:
    """Whether ``monitor`` counts the simulator's crash flags (a collision monitor): its
    violation may name no agent, the crash having happened between two samples."""
    return isinstance(monitor, CollisionMonitor)

"""One violation judged against the same conflict in another run of the case.

The avoidability check runs a counterexample again with a reference driver as the ego and
asks, per violated metric, whether the reference gets into *the same conflict* — not whether
its run violates the metric anywhere. A conflict is what the first violation names:

* the **other agent** (``MonitorResult.agent`` of the first violation): only the reference's
  values toward that agent count, computed on its trajectory cut down to the ego and that
  agent (:func:`conflict_view`). A metric of the ego alone (progress, lane keeping, off road,
  reaching a place: its result names the ego) is judged on the reference's ego alone; a
  violation that names nobody (a plain function, a crash flag without a visible overlap)
  cannot be placed and is unknown;
* the **time**: the reference violates it too when it does so with that agent no later than
  ``window_s`` after the first violation of the run under test (earlier counts: it failed the
  same conflict sooner); it avoids it when it keeps the margin toward that agent over its
  whole run; a violation with that agent only later than the window is unknown — the scene
  has moved on and it may be a conflict of its own.

A **margin** keeps numerical touches from deciding: highway-env stops colliding cars where
their outlines meet, so every real crash has a footprint separation of about -0 m and the
collision ρ alone cannot tell a crash from a graze. For a collision the reference avoids it
only with a separation of at least ``margin`` (default :data:`COLLISION_MARGIN_M`) and
violates it only by touching the agent at an impact speed of at least
:data:`IMPACT_SPEED_MPS`; in between it is unknown. Other metrics are judged on their ρ toward
the agent with a symmetric band: below ``-margin`` violated, from ``+margin`` avoided
(default margin 0: their ρ is not degenerate at a violation).

Plain functions of trajectories; nothing here knows pytest or the simulator.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from ..trajectory import Trajectory
from .base import Monitor
from .metrics import CollisionMonitor, footprint_separation, swept_contacts

__all__ = ["ConflictVerdict", "conflict_view", "crash_partner", "judge_conflict", "CONFLICT_WINDOW_S",
           "COLLISION_MARGIN_M", "IMPACT_SPEED_MPS"]

#: [s] how long after the first violation under test the reference's violation with the same
#: agent still counts as the same conflict: the careful driver reacts 1.15 s late and brakes,
#: so it reaches the same conflict somewhat later than a driver that does not brake
CONFLICT_WINDOW_S = 2.0
#: [m] the footprint separation from the agent a reference must keep to "avoid" a collision:
#: clear of the ≈ -0 m of a real crash and of the centimetres a grazing stop leaves, and
#: about one 0.1-s step of travel at 2 m/s closing speed (closer is a touch between samples)
COLLISION_MARGIN_M = 0.2
#: [m/s] the relative speed at contact from which a touch is an impact: slower is two cars
#: meeting at a standstill, which a sampled trajectory cannot tell from a numerical graze
IMPACT_SPEED_MPS = 0.5


@dataclass(frozen=True)
class ConflictVerdict:
    """What the reference made of one conflict.

    ``agent`` the other agent (the ego's own name for a metric of the ego alone, None when the
    violation named nobody); ``t`` [s] the first violation under test; ``until`` [s] the end of
    the window (None: the whole run); ``avoided`` True (the reference keeps the margin), False
    (it violates it too), None (unknown); ``rho`` the reference's value for this conflict —
    for a collision its smallest footprint separation [m] from the agent, else the metric's ρ
    toward the agent — over the window (None when not evaluated); ``why`` short text.
    """

    metric: str
    agent: str | None
    t: float | None
    until: float | None
    avoided: bool | None
    rho: float | None
    why: str
    ego_alone: bool = False  # a metric of the ego alone: no other road user in the conflict

    def to_json(self) -> dict[str, Any]:
        from ..codec import rho_to_json

        return {"agent": self.agent, "t": self.t, "until": self.until,
                "rho": None if self.rho is None else rho_to_json(self.rho), "why": self.why}


def conflict_view(traj: Trajectory, agent: str | None) -> Trajectory | None:
    """``traj`` cut down to the ego and ``agent`` (the ego alone when ``agent`` is the ego's own
    name); None when ``agent`` is None or not in the run.

    The crash flags are cleared: they are sticky and say nothing of *whom* a car hit, so a
    crash with a third agent would otherwise count against this pair (the collision monitor
    charges an ego crash flag without a visible overlap)."""
    if agent is None or agent not in traj.names:
        return None
    rows = [0] if agent == traj.names[0] else [0, traj.names.index(agent)]
    per_step = {f: getattr(traj, f)[rows] for f in ("x", "y", "vx", "vy", "speed", "heading",
                                                      "lane", "lane_offset", "present", "on_road")}
    return replace(traj, names=tuple(traj.names[i] for i in rows),
                   kinds=tuple(traj.kinds[i] for i in rows), length=traj.length[rows],
                   width=traj.width[rows], crashed=np.zeros((len(rows), traj.n_steps), dtype=bool),
                   **per_step)


def crash_partner(traj: Trajectory) -> tuple[str, float] | None:
    """The agent the ego crashed into, by the simulator's crash flags, and when: the one other
    agent whose flag rose at the step the ego's did (highway-env flags both cars of a collision
    together). None when the ego never crashed or it cannot tell (none, or several, at once).
    It names the other car where the footprints never overlap in the recording (a crash
    between two samples)."""
    ego = np.flatnonzero(traj.crashed[0] & traj.present[0])
    if ego.size == 0 or traj.n_agents < 2:
        return None
    k = int(ego[0])
    rose = traj.crashed[1:, k] & ~(traj.crashed[1:, k - 1] if k > 0 else False)
    together = np.flatnonzero(rose)
    if together.size != 1:
        return None
    return traj.names[1 + int(together[0])], float(traj.t[k])


def _steps_until(traj: Trajectory, until: float | None) -> int:
    if until is None:
        return traj.n_steps
    return max(1, int(np.searchsorted(traj.t, until + 1e-9, side="right")))


def judge_conflict(monitor: Monitor, reference: Trajectory, agent: str | None, t: float | None,
                   *, window_s: float = CONFLICT_WINDOW_S, margin: float | None = None) -> ConflictVerdict:
    """Judge the violation of ``monitor`` under test — first at ``t`` [s] with ``agent`` — on
    the reference's trajectory (see the module doc for the rules)."""
    name = monitor.name
    until = None if t is None or not getattr(monitor, "invariant", False) else float(t) + window_s
    collision = isinstance(monitor, CollisionMonitor)
    if margin is None:
        margin = COLLISION_MARGIN_M if collision else 0.0

    def unknown(why: str, rho: float | None = None) -> ConflictVerdict:
        return ConflictVerdict(name, agent, t, until, None, rho, why)

    if agent is None:
        return unknown("the violation names no agent to find in the reference's run")
    view = conflict_view(reference, agent)
    if view is None:
        return unknown(f"the reference's run has no agent {agent!r}")
    n = _steps_until(view, until)
    with_whom = "" if agent == reference.names[0] else f" with {agent}"
    upto = "" if until is None else f" up to t = {until:.1f} s"
    if collision and view.n_agents == 2:
        partner = crash_partner(reference)
        crashed_at = partner[1] if partner is not None and partner[0] == agent else None
        return _judge_collision(name, view, agent, t, until, n, margin, crashed_at)
    alone = view.n_agents == 1

    def verdict(avoided: bool | None, rho: float | None, why: str) -> ConflictVerdict:
        return ConflictVerdict(name, agent, t, until, avoided, rho, why, ego_alone=alone)

    try:
        within = monitor.evaluate(view.prefix(n)).rho if n < view.n_steps else None
        whole = monitor.evaluate(view).rho
    except Exception as exc:  # a monitor that cannot judge the pair alone (e.g. names a third agent)
        return verdict(None, None, f"{name} cannot be evaluated on the ego{with_whom} alone: {exc}")
    within = whole if within is None else within
    if within < -margin:
        return verdict(False, within, f"violates it too{with_whom}{upto} (rho {within:+.3g})")
    if whole >= margin:
        return verdict(True, within, f"keeps it{with_whom} (rho {whole:+.3g})")
    if within < margin:
        return verdict(None, within, f"within the margin of {margin:g}{with_whom}{upto} (rho {within:+.3g})")
    return verdict(None, within, f"keeps it{with_whom}{upto} but not afterwards (rho {whole:+.3g}): "
                   "a later conflict, maybe another one")


def _judge_collision(name: str, view: Trajectory, agent: str, t: float | None, until: float | None,
                     n: int, margin: float, crashed_at: float | None) -> ConflictVerdict:
    full = footprint_separation(view)
    sep = full[0]  # (T,) metres from that agent, +inf where absent
    # a contact between two recorded steps (the footprints pass through each other, or
    # highway-env pushes the pair apart before the next sample) counts at the step after it
    swept = np.zeros(view.n_steps, dtype=bool)
    if view.n_steps > 1:
        swept[1:] = np.isfinite(swept_contacts(view, separation=full)[0][0])
    window = sep[:n]
    nearest = float(window.min()) if window.size else math.inf
    upto = "" if until is None else f" up to t = {until:.1f} s"
    touching = (window <= 0.0) | swept[:n]
    if crashed_at is not None:  # the simulator's crash with this agent, overlap seen or not
        touching = touching | (view.t[:n] >= crashed_at - 1e-9)
    contact = np.flatnonzero(touching)
    if contact.size:
        k = int(contact[0])
        before = max(k - 1, 0)  # the crash changes speeds from the contact step on
        impact = float(np.hypot(view.vx[0, before] - view.vx[1, before],
                                view.vy[0, before] - view.vy[1, before]))
        if impact >= IMPACT_SPEED_MPS:
            return ConflictVerdict(name, agent, t, until, False, nearest,
                                   f"hits {agent} too, at t = {view.t[k]:.1f} s, {impact:.1f} m/s")
        return ConflictVerdict(name, agent, t, until, None, nearest,
                               f"touches {agent} at t = {view.t[k]:.1f} s at {impact:.2f} m/s only "
                               f"(an impact is >= {IMPACT_SPEED_MPS:g} m/s)")
    overall = float(sep.min()) if sep.size else math.inf
    if crashed_at is not None or swept.any():  # crashed into it, but after the window
        overall = min(overall, 0.0)
    if overall >= margin:
        return ConflictVerdict(name, agent, t, until, True, nearest,
                               f"keeps {overall:.2f} m from {agent}" if math.isfinite(overall)
                               else f"never meets {agent}")
    if nearest < margin:
        return ConflictVerdict(name, agent, t, until, None, nearest,
                               f"comes within {nearest:.2f} m of {agent}{upto} (margin {margin:g} m)")
    if crashed_at is not None or swept.any():
        later = crashed_at if crashed_at is not None else float(view.t[int(np.argmax(swept))])
        what = "crashes into it"
    else:
        later, what = float(view.t[int(np.argmin(sep))]), f"comes within {overall:.2f} m"
    return ConflictVerdict(name, agent, t, until, None, nearest,
                           f"keeps clear of {agent}{upto} but {what} at t = {later:.1f} s: "
                           "a later conflict, maybe another one")

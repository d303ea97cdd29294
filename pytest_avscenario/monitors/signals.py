"""Running a red light, under the name CARLA ScenarioRunner gives it (``RunningRedLightTest``).

CARLA charges a red light when the vehicle crosses the light's stop line while the light is
red, judged at its tail: the short segment from 0.8 half-lengths behind its centre to 1 m
behind its rear must not meet the line across the lane while red — a car whose front is
over the line when the light turns red but clears the junction is not charged, one whose
rear crosses on red is. Here the same point (``point="tail"``: 0.8 half-lengths behind the
centre, the default) or the front bumper (``point="front"``: entering on red, as traffic
codes that forbid entering the junction write it) crosses the stop position.

The recording carries the lights (``sim/signals.py``, ``sim/recording.py``):
``meta["lights"]`` lists the lights of every junction whose lights rule a recorded lane
``{"id", "controller", "x", "y",
"heading", "stops": [{"lane", "s" [m along it], "x", "y", "heading", "width"}]}`` and
``signals["light.<id>"]`` its state at every sample (0 green, 1 amber, 2 red). The monitor
places each stop position on the ego's route (``meta["ego_route"]``) and measures how far that
point of the ego is from it.

Robustness is in metres, continuous where it matters to a falsifier (the crossing that comes
just before or just after the light turns red):

* the ego crossed the stop position on red: ρ = minus the distance the point was before
  the stop position when the light turned red (the room it had to stop and did not
  use) — a car that crosses at the moment of the change has ρ = 0⁻;
* it crossed on green or amber: ρ = how far past the stop position it was when the light
  next turned red (+inf when it did not in the recording);
* it stood or approached while the light was red: ρ is also at most the least distance to
  the stop position it kept while red (the margin of its stop).

The worst stop position on the route decides; ``t`` is the moment the point crossed a
stop position on red (interpolated between samples), the agent the ego. A state sampled at
``t[k]`` holds on ``(t[k-1], t[k]]``; a crossing and a change to red within one sample
interval count as crossed before the change. Distances before and after the crossing are
measured along the path the ego drove (its odometer), so a turn through the junction is
measured along the turn.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..trajectory import Trajectory
from .base import Monitor, MonitorError, MonitorResult, check_name, check_present_finite, factory
from .road import LanePolyline, ego_ok, frame_projection, route_line
from .rules import _step_lengths

__all__ = ["ran_red_light", "red_light_crossings", "LightPass", "RED_CODE", "TAIL_FRACTION"]

#: the recorded code of a red light
RED_CODE = 2
#: CARLA's tail point: this many half-lengths behind the vehicle's centre
TAIL_FRACTION = 0.8
_POINTS = ("tail", "front")
#: [m] how far before a stop position the ego's approach is followed on its route
APPROACH_M = 150.0
#: [m] a sample farther than this from the route's centre line is not on the approach
ROUTE_DEVIATION_M = 5.0


@dataclass(frozen=True)
class LightPass:
    """One stop position of a light on the ego's route and how the ego met it: ``rho`` [m]
    (see the module), ``ran`` whether it crossed on red, ``t`` [s] when it crossed (None if
    it did not), ``step`` the first sample past it, ``detail`` in words."""

    light: str
    lane: str
    rho: float
    ran: bool
    t: float | None
    step: int | None
    detail: str


def _route_stops(traj: Trajectory, name: str) -> tuple[list[LanePolyline], list[tuple]]:
    """The route's lanes and ``(arc length along the route [m], light id, lane id)`` of every
    light's stop position on it (a lane the route runs twice counts twice)."""
    lights = traj.meta.get("lights") or []
    if not lights:
        return [], []
    route = route_line(traj, name)[0]
    at: dict[str, list[tuple[str, float]]] = {}
    for light in lights:
        for stop in light.get("stops", ()):
            at.setdefault(str(stop["lane"]), []).append((str(light["id"]), float(stop["s"])))
    out = []
    acc = 0.0
    for lane in route:
        for lid, s in at.get(lane.id, ()):
            out.append((acc + min(max(s, 0.0), lane.length), lid, lane.id))
        acc += lane.length
    return route, out


def red_light_crossings(traj: Trajectory, name: str = "ran_red_light",
                        point: str = "tail") -> list[LightPass]:
    """How the ego met every light's stop position on its route (:class:`LightPass` each, in
    route order), judged at its ``point`` ("tail", CARLA's, or "front"); [] when the
    recording has no light on the route."""
    route, stops = _route_stops(traj, name)
    if not stops:
        return []
    _, xy, cum = route_line(traj, name)
    # the recorded centre lines are a hair shorter than the lanes (chords of curves): scale
    # the polyline's arc length to the lanes' (a route of one lane is its own length)
    total = float(sum(l.length for l in route))
    if cum[-1] > 0 and total != cum[-1]:
        cum = cum * (total / cum[-1])
    present = ego_ok(traj)
    odo = np.cumsum(_step_lengths(traj))  # the ego's odometer [m]
    half = float(traj.length[0]) / 2
    ahead = half if point == "front" else -TAIL_FRACTION * half  # the point, from the centre
    t = traj.t
    out = []
    for S, lid, lane_id in stops:
        codes = traj.signals.get(f"light.{lid}")
        if codes is None:
            continue
        red = np.asarray(codes) == RED_CODE
        w = (cum >= S - APPROACH_M - 1.0) & (cum <= S + 1.0)
        lo, hi = max(int(np.argmax(w)) - 1, 0), min(len(cum) - 1, len(cum) - int(np.argmax(w[::-1])))
        if hi - lo < 1 or not present.any():
            continue
        whole = lo == 0 and hi == len(cum) - 1 and cum[0] == 0.0
        frame = frame_projection(traj, route[0]) if whole and len(route) == 1 else None
        if frame is not None and xy is route[0].xy and cum is route[0].cum:
            # the approach is the ego's one lane, which its lane frame projected already
            # (of every sample: the ego is present all along)
            s, r = frame.s, frame.r
            on = (np.abs(r) <= ROUTE_DEVIATION_M) & (s >= 0.0)
            at_on = on
        else:
            idx = np.flatnonzero(present)
            poly = LanePolyline("approach", xy[lo:hi + 1], cum[lo:hi + 1] - cum[lo], 0.0)
            s, r, _ = poly.project(traj.x[0, idx], traj.y[0, idx], heading=False)
            on = (np.abs(r) <= ROUTE_DEVIATION_M) & (s >= 0.0)
            at_on = idx[on]
        # the point before the stop position [m]: finite where on the approach (finite
        # positions, stop position and route), NaN elsewhere
        d = np.full(t.shape, np.nan)
        d[at_on] = (S - cum[lo]) - (s[on] + ahead)
        before = d > 0
        if not before.any():
            continue  # never before this stop position on its approach (started past it)
        k0 = int(np.argmax(before))
        past = d <= 0
        past[:k0] = False
        kc = int(np.argmax(past)) if past.any() else None
        if kc is not None:
            # the last sample before the crossing, and the interpolated crossing
            kb = int(np.flatnonzero(before[:kc])[-1])
            f = d[kb] / (d[kb] - d[kc])
            tc = float(t[kb] + f * (t[kc] - t[kb]))
            oc = float(odo[kb] + f * (odo[kc] - odo[kb]))
            dist = oc - odo  # before (+) / past (-) the stop position along the driven path
            stop_margin = dist[:kc][red[:kc] & present[:kc] & (dist[:kc] > 0)]
        else:
            stop_margin = d[red & before]
        margin = float(stop_margin.min()) if stop_margin.size else math.inf
        if kc is None:
            rho = margin
            out.append(LightPass(lid, lane_id, rho, False, None, None,
                                 f"ego did not cross the stop position of light {lid} on "
                                 f"{lane_id}" + (f"; it kept {margin:.3g} m before it on red"
                                                 if math.isfinite(margin) else "")))
            continue
        if red[kc] and red[kb]:
            # the light turned red at the sample after the last one before kb that was not red
            green = np.flatnonzero(~red[:kb])
            kr = int(green[-1]) + 1 if green.size else 0
            rho = -float(dist[kr])
            if rho == 0.0:
                rho = -1e-6  # crossed on red: never ρ = 0
            out.append(LightPass(lid, lane_id, min(rho, margin), True, tc, kc,
                                 f"ego ran the red light {lid} on {lane_id} at t={tc:.2f} s "
                                 f"({traj.speed[0, kc]:.3g} m/s): it was {-rho:.3g} m before "
                                 f"the stop position when the light turned red at "
                                 f"t={t[kr]:.2f} s"))
            continue
        nxt = np.flatnonzero(red[kc:])
        if nxt.size:
            kr = kc + int(nxt[0])
            rho = -float(dist[kr])
            when = f"{rho:.3g} m past it when the light turned red at t={t[kr]:.2f} s"
        else:
            rho = math.inf
            when = "the light did not turn red after it in the recording"
        state = "amber" if np.asarray(codes)[kc] == 1 else "green"
        detail = f"ego crossed the stop position of light {lid} on {lane_id} on {state} at " \
                 f"t={tc:.2f} s, {when}"
        if margin < rho:
            detail += f"; before, it stopped {margin:.3g} m before it on red"
        out.append(LightPass(lid, lane_id, min(rho, margin), False, tc, kc, detail))
    return out


class RanRedLightMonitor(Monitor):
    threshold = 0.0
    invariant = False  # a light not yet crossed is not judged

    def __init__(self, point: str = "tail", *, name: str = "ran_red_light"):
        self.name = check_name(name)
        if point not in _POINTS:
            raise MonitorError(f"{name}: point={point!r}: 'tail' (CARLA's: 0.8 half-lengths "
                               "behind the centre) or 'front' (the front bumper)")
        self.point = point

    def _evaluate(self, traj: Trajectory) -> MonitorResult:
        if traj.present[0].any():
            check_present_finite(traj, self.name, ("x", "y"), [0])
        got = red_light_crossings(traj, self.name, self.point)
        if not got:
            return MonitorResult(self.name, math.inf, 0.0, None, traj.names[0],
                                 "no traffic light on the ego's route")
        worst = min(got, key=lambda p: (p.rho, p.t if p.t is not None else math.inf))
        ran = [p for p in got if p.ran]
        first = min(ran, key=lambda p: p.t) if ran else None
        tail = f"; {len(ran)} of {len(got)} lights run" if len(got) > 1 else ""
        return MonitorResult(self.name, worst.rho, 0.0,
                             first.t if first is not None else worst.t, traj.names[0],
                             worst.detail + tail)


@factory
def ran_red_light(point: str = "tail", *, name: str = "ran_red_light") -> Monitor:
    """CARLA's ``RunningRedLightTest``: the ego never crosses a traffic light's stop position
    while the light is red, judged at its ``point``: ``"tail"`` (CARLA's, 0.8 half-lengths
    behind its centre: a car caught over the line by the change may clear the junction) or
    ``"front"`` (its front bumper: no entering on red). ρ [m], that point's distance: minus
    how far before the stop position it was when the light turned red, for a light it ran;
    how far past it was when a light it crossed on green or amber turned red; at most the
    margin it kept before a stop position while red. +inf with no light on its route."""
    return RanRedLightMonitor(point, name=name)

"""Rules of the road, under the names CARLA ScenarioRunner's criteria and the Leaderboard give
them: staying off the sidewalk, driving with the lane's direction, staying in the route's
lanes, stopping at stop lines, completing the route, not standing blocked, keeping up with
traffic.

Each judges the ego (agent 0) over the whole recording with numpy and reads the road from
the recording (:mod:`.road`: the recorded lane of every agent, the lanes' centre lines and
widths, the stop marks and the ego's route). Robustness is in the unit a tester reads off
the infringement: metres driven while infringing (sidewalk, wrong way, outside the route's
lanes), the speed [m/s] at a stop line above the standing speed, the fraction of the route
left, seconds standing beyond the allowed time. A rule that holds has ρ >= 0 (0 where no
margin is measured). ``off_road`` (CARLA's ``OffRoadTest``) lives in :mod:`.metrics`.
``ran_red_light`` (CARLA's ``RunningRedLightTest``) lives in :mod:`.signals`.
"""

from __future__ import annotations

import math

import numpy as np

from ..trajectory import Trajectory
from .base import (
    Monitor,
    MonitorError,
    MonitorResult,
    check_name,
    check_positive,
    check_present_finite,
    check_threshold,
    factory,
    fmt_t,
    memo,
)
from .road import (
    LanePolyline,
    ego_lane_all_along,
    ego_ok,
    frame_projection,
    lane_frame,
    lanes_of,
    route_line,
    route_of,
)

__all__ = [
    "on_sidewalk", "wrong_way", "outside_route_lanes", "ran_stop", "route_completion",
    "blocked", "min_speed_route", "STANDING_MPS", "STOP_ZONE_BEFORE_M", "STOP_ZONE_PAST_M",
    "SIDEWALK_M", "stop_crossings", "route_fraction", "outside_route_fraction",
    "traffic_speed_ratio",
]

#: [m/s] below this a vehicle stands (the world's all-way-stop rule uses the same value)
STANDING_MPS = 0.5
#: [m] the front bumper this far before, or :data:`STOP_ZONE_PAST_M` past, a stop line is
#: "at" the line (the world's all-way-stop rule uses the same values)
STOP_ZONE_BEFORE_M = 4.0
STOP_ZONE_PAST_M = 1.0
#: [m] the band beyond a road's outer edge that is sidewalk (the built roads' crosswalks
#: start this far beyond the kerb)
SIDEWALK_M = 2.0
#: [m/s] an agent slower than this has no direction of travel to judge
MOVING_MPS = 0.5


def _step_lengths(traj: Trajectory) -> np.ndarray:
    """``(T,)`` metres the ego drove from the previous sample to each sample (0 at the
    first and where it was absent at either end); shared per trajectory."""
    cache = memo(traj)
    got = cache.get("rules.step_lengths")
    if got is None:
        x, y, present = traj.x[0], traj.y[0], traj.present[0]
        got = np.zeros(x.shape)
        d = np.hypot(x[1:] - x[:-1], y[1:] - y[:-1])  # np.diff's arithmetic
        np.copyto(got[1:], d, where=present[1:] & present[:-1] & np.isfinite(d))
        cache["rules.step_lengths"] = got
    return got


def _ego_speed(traj: Trajectory) -> np.ndarray:
    """``(T,)`` the ego's speed [m/s] from its recorded velocity; shared per trajectory."""
    cache = memo(traj)
    got = cache.get("rules.speed")
    if got is None:
        got = cache["rules.speed"] = np.hypot(traj.vx[0], traj.vy[0])
    return got


def _infringement(name: str, traj: Trajectory, bad: np.ndarray, what: str) -> MonitorResult:
    """The result of a rule broken at the steps ``bad``: ρ = minus the metres driven there
    (at least 1 mm, so a violation is never ρ = 0), first at the first such step."""
    if not bad.any():
        return MonitorResult(name, 0.0, 0.0, None, traj.names[0], f"ego never {what}")
    k = int(np.argmax(bad))
    metres = float(_step_lengths(traj)[bad].sum())
    n = int(bad.sum())
    return MonitorResult(name, -max(metres, 1e-3), 0.0, fmt_t(traj, k), traj.names[0],
                         f"ego {what} for {metres:.3g} m ({n} samples), first at "
                         f"t={traj.t[k]:.2f} s")


def _ego_present(traj: Trajectory, name: str) -> np.ndarray:
    present = traj.present[0]
    cache = memo(traj)
    if "rules.ego_checked" not in cache:
        if not present.any():
            raise MonitorError(f"monitor {name!r}: the ego is never present")
        check_present_finite(traj, name, ("x", "y"), [0])
        cache["rules.ego_checked"] = True
    return present


# -- on the sidewalk --------------------------------------------------------------------------

class OnSidewalkMonitor(Monitor):
    threshold = 0.0
    invariant = True

    def __init__(self, width: float = SIDEWALK_M, *, name: str = "on_sidewalk"):
        self.width = check_positive(name, width, "width")
        self.name = check_name(name)

    def _evaluate(self, traj: Trajectory) -> MonitorResult:
        present = _ego_present(traj, self.name)
        off = present & ~traj.on_road[0]
        f = lane_frame(traj, self.name)
        if not off.any():
            bad = off
        else:
            lanes = lanes_of(traj, self.name)
            walks = [k for k in lanes if lanes.kind(k) == "sidewalk"]
            if walks or traj.meta.get("road") == "map":
                # a map's own sidewalks (none beside the lanes driven: no sidewalk to be on)
                bad = off & _inside_any(traj, [lanes[k] for k in walks], off)
            else:
                beyond = np.abs(f.r) - f.width / 2  # metres beyond the edge of its lane
                bad = off & (beyond > 0) & (beyond <= self.width)
        return _infringement(self.name, traj, bad, "drove on the sidewalk")


def _inside_any(traj: Trajectory, lanes: list[LanePolyline], where: np.ndarray) -> np.ndarray:
    """``(T,)`` whether the ego's centre lies on one of ``lanes`` (between its ends, within
    half its width of its centre line), at the samples ``where`` (False elsewhere)."""
    idx = np.flatnonzero(where)
    inside = np.zeros(idx.size, dtype=bool)
    for lane in lanes:
        s, r, _ = lane.project(traj.x[0, idx], traj.y[0, idx])
        inside |= (s >= 0) & (s <= lane.length) & (np.abs(r) <= lane.width_at(s) / 2)
    out = np.zeros(traj.n_steps, dtype=bool)
    out[idx] = inside
    return out


@factory
def on_sidewalk(width: float = SIDEWALK_M, *, name: str = "on_sidewalk") -> Monitor:
    """CARLA's ``OnSidewalkTest``: the ego's centre never leaves the road onto the sidewalk:
    on a map, the map's own sidewalk lanes beside the lanes driven (the recording lists them,
    ``kind`` "sidewalk"; a shoulder or a border is off the road, not sidewalk); on built
    roads, which draw none, the ``width`` [m] band beyond the edge of the lane it last drove
    in. ρ = 0 when it holds, else minus the metres driven
    there. Farther off the road is :func:`off_road`'s."""
    return OnSidewalkMonitor(width, name=name)


# -- wrong way --------------------------------------------------------------------------------

class WrongWayMonitor(Monitor):
    threshold = 0.0
    invariant = True

    def __init__(self, max_angle_deg: float = 90.0, *, name: str = "wrong_way"):
        self.max_angle = math.radians(check_positive(name, max_angle_deg, "max_angle_deg"))
        if not self.max_angle < math.pi:
            raise MonitorError(f"{name}: max_angle_deg must be < 180, got {max_angle_deg!r}")
        self.name = check_name(name)

    def against(self, traj: Trajectory) -> np.ndarray:
        """``(T,)`` whether the ego moves against its lane's direction at each sample."""
        f = lane_frame(traj, self.name)
        lanes = lanes_of(traj, self.name)
        parking = [k for k in lanes if lanes.kind(k) == "parking"]
        travel = np.arctan2(traj.vy[0], traj.vx[0])  # direction of motion, also when reversing
        err = np.abs(np.mod(travel - f.heading + np.pi, 2 * np.pi) - np.pi)
        moving = _ego_speed(traj) > MOVING_MPS
        bad = traj.present[0] & moving & np.isfinite(f.heading) & (err > self.max_angle)
        if parking:
            bad &= ~np.isin(traj.lane[0], parking)
        return bad

    def _evaluate(self, traj: Trajectory) -> MonitorResult:
        _ego_present(traj, self.name)
        return _infringement(self.name, traj, self.against(traj),
                             "drove against its lane's direction")


@factory
def wrong_way(max_angle_deg: float = 90.0, *, name: str = "wrong_way") -> Monitor:
    """CARLA's ``WrongLaneTest``: the ego never moves against the direction of the lane it
    is on (its direction of motion, so reversing down a lane counts, more than
    ``max_angle_deg`` from the lane's heading, while faster than 0.5 m/s; parking lanes
    excepted). ρ = 0 when it holds, else minus the metres driven the wrong way."""
    return WrongWayMonitor(max_angle_deg, name=name)


# -- outside the route's lanes ----------------------------------------------------------------

def _outside_route(traj: Trajectory, name: str) -> np.ndarray:
    """``(T,)`` whether the ego is off the road or on a lane of no carriageway of its route
    (shared per trajectory)."""
    cache = memo(traj)
    got = cache.get("rules.outside_route")
    if got is not None:
        return got
    route_ids = _route_ids(traj, name)
    lanes = lanes_of(traj, name)
    groups = {lanes.group(i) for i in route_ids} - {""}
    ok_ids = [k for k in lanes if k in route_ids or lanes.group(k) in groups]
    one = ego_lane_all_along(traj)
    if one is not None:  # on one lane all along: that lane decides every sample
        on_route = np.full(traj.n_steps, one in ok_ids)
    else:
        on_route = _among(traj.lane[0], ok_ids)
    got = cache["rules.outside_route"] = traj.present[0] & (~traj.on_road[0] | ~on_route)
    return got


def _among(lane: np.ndarray, ids: list[str]) -> np.ndarray:
    """``np.isin(lane, ids)``; a few comparisons for a few ids (isin sorts strings)."""
    if len(ids) > 6:
        return np.isin(lane, ids)
    out = np.zeros(lane.shape, dtype=bool)
    for i in ids:
        out |= lane == i
    return out


def _route_ids(traj: Trajectory, name: str) -> set[str]:
    """The ids of the ego's route lanes, checked against the recorded lanes (no shapes)."""
    ids = traj.meta.get("ego_route")
    if not ids:
        route_of(traj, name)  # raises the error naming what is missing
    lanes = lanes_of(traj, name)
    missing = [i for i in ids if i not in lanes]
    if missing:
        raise MonitorError(f"monitor {name!r}: route lanes {missing} are not in meta['lanes']")
    return set(ids)


def outside_route_fraction(traj: Trajectory, name: str = "outside_route_lanes") -> float:
    """Fraction of the metres the ego drove that it drove outside its route's lanes (0..1)."""
    bad = _outside_route(traj, name)
    d = _step_lengths(traj)
    total = float(d.sum())
    return float(d[bad].sum() / total) if total > 0 else 0.0


class OutsideRouteLanesMonitor(Monitor):
    threshold = 0.0
    invariant = True

    def __init__(self, *, name: str = "outside_route_lanes"):
        self.name = check_name(name)

    def _evaluate(self, traj: Trajectory) -> MonitorResult:
        _ego_present(traj, self.name)
        bad = _outside_route(traj, self.name)
        res = _infringement(self.name, traj, bad, "drove outside its route's lanes")
        if bad.any():
            pct = 100 * outside_route_fraction(traj, self.name)
            res = MonitorResult(self.name, res.rho, 0.0, res.t, res.agent,
                                res.detail + f"; {pct:.3g}% of its distance")
        return res


@factory
def outside_route_lanes(*, name: str = "outside_route_lanes") -> Monitor:
    """CARLA's ``OutsideRouteLanesTest``: the ego stays on the carriageways of its route (a
    lane change within one is allowed; the opposite direction, a parking lane, another road
    or off the road is not). ρ = 0 when it holds, else minus the metres driven outside
    (the detail gives the share of its distance, which the driving score charges)."""
    return OutsideRouteLanesMonitor(name=name)


# -- stop lines -------------------------------------------------------------------------------

def stop_crossings(traj: Trajectory, name: str = "ran_stop", *,
                   before: float = STOP_ZONE_BEFORE_M,
                   past: float = STOP_ZONE_PAST_M) -> list[tuple[str, int, float]]:
    """Every stop line the ego drove over: ``(lane id, step it passed the line by more than
    ``past``, the lowest speed [m/s] it had with its front bumper from ``before`` metres
    before to ``past`` metres past the line)``. A line the ego started beyond, or never
    passed, is not listed."""
    stops = traj.meta.get("stops") or []
    lines = [(str(m["lane"]), float(m["s"])) for m in stops if m.get("kind") == "stop"]
    if not lines:
        return []
    cache = memo(traj)
    key = ("rules.stop_crossings", before, past)
    got = cache.get(key)
    if got is not None:
        return list(got)
    f = lane_frame(traj, name)
    front = f.s + traj.length[0] / 2
    speed = _ego_speed(traj)
    out = []
    one = ego_lane_all_along(traj)
    for lane_id, s_line in lines:
        if one is None:
            on = traj.present[0] & (traj.lane[0] == lane_id) & np.isfinite(front)
        elif one == lane_id:  # on this lane at every sample
            on = traj.present[0] & np.isfinite(front)
        else:
            continue  # never on it
        if not on.any():
            continue
        passed = on & (front > s_line + past)
        came = on & (front <= s_line + past)
        if not passed.any() or not came.any():
            continue
        k = int(np.argmax(passed))
        if not came[:k].any():
            continue  # started past the line
        zone = came[:k] & (front[:k] >= s_line - before)
        if zone.any():
            vmin = float(speed[:k][zone].min())
        else:  # jumped over the zone between two samples: the last sample before it
            vmin = float(speed[int(np.flatnonzero(came[:k])[-1])])
        out.append((lane_id, k, vmin))
    cache[key] = tuple(out)
    return out


class RanStopMonitor(Monitor):
    invariant = False  # judged per line once passed: a prefix that stops short is not judged

    def __init__(self, standing: float = STANDING_MPS, *, before: float = STOP_ZONE_BEFORE_M,
                 past: float = STOP_ZONE_PAST_M, name: str = "ran_stop"):
        self.threshold = check_positive(name, standing, "standing")
        self.before = check_positive(name, before, "before")
        self.past = check_positive(name, past, "past", allow_zero=True)
        self.name = check_name(name)

    def _evaluate(self, traj: Trajectory) -> MonitorResult:
        _ego_present(traj, self.name)
        check_present_finite(traj, self.name, ("vx", "vy"), [0])
        lanes_of(traj, self.name)
        got = stop_crossings(traj, self.name, before=self.before, past=self.past)
        if not got:
            return MonitorResult(self.name, math.inf, self.threshold, None, traj.names[0],
                                 "ego passed no stop line")
        lane_id, k, vmin = min(got, key=lambda g: (self.threshold - g[2] >= 0, -g[2]))
        ran = sum(1 for g in got if g[2] >= self.threshold)
        verb = "ran" if vmin >= self.threshold else "stopped at"
        return MonitorResult(
            self.name, self.threshold - vmin, self.threshold, fmt_t(traj, k), traj.names[0],
            f"ego {verb} the stop line of {lane_id}: lowest speed {vmin:.3g} m/s within "
            f"{self.before:g} m before it (standing < {self.threshold:g} m/s); passed at "
            f"t={traj.t[k]:.2f} s; {ran} of {len(got)} stop lines run")


@factory
def ran_stop(standing: float = STANDING_MPS, *, before: float = STOP_ZONE_BEFORE_M,
             past: float = STOP_ZONE_PAST_M, name: str = "ran_stop") -> Monitor:
    """CARLA's ``RunningStopTest``: before driving over a stop line the ego stands (slower
    than ``standing`` [m/s]) with its front bumper from ``before`` [m] before to ``past`` [m]
    past the line. ρ [m/s] = ``standing`` minus the lowest speed it had there, the worst line
    deciding; +inf when it passed none. CARLA's test uses 0.1 m/s within 4 m; the default is
    the world's own all-way-stop rule (0.5 m/s, 4 m before to 1 m past)."""
    return RanStopMonitor(standing, before=before, past=past, name=name)


# -- route completion -------------------------------------------------------------------------

#: [m] a sample farther than this from the route's centre line does not advance along it
ROUTE_DEVIATION_M = 5.0


def route_fraction(traj: Trajectory, name: str = "route_completion") -> tuple[float, int, float]:
    """``(fraction of the route from the ego's start to its end the ego completed (0..1),
    the step it got farthest, metres left)``; 1 when the recording says it reached the end.
    Shared per trajectory."""
    cache = memo(traj)
    got = cache.get("rules.route_fraction")
    if got is None:
        got = cache["rules.route_fraction"] = _route_fraction(traj, name)
    return got


def _route_fraction(traj: Trajectory, name: str) -> tuple[float, int, float]:
    route, xy, cum = route_line(traj, name)
    if len(route) == 1:  # the lane's own polyline (its points are already apart)
        path = route[0]
    else:
        path = LanePolyline("route", xy, cum, 0.0)
    present = ego_ok(traj)
    frame = frame_projection(traj, path) if path is route[0] else None
    if frame is not None:
        # the ego kept its one route lane all along: its lane frame is this projection
        idx = np.arange(traj.n_steps)
        s, r = frame.s, frame.r
    else:
        idx = np.flatnonzero(present)
        if path is route[0] and (traj.lane[0, idx] == path.id).all():
            # the ego stayed on its one route lane: its lane frame is this projection already
            f = lane_frame(traj, name)
            s, r = f.s[idx], f.r[idx]
        else:
            s, r, _ = path.project(traj.x[0, idx], traj.y[0, idx], heading=False)
    length = path.length
    s = np.minimum(np.maximum(s, 0.0), length)  # np.clip's arithmetic
    s0 = float(s[0])
    near = np.abs(r) <= ROUTE_DEVIATION_M
    reach = np.where(near, s, -np.inf)
    j = int(np.argmax(reach))
    best = max(float(reach[j]), s0)
    todo = length - s0
    if traj.meta.get("ego_reached_route_end") is True:
        return 1.0, int(idx[j]), 0.0
    if todo <= 1e-9:
        return 1.0, int(idx[0]), 0.0
    frac = (best - s0) / todo
    return min(max(frac, 0.0), 1.0), int(idx[j]), float(length - best)


class RouteCompletionMonitor(Monitor):
    def __init__(self, min_fraction: float = 1.0, *, name: str = "route_completion"):
        self.threshold = check_threshold(name, min_fraction, "min_fraction")
        if not 0.0 <= self.threshold <= 1.0:
            raise MonitorError(f"{name}: min_fraction must be in [0, 1], got {min_fraction!r}")
        self.name = check_name(name)

    def _evaluate(self, traj: Trajectory) -> MonitorResult:
        _ego_present(traj, self.name)
        frac, k, left = route_fraction(traj, self.name)
        return MonitorResult(self.name, frac - self.threshold, self.threshold, fmt_t(traj, k),
                             traj.names[0],
                             f"ego completed {100 * frac:.3g}% of its route ({left:.3g} m left; "
                             f"required >= {100 * self.threshold:g}%)")


@factory
def route_completion(min_fraction: float = 1.0, *, name: str = "route_completion") -> Monitor:
    """CARLA's ``RouteCompletionTest``: the ego completes at least ``min_fraction`` of its
    route, measured along the route's centre line from where it started to the route's end
    (samples more than 5 m off the route do not advance it). ρ = completed fraction -
    ``min_fraction``."""
    return RouteCompletionMonitor(min_fraction, name=name)


# -- blocked ----------------------------------------------------------------------------------

def standing_time(traj: Trajectory, min_speed: float) -> np.ndarray:
    """``(T,)`` seconds the ego has been standing (slower than ``min_speed``) without a break,
    at each sample (0 while it moves)."""
    cache = memo(traj)
    key = ("rules.standing_time", min_speed)
    got = cache.get(key)
    if got is not None:
        return got
    slow = traj.present[0] & (_ego_speed(traj) < min_speed)
    if not slow.any():
        got = cache[key] = np.zeros(traj.n_steps)
        return got
    began = slow & ~np.concatenate([[False], slow[:-1]])
    start = np.maximum.accumulate(np.where(began, traj.t, -np.inf))
    with np.errstate(invalid="ignore"):
        got = cache[key] = np.where(slow, traj.t - start, 0.0)
    return got


class BlockedMonitor(Monitor):
    invariant = True

    def __init__(self, seconds: float = 10.0, min_speed: float = 0.1, *, name: str = "blocked"):
        self.threshold = check_positive(name, seconds, "seconds")
        self.min_speed = check_positive(name, min_speed, "min_speed")
        self.name = check_name(name)

    def series(self, traj: Trajectory) -> np.ndarray:
        return self.threshold - standing_time(traj, self.min_speed)

    def _evaluate(self, traj: Trajectory) -> MonitorResult:
        _ego_present(traj, self.name)
        check_present_finite(traj, self.name, ("vx", "vy"), [0])
        stood = standing_time(traj, self.min_speed)
        k = int(np.argmax(stood))
        longest = float(stood[k])
        rho = self.threshold - longest
        if rho < 0:  # the first sample past the allowed time
            k = int(np.argmax(stood > self.threshold))
        return MonitorResult(self.name, rho, self.threshold, fmt_t(traj, k), traj.names[0],
                             f"ego stood (< {self.min_speed:g} m/s) for {longest:.3g} s at most, "
                             f"until t={traj.t[int(np.argmax(stood))]:.2f} s "
                             f"(allowed {self.threshold:g} s)")


@factory
def blocked(seconds: float = 10.0, min_speed: float = 0.1, *, name: str = "blocked") -> Monitor:
    """CARLA's ``ActorBlockedTest``: the ego never stands (slower than ``min_speed`` [m/s])
    for more than ``seconds`` [s] without a break. ρ [s] = ``seconds`` minus the longest
    such stand (time between its first and last sample)."""
    return BlockedMonitor(seconds, min_speed, name=name)


# -- keeping up with traffic ------------------------------------------------------------------

#: agent kinds that are traffic (parked vehicles and pedestrians are not)
TRAFFIC_KINDS = ("car", "truck", "bus", "bicycle", "motorcycle")


def traffic_speed_ratio(traj: Trajectory) -> tuple[float, float, float]:
    """``(ego mean speed / traffic mean speed, ego mean [m/s], traffic mean [m/s])`` over the
    samples where the ego and some moving-traffic agent are present (NaN when there are none).
    Shared per trajectory."""
    cache = memo(traj)
    got = cache.get("rules.traffic_speed_ratio")
    if got is None:
        got = cache["rules.traffic_speed_ratio"] = _traffic_speed_ratio(traj)
    return got


def _traffic_speed_ratio(traj: Trajectory) -> tuple[float, float, float]:
    rows = [i for i, k in enumerate(traj.kinds) if i and k in TRAFFIC_KINDS]
    if not rows:
        return math.nan, math.nan, math.nan
    if rows[-1] - rows[0] == len(rows) - 1:  # side by side: a view, no copy
        rows = slice(rows[0], rows[-1] + 1)
    sp = np.hypot(traj.vx[rows], traj.vy[rows])
    pres = traj.present[rows] & np.isfinite(sp)
    n = pres.sum(axis=0)
    use = traj.present[0] & (n > 0)
    if not use.any():
        return math.nan, math.nan, math.nan
    # np.mean's arithmetic: the (pairwise) sum over the samples, divided by their number
    per_step = np.where(pres, sp, 0.0).sum(axis=0)[use] / n[use]
    traffic = float(np.add.reduce(per_step) / per_step.size)
    ego_used = _ego_speed(traj)[use]
    ego = float(np.add.reduce(ego_used) / ego_used.size)
    ratio = ego / traffic if traffic > 0 else math.inf
    return ratio, ego, traffic


class MinSpeedRouteMonitor(Monitor):
    def __init__(self, fraction: float = 1.0, *, name: str = "min_speed_route"):
        self.threshold = check_positive(name, fraction, "fraction")
        self.name = check_name(name)

    def _evaluate(self, traj: Trajectory) -> MonitorResult:
        _ego_present(traj, self.name)
        check_present_finite(traj, self.name, ("vx", "vy"))
        ratio, ego, traffic = traffic_speed_ratio(traj)
        if math.isnan(ratio):
            return MonitorResult(self.name, math.inf, self.threshold, None, traj.names[0],
                                 "no traffic beside the ego to compare with")
        return MonitorResult(self.name, ratio - self.threshold, self.threshold, None,
                             traj.names[0],
                             f"ego's mean speed {ego:.3g} m/s is {100 * ratio:.3g}% of the "
                             f"traffic's {traffic:.3g} m/s (required >= "
                             f"{100 * self.threshold:g}%)")


@factory
def min_speed_route(fraction: float = 1.0, *, name: str = "min_speed_route") -> Monitor:
    """CARLA's ``MinimumSpeedRouteTest``: the ego's mean speed is at least ``fraction`` of
    the mean speed of the traffic around it (cars, trucks, buses present at the same
    samples). ρ = ratio - ``fraction``; +inf with no traffic. The Leaderboard compares per
    tenth of the route; here the whole run is one stretch."""
    return MinSpeedRouteMonitor(fraction, name=name)

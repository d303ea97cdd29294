"""Responsibility-Sensitive Safety (RSS): safe distances as a monitor, and who was unsafe first.

Source: S. Shalev-Shwartz, S. Shammah, A. Shashua, "On a Formal Model of Safe and Scalable
Self-driving Cars", Mobileye 2017, arXiv:1708.06374 (v6, 2018). Carried over:

* **safe longitudinal distance, same direction** (Definition 1, Lemma 2): a rear car at
  speed ``v_r`` behind a front car at ``v_f`` keeps at least ::

      d_min = [ v_r rho + a_max_accel rho^2 / 2 + (v_r + rho a_max_accel)^2 / (2 a_min_brake)
                - v_f^2 / (2 a_max_brake) ]_+

  between its front and the other's rear: even if the front car brakes at ``a_max_brake``,
  the rear car, accelerating at up to ``a_max_accel`` during its response time ``rho`` and
  braking at ``a_min_brake`` after it, does not hit it ([x]_+ = max(x, 0));
* **safe longitudinal distance, opposite directions** (Lemma 3): both close in at up to
  ``a_max_accel`` during ``rho``, then brake — the car in its correct lane at
  ``a_min_brake_correct``, the other at ``a_min_brake``; the distance is the sum of both
  stopping distances;
* **safe lateral distance** (the lateral lemma): car 1 left of car 2, lateral velocities
  toward each other ``u1``, ``u2``; each accelerates toward the other at up to
  ``a_lat_max_accel`` during ``rho`` and then brakes its lateral velocity at
  ``a_lat_min_brake``; with a margin ``mu`` ::

      d_min = mu + [ sum over both of (u rho + a_lat_max_accel rho^2 / 2 + w|w| / (2 a_lat_min_brake)) ]_+,
      w = u + rho a_lat_max_accel

  (the paper writes ``w^2``, assuming both end up closing in; ``w|w|`` keeps the sign of a
  car that moves away after ``rho``);
* **dangerous situation, blame time, proper response, responsibility** (Section 3): a time is
  dangerous for two cars when both their longitudinal and their lateral distance are below
  the safe ones; the blame time of a dangerous time is the last non-dangerous time before it;
  the distance that was still safe at the blame time says which proper response applies
  (longitudinal: the rear car brakes at least ``a_min_brake`` after ``rho``, the front car
  brakes at most ``a_max_brake``; lateral: both brake their lateral velocity toward each other
  at least ``a_lat_min_brake`` after ``rho``; during ``rho`` neither accelerates toward the
  other beyond the ``*_max_accel`` bound); a car that does not respond properly is
  responsible.

Parameter values: the paper names the parameters, not their values. The defaults of
:class:`RSSParams` are the starting values of Intel's open-source RSS library
(ad-rss-lib, documentation "Parameter Discussion"): ``rho`` = 1 s (its value for the ego),
``a_max_accel`` 3.5, ``a_min_brake`` 4, ``a_max_brake`` 8, ``a_min_brake_correct`` 3,
``a_lat_max_accel`` 0.2, ``a_lat_min_brake`` 0.8 m/s^2, ``mu`` 0.1 m.

Simplifications, so a reader can judge a verdict:

* the longitudinal axis is the ego's lane direction, estimated per step from the ego's
  heading and the rate of its recorded lane offset (the ego's heading where it has no lane),
  or a fixed ``axis`` [rad]; at t = 0 it is the ego's heading as placed, never the step
  after (the ego's first action must not decide whether the scene starts unsafe); one axis for every pair (straight or gently curved roads, not
  intersections, whose route geometry the paper handles separately);
* lateral velocities are the plain ones, not the paper's mu-lateral-velocity;
* in opposite directions the trajectory does not say which car is in its correct lane, so
  both brake at ``a_min_brake_correct`` (the smaller, the larger distance);
* :func:`rss_blame`: an episode dangerous from the first sample has no blame time; nobody
  entered it and nobody is made responsible for it. When both distances are lost in the same
  step, a car complying with either response complies. Accelerations are differences of
  recorded velocities; bounds are checked with a tolerance of 0.05 m/s^2, and a step that
  ends with the car slower than 0.1 m/s (toward the other) counts as a response. Steps
  after either car has crashed are not judged (the simulator moves them then).
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, fields
from typing import Any

import numpy as np

from ..trajectory import Trajectory
from .base import (
    Monitor,
    MonitorError,
    MonitorResult,
    check_name,
    check_present_finite,
    factory,
    fmt_t,
)

__all__ = [
    "RSSParams", "rss", "rss_blame", "RSSBlame", "RSSEpisode", "rss_margins", "starts_unsafe",
    "safe_longitudinal_distance", "safe_opposite_distance", "safe_lateral_distance",
]

#: [m/s^2] slack on acceleration bounds when judging a proper response (finite differences)
ACCEL_TOLERANCE = 0.05
#: [m/s] a car slower than this toward the other has responded (stopped / no lateral motion)
STILL = 0.1


@dataclass(frozen=True)
class RSSParams:
    """The RSS model's parameters, named as in the paper (see the module doc for defaults)."""

    response_time: float = 1.0  # [s] rho
    a_max_accel: float = 3.5  # [m/s^2] longitudinal acceleration during rho, at most
    a_min_brake: float = 4.0  # [m/s^2] braking of the responding car, at least
    a_max_brake: float = 8.0  # [m/s^2] braking of the car ahead, at most
    a_min_brake_correct: float = 3.0  # [m/s^2] braking of a car in its correct lane, oncoming
    a_lat_max_accel: float = 0.2  # [m/s^2] lateral acceleration during rho, at most
    a_lat_min_brake: float = 0.8  # [m/s^2] lateral braking after rho, at least
    mu: float = 0.1  # [m] lateral margin

    def __post_init__(self) -> None:
        for f in fields(self):
            value = getattr(self, f.name)
            if isinstance(value, bool) or not isinstance(value, (int, float, np.floating)) \
                    or not math.isfinite(value):
                raise MonitorError(f"rss: {f.name} must be a finite number, got {value!r}")
            positive = f.name not in ("response_time", "a_max_accel", "a_lat_max_accel", "mu")
            if value < 0 or (positive and value == 0):
                bound = "> 0" if positive else ">= 0"
                raise MonitorError(f"rss: {f.name} [{_UNITS[f.name]}] must be {bound}, got {value!r}")


_UNITS = {"response_time": "s", "mu": "m"}
_UNITS.update({f.name: "m/s^2" for f in fields(RSSParams) if f.name.startswith("a_")})


def _params(params: RSSParams | None, overrides: dict[str, Any]) -> RSSParams:
    base = params if params is not None else RSSParams()
    if not isinstance(base, RSSParams):
        raise MonitorError(f"rss: params must be an RSSParams, got {type(base).__name__}")
    if overrides:
        known = {f.name for f in fields(RSSParams)}
        unknown = sorted(set(overrides) - known)
        if unknown:
            raise MonitorError(f"rss: unknown parameter(s) {', '.join(unknown)}; known: "
                               f"{', '.join(f.name for f in fields(RSSParams))}")
        base = RSSParams(**{**asdict(base), **overrides})
    return base


# -- the paper's formulas (numpy-vectorized, scalars work too) --------------------------------

def safe_longitudinal_distance(v_rear: Any, v_front: Any, params: RSSParams | None = None,
                               **overrides: Any) -> Any:
    """Lemma 2: the minimal safe distance [m] from the rear car's front to the front car's
    rear, both driving the same way at ``v_rear``, ``v_front`` [m/s] (negative speeds count
    as 0)."""
    p = _params(params, overrides)
    vr = np.maximum(np.asarray(v_rear, dtype=float), 0.0)
    vf = np.maximum(np.asarray(v_front, dtype=float), 0.0)
    rho = p.response_time
    v_rho = vr + rho * p.a_max_accel
    d = (vr * rho + 0.5 * p.a_max_accel * rho * rho + v_rho * v_rho / (2.0 * p.a_min_brake)
         - vf * vf / (2.0 * p.a_max_brake))
    return np.maximum(d, 0.0)


def safe_opposite_distance(v1: Any, v2: Any, params: RSSParams | None = None,
                           **overrides: Any) -> Any:
    """Lemma 3: the minimal safe distance [m] between two cars driving toward each other at
    speeds ``v1`` (in its correct lane, brakes at ``a_min_brake_correct``) and ``v2``
    (brakes at ``a_min_brake``) [m/s]."""
    p = _params(params, overrides)
    rho = p.response_time
    out = 0.0
    for v, brake in ((v1, p.a_min_brake_correct), (v2, p.a_min_brake)):
        v = np.maximum(np.asarray(v, dtype=float), 0.0)
        v_rho = v + rho * p.a_max_accel
        out = out + (v + v_rho) / 2.0 * rho + v_rho * v_rho / (2.0 * brake)
    return out


def _lateral_reach(u: Any, p: RSSParams) -> Any:
    """How far [m] a car moves toward the other: ``u`` toward it, accelerating during rho,
    then braking its lateral velocity to zero (negative when it ends up further away)."""
    rho = p.response_time
    w = u + rho * p.a_lat_max_accel
    return u * rho + 0.5 * p.a_lat_max_accel * rho * rho + w * np.abs(w) / (2.0 * p.a_lat_min_brake)


def safe_lateral_distance(u1: Any, u2: Any, params: RSSParams | None = None,
                          **overrides: Any) -> Any:
    """The lateral lemma: the minimal safe lateral distance [m] between two cars side by side
    whose lateral velocities toward each other are ``u1``, ``u2`` [m/s]."""
    p = _params(params, overrides)
    u1 = np.asarray(u1, dtype=float)
    u2 = np.asarray(u2, dtype=float)
    return p.mu + np.maximum(_lateral_reach(u1, p) + _lateral_reach(u2, p), 0.0)


# -- geometry of the pairs ----------------------------------------------------------------------

def _road_axis(traj: Trajectory, axis: float | None) -> np.ndarray:
    """``(T,)`` direction [rad] of the longitudinal axis: the ego's lane direction, its heading
    corrected by the angle its lane offset changes at (see module doc), or ``axis``."""
    T = traj.n_steps
    if axis is not None:
        return np.full(T, float(axis))
    heading = np.where(np.isfinite(traj.heading[0]), traj.heading[0], 0.0)
    if T < 2:
        return heading
    off, lane, t = traj.lane_offset[0], traj.lane[0], traj.t
    ok = (lane[1:] == lane[:-1]) & (lane[1:] != "") & np.isfinite(off[1:]) & np.isfinite(off[:-1])
    with np.errstate(invalid="ignore", divide="ignore"):
        step = np.where(ok, (off[1:] - off[:-1]) / np.diff(t), np.nan)
    # the rate at a step is the mean of the steps before and after it — except at t = 0,
    # which is the initial scene as placed: the step after is the ego's first action (a lane
    # change there would tilt the axis and decide whether the scene *starts* unsafe)
    after = np.concatenate([step, [np.nan]])
    after[0] = np.nan
    around = np.stack([np.concatenate([[np.nan], step]), after])
    n = np.isfinite(around).sum(axis=0)
    rate = np.where(n > 0, np.nansum(np.where(np.isfinite(around), around, 0.0), axis=0)
                    / np.maximum(n, 1), 0.0)
    speed = np.where(np.isfinite(traj.speed[0]), traj.speed[0], 0.0)
    rel = np.where(speed > 0.5, np.arcsin(np.clip(rate / np.maximum(speed, 0.5), -1.0, 1.0)), 0.0)
    return heading - rel


@dataclass(frozen=True)
class _Pairs:
    """Every (ego, other) pair's RSS quantities, each ``(A-1, T)``."""

    lon_gap: np.ndarray  # [m] bumper to bumper along the axis (< 0 overlapping)
    lat_gap: np.ndarray  # [m] side to side across the axis
    lon_safe: np.ndarray  # [m] RSS-safe longitudinal distance
    lat_safe: np.ndarray  # [m] RSS-safe lateral distance
    ahead: np.ndarray  # other ahead of the ego along the ego's direction of travel
    same_way: np.ndarray  # both travel the same way along the axis
    sign: np.ndarray  # +1/-1 the ego's direction of travel along the axis (T,)
    v_lon: np.ndarray  # (A, T) velocity along the axis [m/s]
    v_lat: np.ndarray  # (A, T) velocity across the axis, + left [m/s]
    left: np.ndarray  # other left of the ego
    present: np.ndarray

    @property
    def lon_margin(self) -> np.ndarray:
        return self.lon_gap - self.lon_safe

    @property
    def lat_margin(self) -> np.ndarray:
        return self.lat_gap - self.lat_safe


def _pairs(traj: Trajectory, p: RSSParams, axis: float | None) -> _Pairs:
    theta = _road_axis(traj, axis)
    c, s = np.cos(theta), np.sin(theta)
    v_lon = traj.vx * c + traj.vy * s
    v_lat = traj.vy * c - traj.vx * s
    rel = traj.heading - theta
    cr, sr = np.abs(np.cos(rel)), np.abs(np.sin(rel))
    hl, hw = (traj.length / 2)[:, None], (traj.width / 2)[:, None]
    ext_lon = hl * cr + hw * sr
    ext_lat = hl * sr + hw * cr
    dx = traj.x[1:] - traj.x[0]
    dy = traj.y[1:] - traj.y[0]
    lon = dx * c + dy * s
    lat = dy * c - dx * s
    lon_gap = np.abs(lon) - ext_lon[:1] - ext_lon[1:]
    lat_gap = np.abs(lat) - ext_lat[:1] - ext_lat[1:]

    forward = np.cos(rel) >= 0.0  # travels along +axis
    sign = np.where(forward[0], 1.0, -1.0)
    same_way = forward[1:] == forward[:1]
    ahead = sign * lon > 0.0
    u_ego = sign * v_lon[0]  # along the ego's direction of travel
    u_other = sign * v_lon[1:]
    lon_same = np.where(ahead, safe_longitudinal_distance(u_ego, u_other, p),
                        safe_longitudinal_distance(u_other, u_ego, p))
    # opposite ways: closing in only when the other is ahead of the ego and faces it
    lon_opp = np.where(ahead, safe_opposite_distance(u_ego, -u_other, p,
                                                     a_min_brake=p.a_min_brake_correct), 0.0)
    lon_safe = np.where(same_way, lon_same, lon_opp)

    left = lat > 0.0
    toward_ego = np.where(left, v_lat[:1], -v_lat[:1])  # ego's lateral velocity toward the other
    toward_other = np.where(left, -v_lat[1:], v_lat[1:])
    lat_safe = safe_lateral_distance(toward_ego, toward_other, p)
    present = traj.present[0][None, :] & traj.present[1:]
    return _Pairs(lon_gap, lat_gap, lon_safe, lat_safe, ahead, same_way, sign, v_lon, v_lat,
                  left, present)


def _decisive(pr: _Pairs) -> np.ndarray:
    """The margin [m] that decides each pair-step: safe while either distance is safe (the
    paper's dangerous situation needs both unsafe), so the larger of the two — except that
    for an agent in line with the ego (overlapping across the axis) it is the longitudinal
    one and for an agent beside it (overlapping along the axis) the lateral one, which keeps
    the number meaningful where the other distance can only be unsafe."""
    lon, lat = pr.lon_margin, pr.lat_margin
    return np.where(pr.lat_gap <= 0.0, lon, np.where(pr.lon_gap <= 0.0, lat, np.maximum(lon, lat)))


def starts_unsafe(trajectory: Trajectory) -> bool:
    """Whether the ego and another agent are in an RSS-dangerous situation at t = 0 (both
    distances unsafe): nobody entered it, no driver is to blame. False when it cannot be
    judged (fewer than two agents, no sample, a trajectory the margins reject)."""
    if trajectory.n_agents < 2 or trajectory.n_steps < 1:
        return False
    try:
        lon, lat = rss_margins(trajectory)
    except (MonitorError, ValueError, FloatingPointError):
        return False
    return bool(((lon[:, 0] < 0) & (lat[:, 0] < 0)).any())


def rss_margins(trajectory: Trajectory, params: RSSParams | None = None, *,
                axis: float | None = None, **overrides: Any) -> tuple[np.ndarray, np.ndarray]:
    """``(longitudinal, lateral)`` margins [m], each ``(A-1, T)``: actual minus RSS-safe
    distance from the ego to every other agent (+inf where either is absent). A pair is in a
    dangerous situation where both are negative."""
    p = _params(params, overrides)
    pr = _pairs(trajectory, p, axis)
    return (np.where(pr.present, pr.lon_margin, np.inf),
            np.where(pr.present, pr.lat_margin, np.inf))


# -- the monitor ----------------------------------------------------------------------------------

class RSSMonitor(Monitor):
    """Always RSS-safe toward every other agent (see :func:`rss`)."""

    threshold = 0.0

    invariant = True  # must hold at every step (first_violation bisects prefixes)

    def __init__(self, params: RSSParams, axis: float | None, name: str):
        self.params = params
        self.axis = axis
        self.name = check_name(name)

    def _evaluate(self, traj: Trajectory) -> MonitorResult:
        check_present_finite(traj, self.name, ("x", "y", "vx", "vy", "heading"))
        if traj.n_agents < 2:
            return MonitorResult(self.name, math.inf, 0.0, None, None, "no other agent")
        pr = _pairs(traj, self.params, self.axis)
        lon, lat = pr.lon_margin, pr.lat_margin
        margin = np.where(pr.present, _decisive(pr), np.inf)
        if not np.isfinite(margin).any():
            return MonitorResult(self.name, math.inf, 0.0, None, None, "no other agent present")
        flat = int(np.argmin(margin.T))
        step, row = divmod(flat, margin.shape[0])
        v = float(margin[row, step])
        who = traj.names[row + 1]
        detail = (f"RSS margin {v:.3g} m to {who} at t={traj.t[step]:.2f} s: longitudinal gap "
                  f"{pr.lon_gap[row, step]:.3g} m vs safe {pr.lon_safe[row, step]:.3g} m, "
                  f"lateral gap {pr.lat_gap[row, step]:.3g} m vs safe "
                  f"{pr.lat_safe[row, step]:.3g} m")
        return MonitorResult(self.name, v, 0.0, fmt_t(traj, step), who, detail)


@factory
def rss(params: RSSParams | None = None, *, axis: float | None = None, name: str = "rss",
        **overrides: Any) -> Monitor:
    """RSS safe distances as a monitor: rho [m] = min over steps and other agents of the
    margin actual - RSS-safe distance: the longitudinal one for an agent in line with the ego
    (same lane), the lateral one for an agent beside it, else the larger of the two — negative
    exactly where the pair is in the paper's dangerous situation, by how many metres the
    distance falls short. ``t`` and ``agent`` name the worst moment. Parameters: an :class:`RSSParams` and/or its fields as keywords
    (``rss(response_time=0.5)``); ``axis`` [rad] fixes the longitudinal axis (default: the
    ego's lane direction). Blame is not judged here; see :func:`rss_blame`."""
    if axis is not None:
        try:
            axis = float(axis)
        except (TypeError, ValueError):
            raise MonitorError(f"{name}: axis must be an angle [rad] or None, got {axis!r}") from None
        if not math.isfinite(axis):
            raise MonitorError(f"{name}: axis must be finite, got {axis!r}")
    return RSSMonitor(_params(params, overrides), axis, name)


# -- responsibility -------------------------------------------------------------------------------

@dataclass(frozen=True)
class RSSEpisode:
    """One maximal run of dangerous samples of a pair.

    ``start``/``end`` [s] its first and last dangerous sample; ``blame_time`` [s] the last
    safe sample before it; ``response`` the proper response owed: "longitudinal" or
    "lateral" (the distance still safe at the blame time), "either" when both were lost at
    once (a car complying with one of them complies), "initial" when the episode is dangerous
    from the first sample (no blame time: nobody entered it, nobody is responsible);
    ``ego_violation``/``other_violation`` [s] when that car first failed its proper response
    in the episode (None: it responded properly).
    """

    start: float
    end: float
    blame_time: float | None
    response: str
    ego_violation: float | None
    other_violation: float | None


@dataclass(frozen=True)
class RSSBlame:
    """Who was RSS-unsafe first between the ego and one other agent.

    ``ego_unsafe_at``/``other_unsafe_at`` [s]: the start of the first dangerous episode that
    car is responsible for (it did not respond properly), None if none.
    """

    ego: str
    other: str
    ego_unsafe_at: float | None
    other_unsafe_at: float | None
    episodes: tuple[RSSEpisode, ...]

    @property
    def first(self) -> str | None:
        """The name of the car that entered an unsafe state by its own responsibility first,
        ``"both"`` at the same time, None if neither did."""
        e, o = self.ego_unsafe_at, self.other_unsafe_at
        if e is None and o is None:
            return None
        if o is None or (e is not None and e < o):
            return self.ego
        if e is None or o < e:
            return self.other
        return "both"


def _first_true(mask: np.ndarray, t: np.ndarray) -> float | None:
    idx = np.flatnonzero(mask)
    return float(t[idx[0]]) if idx.size else None


def _later(a: float | None, b: float | None) -> float | None:
    """Both responses applied and either suffices: a car fails when it failed both."""
    return None if a is None or b is None else max(a, b)


def rss_blame(trajectory: Trajectory, params: RSSParams | None = None, *,
              axis: float | None = None, **overrides: Any) -> tuple[RSSBlame, ...]:
    """For every (ego, other) pair: its dangerous episodes, which proper response each owed,
    and the first time each car entered an RSS-unsafe state by its own responsibility.

    One :class:`RSSBlame` per other agent, in trajectory order. See the module doc for the
    paper's definitions and the simplifications made.
    """
    p = _params(params, overrides)
    traj = trajectory
    if not isinstance(traj, Trajectory):
        raise MonitorError(f"rss_blame needs a Trajectory, got {type(traj).__name__}")
    check_present_finite(traj, "rss_blame", ("x", "y", "vx", "vy", "heading"))
    if traj.n_agents < 2:
        return ()
    pr = _pairs(traj, p, axis)
    t = traj.t
    T = traj.n_steps
    dt = np.diff(t)
    danger = pr.present & (pr.lon_margin < 0) & (pr.lat_margin < 0)
    out = []
    for i in range(traj.n_agents - 1):
        episodes = []
        d = danger[i].astype(np.int8)
        edges = np.diff(np.concatenate([[0], d, [0]]))
        crashed = np.flatnonzero((traj.crashed[0] | traj.crashed[i + 1]) & pr.present[i])
        crash = int(crashed[0]) if crashed.size else T
        for k0, k1 in zip(np.flatnonzero(edges == 1), np.flatnonzero(edges == -1) - 1):
            episodes.append(_episode(pr, i, int(k0), int(k1), t, dt, T, p, crash))
        ego_at = next((e.start for e in episodes if e.ego_violation is not None), None)
        other_at = next((e.start for e in episodes if e.other_violation is not None), None)
        out.append(RSSBlame(traj.names[0], traj.names[i + 1], ego_at, other_at, tuple(episodes)))
    return tuple(out)


def _episode(pr: _Pairs, i: int, k0: int, k1: int, t: np.ndarray, dt: np.ndarray, T: int,
             p: RSSParams, crash: int) -> RSSEpisode:
    if k0 == 0:
        # dangerous from the first sample: nobody entered it, there is no blame time
        return RSSEpisode(float(t[k0]), float(t[k1]), None, "initial", None, None)
    kb = k0 - 1  # the blame time: roles and sides are those then
    lon_kind = pr.lon_margin[i, kb] >= 0
    lat_kind = pr.lat_margin[i, kb] >= 0
    # accelerations of the steps the episode spans (step k acts from t[k] to t[k + 1]),
    # up to a crash of either car: after it the simulator, not the drivers, moves them
    end = min(k1 + 1, T - 1, crash)
    ks = np.arange(kb, max(end, kb))
    t_start = t[kb]
    in_rho = t[ks] < t_start + p.response_time - 1e-9
    sign = pr.sign[kb]
    ahead = bool(pr.ahead[i, kb])
    same_way = bool(pr.same_way[i, kb])
    left = bool(pr.left[i, kb])

    def lon_violation(row: int, role: str) -> float | None:
        # speed along the car's own direction of travel (the ego's, or against it when the
        # other comes the opposite way)
        direction = sign if (row == 0 or same_way) else -sign
        u_next = direction * pr.v_lon[row, ks + 1]
        a = (u_next - direction * pr.v_lon[row, ks]) / dt[ks]
        if role == "front":
            bad = a < -p.a_max_brake - ACCEL_TOLERANCE
        else:
            brake = p.a_min_brake if role == "rear" else p.a_min_brake_correct
            # a step that ends (nearly) standing has responded, however little it braked
            bad = np.where(in_rho, a > p.a_max_accel + ACCEL_TOLERANCE,
                           (a > -brake + ACCEL_TOLERANCE) & (u_next > STILL))
        return _first_true(bad, t[ks])

    def lat_violation(row: int) -> float | None:
        toward = (-1.0 if left else 1.0) if row else (1.0 if left else -1.0)
        u_next = toward * pr.v_lat[row, ks + 1]
        a = (u_next - toward * pr.v_lat[row, ks]) / dt[ks]
        bad = np.where(in_rho, a > p.a_lat_max_accel + ACCEL_TOLERANCE,
                       (a > -p.a_lat_min_brake + ACCEL_TOLERANCE) & (u_next > STILL))
        return _first_true(bad, t[ks])

    if same_way:
        roles = ("rear", "front") if ahead else ("front", "rear")
    else:
        roles = ("oncoming", "oncoming")
    found = []
    for row, role in ((0, roles[0]), (i + 1, roles[1])):
        lon_v = lon_violation(row, role) if ks.size else None
        lat_v = lat_violation(row) if ks.size else None
        if lon_kind and not lat_kind:
            found.append(lon_v)
        elif lat_kind and not lon_kind:
            found.append(lat_v)
        else:
            found.append(_later(lon_v, lat_v))
    response = ("longitudinal" if lon_kind and not lat_kind else
                "lateral" if lat_kind and not lon_kind else "either")
    return RSSEpisode(float(t[k0]), float(t[k1]), float(t[kb]), response, found[0], found[1])

"""Criticality measures under the names CommonRoad-CriMe gives them: enhanced time to
collision (TTC with accelerations), required deceleration, brake threat number, time to
brake, time to steer, and post-encroachment time at crossings.

The first five look at the road user ahead of the ego in its lane (same lane id when both
are known, or a lane further along the ego's recorded route, so a lead past a map's lane
section or road boundary stays ahead; else overlapping lateral corridors, as
:func:`.metrics.headway`), along the ego's
heading: bumper-to-bumper gap ``g`` [m], speeds ``v_e``, ``v_l`` [m/s] and accelerations
``a_e``, ``a_l`` [m/s²] (signed; the time derivative of the recorded velocities, projected on
the ego's heading). Post-encroachment time looks at every road user whose path crosses the
ego's. All of them are computed with numpy over the whole ``(agents, steps)`` grid; their
closed forms are in each function's docstring and checked in the tests.

Where CriMe differs (README, "Rules of the road, criticality and the driving score"): its
TTC (constant accelerations, our :func:`ettc`) and required deceleration use the magnitude
of the other vehicle's acceleration, dropping its sign, project on a lanelet's orientation,
and let a braking lead reverse. Here the signs are kept, everything is along the ego's
heading, and a lead that brakes stops.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

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
from .metrics import _pair_mask, _sat_separation

__all__ = [
    "LeadKinematics", "lead_kinematics", "ettc_values", "required_deceleration_values",
    "time_to_brake_values", "time_to_steer_values", "pet_values",
    "ettc", "required_deceleration", "brake_threat_number", "time_to_brake", "time_to_steer",
    "post_encroachment_time", "MAX_DECEL_MPS2", "MAX_LAT_ACCEL_MPS2",
]

#: [m/s²] the ego's default braking capability (dry road, emergency braking)
MAX_DECEL_MPS2 = 8.0
#: [m/s²] the ego's default lateral acceleration capability for an evasive steer
MAX_LAT_ACCEL_MPS2 = 5.0
#: [s] how far ahead time to brake looks for the moment braking stops being enough
TTB_HORIZON_S = 10.0


@dataclass(frozen=True)
class LeadKinematics:
    """The pairs (ego, other agent) in which the other is ahead of the ego in its lane (or on
    a lane further along its route), as
    1-D arrays over those pairs: gap [m] bumper to bumper along the ego's heading, lateral
    offset ``lat`` [m] of its centre from the ego's axis, speeds ``v_e``/``v_l`` [m/s] and
    accelerations ``a_e``/``a_l`` [m/s²] along the ego's heading, the other's width
    ``width_l`` [m]; ``idx`` their flat indices in the ``(A-1, T)`` grid (``shape``). The
    measures are computed on these few pairs and put back with :meth:`scatter`."""

    gap: np.ndarray
    lat: np.ndarray
    v_e: np.ndarray
    v_l: np.ndarray
    a_e: np.ndarray
    a_l: np.ndarray
    width_l: np.ndarray
    idx: np.ndarray
    shape: tuple[int, int]
    #: each pair's other agent (its row in the ``(A-1, T)`` grid) and step: ``divmod(idx, T)``
    row: np.ndarray | None = None
    step: np.ndarray | None = None

    def scatter(self, values: np.ndarray) -> np.ndarray:
        """``values`` of the pairs back on the ``(A-1, T)`` grid, NaN elsewhere."""
        out = np.full(self.shape, np.nan)
        out.ravel()[self.idx] = values
        return out




def _derivative(v: np.ndarray, t: np.ndarray) -> np.ndarray:
    """``d v / d t`` along the last axis: central differences inside, one-sided at the ends
    (exact for a velocity linear in time)."""
    out = np.empty_like(v)
    if v.shape[-1] < 2:
        out[...] = 0.0
        return out
    out[..., 1:-1] = (v[..., 2:] - v[..., :-2]) / (t[2:] - t[:-2])
    out[..., 0] = (v[..., 1] - v[..., 0]) / (t[1] - t[0])
    out[..., -1] = (v[..., -1] - v[..., -2]) / (t[-1] - t[-2])
    return out


def _derivative_at(v: np.ndarray, t: np.ndarray, rows: np.ndarray, cols: np.ndarray
                   ) -> np.ndarray:
    """:func:`_derivative` of ``v`` (``(..., agents, steps)``) at ``[..., rows, cols]`` only,
    with the same differences (central inside, one-sided at the ends)."""
    T = t.shape[0]
    if T < 2:
        return np.zeros(v.shape[:-2] + rows.shape)
    lo = np.maximum(cols - 1, 0)
    hi = np.minimum(cols + 1, T - 1)
    return (v[..., rows, hi] - v[..., rows, lo]) / (t[hi] - t[lo])


#: rows selecting the ego (0) and the other agent (its row) of a pair
_EGO_OTHER = np.array([[0], [1]])


def _further_on_route(traj: Trajectory, route: list[str]) -> np.ndarray:
    """``(A-1, T)``: whether the other agent is on a lane of the ego's route beyond the
    route lane the ego is on (its lane ahead carries another id: the next lane section or
    road of a map, the road past a junction)."""
    where = {}
    for k, lane_id in enumerate(route):
        where.setdefault(lane_id, k)
    ids = set(traj.lane.ravel().tolist()) & where.keys()
    pos = np.full(traj.lane.shape, -1)
    for lane_id in ids:
        pos[traj.lane == lane_id] = where[lane_id]
    return (pos[0] >= 0)[None, :] & (pos[1:] > pos[0][None, :])


def lead_kinematics(traj: Trajectory) -> LeadKinematics:
    """The :class:`LeadKinematics` of ``traj`` (computed once per trajectory)."""
    cache = memo(traj)
    got = cache.get("criticality.lead")
    if got is not None:
        return got
    h = traj.heading[0]
    c, s = np.cos(h), np.sin(h)
    dx = traj.x[1:] - traj.x[0]
    dy = traj.y[1:] - traj.y[0]
    lon = dx * c + dy * s
    lat = -dx * s + dy * c
    with np.errstate(invalid="ignore", divide="ignore"):
        lanes_known = (traj.lane[0] != "")[None, :] & (traj.lane[1:] != "")
        same_lane = traj.lane[1:] == traj.lane[0][None, :]
        route = traj.meta.get("ego_route") or ()
        if len(route) > 1:  # a lane change of id along the way (a map's next road or section)
            same_lane |= _further_on_route(traj, [str(r) for r in route])
        if lanes_known.all():  # every lane known: the lanes decide, no corridor needed
            ahead = (lon > 0) & same_lane & _pair_mask(traj)
        else:
            corridor = np.abs(lat) < (traj.width[0] + traj.width[1:, None]) / 2
            ahead = (lon > 0) & np.where(lanes_known, same_lane, corridor) & _pair_mask(traj)
        idx = np.flatnonzero(ahead)
        rows, cols = np.divmod(idx, traj.n_steps)
        o = rows + 1  # the other agent's row in the trajectory
        # velocities and their time derivatives (as _derivative takes them, at the pairs'
        # steps only) of the ego and the other, projected on the ego's heading at once
        vel = np.array([traj.vx, traj.vy])
        who = _EGO_OTHER * o  # (ego / other, pairs): row 0 the ego's, row 1 the other's
        kin = np.array([vel[:, who, cols], _derivative_at(vel, traj.t, who, cols)])
        along = kin[:, 0] * c[cols] + kin[:, 1] * s[cols]  # (v / a, ego / other, pairs)
    got = LeadKinematics(
        gap=lon[rows, cols] - (traj.length[0] + traj.length[o]) / 2,
        lat=lat[rows, cols],
        v_e=along[0, 0], v_l=along[0, 1], a_e=along[1, 0], a_l=along[1, 1],
        width_l=traj.width[o], idx=idx, shape=(traj.n_agents - 1, traj.n_steps),
        row=rows, step=cols)
    cache["criticality.lead"] = got
    return got


# -- closed forms -----------------------------------------------------------------------------

def ettc_values(gap, v_e, v_l, a_e, a_l):
    """Enhanced time to collision [s]: the first ``t > 0`` with
    ``gap - (v_e - v_l) t - ½ (a_e - a_l) t² = 0`` (both keep their accelerations), i.e.
    ``2 g / (u + sqrt(u² + 2 α g))`` with closing speed ``u = v_e - v_l`` and closing
    acceleration ``α = a_e - a_l``, where ``u² + 2 α g >= 0`` and ``u + sqrt(...) > 0``;
    +inf where the gap never closes; 0 where it is already closed. NaN stays NaN."""
    g = np.asarray(gap, dtype=float)
    u = np.asarray(v_e, dtype=float) - v_l
    alpha = np.asarray(a_e, dtype=float) - a_l
    # differentiated velocities carry rounding noise: a relative acceleration of 1e-9 m/s²
    # would turn a receding pair into a collision in 1e15 s
    alpha = np.where(np.abs(alpha) < 1e-9, 0.0, alpha)
    disc = u * u + 2.0 * alpha * g
    with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
        real = disc >= 0
        root = np.sqrt(np.where(real, disc, 0.0))
        den = u + root
        out = np.where(real & (den > 1e-9), 2.0 * g / den, np.inf)
    out = np.where(g <= 0, 0.0, out)
    return np.where(np.isnan(g) | np.isnan(u) | np.isnan(alpha), np.nan, out)


def required_deceleration_values(gap, v_e, v_l, a_l):
    """Required deceleration [m/s², >= 0]: the smallest constant braking ``b`` of the ego,
    from now to a stop, that keeps the gap open while the lead keeps its acceleration
    ``a_l`` until it stands (no one reverses).

    The gap is smallest when the speeds match: ``b1 = max(0, u²/(2g) - a_l)`` with closing
    speed ``u = v_e - v_l > 0``, when that moment ``u / (a_l + b1)`` comes before a braking
    lead stands (``v_l / -a_l``). Otherwise the ego must stop behind where the lead stops:
    ``b2 = v_e² / (2 (g + d_l))``, ``d_l = v_l² / (2 (-a_l))`` (0 for a standing lead; a lead
    that does not brake never stops, and an ego not closing in needs 0). +inf where the gap
    is already closed."""
    g = np.asarray(gap, dtype=float)
    v_e = np.maximum(np.asarray(v_e, dtype=float), 0.0)
    v_l = np.maximum(np.asarray(v_l, dtype=float), 0.0)
    a_l = np.asarray(a_l, dtype=float)
    u = v_e - v_l
    moving = v_l > 0
    with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
        b1 = np.maximum(u * u / (2.0 * g) - a_l, 0.0)
        # when and where a braking lead stands (0 for a standing one, inf for one that never does)
        t_lead = np.where(moving, np.where(a_l < 0, v_l / -a_l, np.inf), 0.0)
        d_lead = np.where(moving, v_l * t_lead / 2.0, 0.0)
        b2 = v_e * v_e / (2.0 * (g + d_lead))
        # closing in (u > 0) gives a_l + b1 >= u²/2g > 0: the speeds match at u / (a_l + b1)
        match_first = (u > 0) & (u <= (a_l + b1) * t_lead)
    out = np.where(match_first, b1, np.where(t_lead < np.inf, b2, 0.0))
    out = np.where(g <= 0, np.inf, out)
    return np.where(np.isnan(g) | np.isnan(u) | np.isnan(a_l), np.nan, out)


def _advance(v: np.ndarray, a: np.ndarray, tau: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Distance [m] and speed [m/s] after ``tau`` [s] at constant ``a``, stopping at 0 (the
    definition :func:`_too_hard` computes inline; the tests hold the two to each other)."""
    with np.errstate(invalid="ignore", divide="ignore"):
        t_stop = np.where(a < 0, v / np.where(a < 0, -a, 1.0), np.inf)
    t = np.minimum(tau, t_stop)
    return v * t + 0.5 * a * t * t, np.maximum(v + a * t, 0.0)


def time_to_brake_values(k: LeadKinematics, max_decel: float,
                         horizon: float = TTB_HORIZON_S, grid_s: float = 0.5,
                         fine: int = 64, *, smallest_only: bool = False) -> np.ndarray:
    """Time to brake [s]: how long the ego can keep its acceleration before braking at
    ``max_decel`` is no longer enough (the required deceleration of the state it then
    reaches exceeds ``max_decel``); both keep their accelerations meanwhile, no one reverses.
    0 when it is already too late, +inf when braking is still enough after ``horizon``
    (1-D over the pairs of ``k``).
    The first moment on a ``grid_s`` grid, refined twice on ``fine`` points within the
    bracket (to ``grid_s / fine²``, 0.12 ms by default), for every agent ahead and step at
    once. With ``smallest_only`` a pair whose grid bracket lies wholly above another's keeps
    the bracket's lower end instead of being refined: the smallest value, and which pairs
    have it, are exact (what a monitor's verdict needs), the others are lower bounds."""
    if k.gap.size == 0:
        return np.zeros(0)
    with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
        return _time_to_brake(k, float(max_decel), horizon, grid_s, fine, smallest_only)


def _too_hard(tau: np.ndarray, p: np.ndarray, max_decel: float) -> np.ndarray:
    """Whether braking at ``max_decel`` is no longer enough after keeping the accelerations
    for ``tau`` [s]: ``required_deceleration_values(state after tau) > max_decel``, the same
    arithmetic as :func:`_advance` and :func:`required_deceleration_values` (bit for bit,
    so the grid finds the same moments) with the per-pair parts ``p`` (:func:`_pair_columns`)
    computed once and the comparison taken case by case instead of building the value. A
    pair with a NaN input is never too hard (its gap is NaN at every ``tau``)."""
    if p.shape[-1] != tau.shape[-1]:
        # the columns repeated along the moments: numpy's same-shape loops are much faster
        # than broadcasting a column, and the arithmetic is the same
        p = np.repeat(p, tau.shape[-1], axis=-1)
    g0, v, a, ha, ts, nal = p[0], p[1:3], p[3:5], p[5:7], p[7:9], p[9]
    a_l = a[1]
    # ego (row 0) and lead (row 1) advanced at once: _advance's arithmetic on both
    t = np.minimum(tau, ts)
    d = v * t + ha * t * t
    vv = np.maximum(v + a * t, 0.0)
    de, dl, ve, vl = d[0], d[1], vv[0], vv[1]
    g = g0 + dl - de
    u = ve - vl
    # required_deceleration_values takes a standing lead's acceleration as 0; a_l serves
    # here because there t_lead = 0 makes match_first False whatever b1 is, and b1 decides
    # nothing else
    b1 = np.maximum(u * u / (2.0 * g) - a_l, 0.0)
    # when a braking lead stands (0 standing, inf when it never does: nal is 0 for a lead
    # that does not brake, and vl / 0 is inf for a moving one); where it is moving its
    # acceleration is a_l's, so the per-pair sign and magnitude serve
    t_lead = np.where(vl > 0, vl / nal, 0.0)
    d_lead = vl * t_lead / 2.0  # 0 for a standing lead (vl = 0, t_lead = 0)
    b2 = ve * ve / (2.0 * (g + d_lead))
    match_first = (u > 0) & (u <= (a_l + b1) * t_lead)
    # out = b1 where the speeds match first, else b2 where the lead stops, else 0 (never
    # above max_decel > 0: and b2 is 0 where the lead never stops, d_lead being inf there);
    # inf (too hard) where the gap is closed
    return (g <= 0) | (np.where(match_first, b1, b2) > max_decel)


def _pair_columns(k: LeadKinematics) -> np.ndarray:
    """What :func:`_too_hard` needs of every pair, stacked as rows of one ``(10, pairs, 1)``
    array (so the pairs still to refine are one selection) against a grid of moments: the
    gap; the ego's and the lead's speed (no reversing), acceleration, half of it and
    :func:`_advance`'s stop time; the lead's deceleration (-a_l where it brakes, else 0)."""
    v = np.maximum(np.array([k.v_e, k.v_l]), 0.0)
    a = np.array([k.a_e, k.a_l])
    brakes = a < 0
    ts = np.where(brakes, v / np.where(brakes, -a, 1.0), np.inf)
    nal = np.where(brakes[1], -k.a_l, 0.0)
    return np.concatenate([k.gap[None], v, a, 0.5 * a, ts, nal[None]])[..., None]


_GRIDS: dict[tuple[float, float], np.ndarray] = {}


def _grid(horizon: float, grid_s: float) -> np.ndarray:
    """The moments ``0, grid_s, ...`` up to ``horizon`` [s], made once per pair of values."""
    got = _GRIDS.get((horizon, grid_s))
    if got is None:
        got = np.arange(0.0, horizon + grid_s / 2, grid_s)
        got.flags.writeable = False
        if len(_GRIDS) < 16:  # a caller sweeping the horizon does not fill memory
            _GRIDS[(horizon, grid_s)] = got
    return got


_FRACTIONS: dict[int, np.ndarray] = {}


def _fractions(fine: int) -> np.ndarray:
    """``(1..fine) / fine``, made once per ``fine``."""
    got = _FRACTIONS.get(fine)
    if got is None:
        got = _FRACTIONS[fine] = np.arange(1, fine + 1) / fine
    return got


def _time_to_brake(k: LeadKinematics, max_decel: float, horizon: float, grid_s: float,
                   fine: int, smallest_only: bool = False) -> np.ndarray:
    p = _pair_columns(k)

    grid = _grid(horizon, grid_s)
    too_hard = _too_hard(grid, p, max_decel)
    first = np.argmax(too_hard, axis=1)
    # too late already (the first grid point, now) or still enough at the horizon (never)
    now = too_hard[:, 0]
    res = np.where(now, 0.0, np.inf)
    todo = np.flatnonzero(first > 0)  # too hard first at a later grid point: refine
    lower = grid[first[todo] - 1]
    if smallest_only and todo.size:
        # a refined value lies in [grid[first - 1], grid[first]); pairs whose lower end is
        # above the smallest upper end (0 when some pair is too late already) cannot be
        # the smallest nor tie with it
        upper = 0.0 if now.any() else grid[first[todo]].min()
        res[todo] = lower
        keep = lower <= upper
        todo, lower = todo[keep], lower[keep]
    if todo.size:
        # the pairs' columns along `fine` moments, for both rounds
        p = np.repeat(p[:, todo] if todo.size < first.size else p, fine, axis=-1)
        lo, step = lower, grid_s
        # refine on finer grids inside the bracket (two rounds of `fine` points: few numpy
        # calls, which is what costs on a handful of pairs)
        frac = _fractions(fine)
        for _ in range(2):
            pts = lo[:, None] + step * frac[None, :]
            bad = _too_hard(pts, p, max_decel)
            j = np.argmax(bad, axis=1)  # the first too-late point; the one before is fine
            lo = lo + step * np.where(j > 0, frac[np.maximum(j - 1, 0)], 0.0)
            step = step / fine
        res[todo] = lo
    return res


def time_to_steer_values(k: LeadKinematics, width_e: float, max_lat_accel: float,
                         ttc: np.ndarray | None = None) -> np.ndarray:
    """Time to steer [s]: the enhanced time to collision minus the time an evasive steer at
    ``max_lat_accel`` [m/s²] (from no lateral speed) takes to move the ego sideways clear of
    the lead, ``sqrt(2 d / a_lat)`` with ``d = (w_e + w_l)/2 - |lat|``. Negative: too late.
    ``ttc``: the pairs' enhanced TTC when the caller has it (1-D over the pairs of ``k``)."""
    if ttc is None:
        ttc = ettc_values(k.gap, k.v_e, k.v_l, k.a_e, k.a_l)
    d = np.maximum((width_e + k.width_l) / 2 - np.abs(k.lat), 0.0)
    return ttc - np.sqrt(2.0 * d / max_lat_accel)


# -- monitors of the vehicle ahead ------------------------------------------------------------

class _LeadMeasure(Monitor):
    """ρ = min over steps and agents ahead of ``sign * (value - threshold)``."""

    invariant = True
    _what = ""
    _unit = ""
    _upper = False  # True: the value must stay <= threshold

    def _values(self, traj: Trajectory) -> np.ndarray:
        """The measure over the pairs of :func:`lead_kinematics` (1-D)."""
        raise NotImplementedError

    def _smallest(self, traj: Trajectory) -> np.ndarray:
        """:meth:`_values` where a measure's smallest margin (and the pairs that have it)
        must be exact, the others may be bounds on the safe side of it."""
        return self._values(traj)

    def _margins(self, v: np.ndarray) -> np.ndarray:
        m = (self.threshold - v) if self._upper else (v - self.threshold)
        # +inf where v is NaN (m is NaN exactly there: the threshold is finite)
        return np.fmin(m, np.inf)

    def series(self, traj: Trajectory) -> np.ndarray:
        """ρ(t): the margin toward the most critical agent ahead at each step; +inf where
        nothing is ahead."""
        k = lead_kinematics(traj)
        out = np.full(traj.n_steps, np.inf)
        np.minimum.at(out, k.step, self._margins(self._values(traj)))
        return out

    def _evaluate(self, traj: Trajectory) -> MonitorResult:
        check_present_finite(traj, self.name, ("x", "y", "vx", "vy", "heading"))
        k = lead_kinematics(traj)
        values = self._smallest(traj)
        m = self._margins(values)
        # the smallest margin, earliest step first on ties (as the pairwise metrics)
        j = int(np.lexsort((k.row, k.step, m))[0]) if m.size else -1
        if j < 0 or not m[j] < math.inf:
            return MonitorResult(self.name, math.inf, self.threshold, None, None,
                                 f"nothing ahead of the ego that makes {self._what} finite")
        row, step = int(k.row[j]), int(k.step[j])
        v = values[j]
        who = traj.names[row + 1]
        bound = "<=" if self._upper else ">="
        return MonitorResult(
            self.name, float(m[j]), self.threshold, fmt_t(traj, step), who,
            f"{self._what} {v:.3g}{' ' + self._unit if self._unit else ''} behind {who} at "
            f"t={traj.t[step]:.2f} s (required {bound} {self.threshold:g} {self._unit})".rstrip())


def _required(traj: Trajectory) -> np.ndarray:
    """Required deceleration toward each agent ahead, over the pairs of
    :func:`lead_kinematics` (shared by a_req and BTN)."""
    cache = memo(traj)
    got = cache.get("criticality.required")
    if got is None:
        k = lead_kinematics(traj)
        got = cache["criticality.required"] = required_deceleration_values(
            k.gap, k.v_e, k.v_l, k.a_l)
    return got


def _ettc(traj: Trajectory) -> np.ndarray:
    """Enhanced TTC toward each agent ahead, over the pairs of :func:`lead_kinematics`
    (shared by ETTC and TTS)."""
    cache = memo(traj)
    got = cache.get("criticality.ettc")
    if got is None:
        k = lead_kinematics(traj)
        got = cache["criticality.ettc"] = ettc_values(k.gap, k.v_e, k.v_l, k.a_e, k.a_l)
    return got


class ETTCMonitor(_LeadMeasure):
    _what, _unit = "enhanced TTC", "s"

    def __init__(self, threshold: float = 2.0, *, name: str = "ettc"):
        self.threshold = check_threshold(name, threshold)
        self.name = check_name(name)

    def _values(self, traj):
        return _ettc(traj)


class RequiredDecelerationMonitor(_LeadMeasure):
    _what, _unit, _upper = "required deceleration", "m/s²", True

    def __init__(self, max: float = 4.0, *, name: str = "required_deceleration"):
        self.threshold = check_positive(name, max, "max", allow_zero=True)
        self.name = check_name(name)

    def _values(self, traj):
        return _required(traj)


class BrakeThreatMonitor(_LeadMeasure):
    _what, _unit, _upper = "brake threat number", "", True

    def __init__(self, max: float = 1.0, *, max_decel: float = MAX_DECEL_MPS2,
                 name: str = "brake_threat_number"):
        self.threshold = check_positive(name, max, "max", allow_zero=True)
        self.max_decel = check_positive(name, max_decel, "max_decel")
        self.name = check_name(name)

    def _values(self, traj):
        return _required(traj) / self.max_decel


class TimeToBrakeMonitor(_LeadMeasure):
    _what, _unit = "time to brake", "s"

    def __init__(self, threshold: float = 1.0, *, max_decel: float = MAX_DECEL_MPS2,
                 name: str = "time_to_brake"):
        self.threshold = check_threshold(name, threshold)
        self.max_decel = check_positive(name, max_decel, "max_decel")
        self.name = check_name(name)

    def _values(self, traj):
        return time_to_brake_values(lead_kinematics(traj), self.max_decel)

    def _smallest(self, traj):
        return time_to_brake_values(lead_kinematics(traj), self.max_decel, smallest_only=True)


class TimeToSteerMonitor(_LeadMeasure):
    _what, _unit = "time to steer", "s"

    def __init__(self, threshold: float = 0.5, *, max_lat_accel: float = MAX_LAT_ACCEL_MPS2,
                 name: str = "time_to_steer"):
        self.threshold = check_threshold(name, threshold)
        self.max_lat_accel = check_positive(name, max_lat_accel, "max_lat_accel")
        self.name = check_name(name)

    def _values(self, traj):
        return time_to_steer_values(lead_kinematics(traj), float(traj.width[0]),
                                    self.max_lat_accel, ttc=_ettc(traj))


@factory
def ettc(threshold: float = 2.0, *, name: str = "ettc") -> Monitor:
    """CriMe's TTC (constant accelerations, often called ETTC): rho = min over steps of
    (enhanced TTC - ``threshold``) [s] toward the road user ahead in the ego's lane, both keeping their
    accelerations (see :func:`ettc_values`); +inf when the gap never closes. The paper's
    :func:`ttc` (constant velocities, any direction, a circle) is not CriMe's."""
    return ETTCMonitor(threshold, name=name)


@factory
def required_deceleration(max: float = 4.0, *,
                          name: str = "required_deceleration") -> Monitor:
    """CriMe's a_req: the ego never needs to brake harder than ``max`` [m/s²] to avoid the
    road user ahead (see :func:`required_deceleration_values`). rho = ``max`` - the largest
    required deceleration [m/s²]."""
    return RequiredDecelerationMonitor(max, name=name)


@factory
def brake_threat_number(max: float = 1.0, *, max_decel: float = MAX_DECEL_MPS2,
                        name: str = "brake_threat_number") -> Monitor:
    """CriMe's BTN: required deceleration / the ego's braking capability ``max_decel``
    [m/s²] stays <= ``max`` (above 1 braking alone cannot avoid the collision). rho = ``max``
    - the largest BTN."""
    return BrakeThreatMonitor(max, max_decel=max_decel, name=name)


@factory
def time_to_brake(threshold: float = 1.0, *, max_decel: float = MAX_DECEL_MPS2,
                  name: str = "time_to_brake") -> Monitor:
    """CriMe's TTB: the ego can always wait at least ``threshold`` [s] before braking at
    ``max_decel`` [m/s²] must begin (see :func:`time_to_brake_values`). rho = min over steps
    of (TTB - ``threshold``) [s]."""
    return TimeToBrakeMonitor(threshold, max_decel=max_decel, name=name)


@factory
def time_to_steer(threshold: float = 0.5, *, max_lat_accel: float = MAX_LAT_ACCEL_MPS2,
                  name: str = "time_to_steer") -> Monitor:
    """CriMe's TTS: an evasive steer at ``max_lat_accel`` [m/s²] can always wait at least
    ``threshold`` [s] (see :func:`time_to_steer_values`). rho = min over steps of (TTS -
    ``threshold``) [s]."""
    return TimeToSteerMonitor(threshold, max_lat_accel=max_lat_accel, name=name)


# -- post-encroachment time -------------------------------------------------------------------

#: [deg] paths that meet at a smaller angle (following, oncoming) do not cross
CROSSING_MIN_ANGLE_DEG = 30.0


#: heading bins over half a turn (|sin| of a heading difference repeats every pi)
_NBINS = 32  # a power of two: the bin of a half turn is a bit mask of the floor


def _heading_bins(h: np.ndarray) -> np.ndarray:
    return np.floor(h * (_NBINS / np.pi)).astype(np.int64) & (_NBINS - 1)


def _can_cross(min_angle_deg: float) -> np.ndarray:
    """``(bins, bins)``: whether two headings in these bins can differ by at least
    ``min_angle_deg`` (modulo a half turn); conservative by one bin."""
    b = np.arange(_NBINS)
    d = np.abs(b[:, None] - b[None, :])
    d = np.minimum(d, _NBINS - d)  # 0 .. NBINS/2 bins: 0 .. 90 degrees
    return (d + 1) * (180.0 / _NBINS) >= min_angle_deg


#: the default angle's table, and as 0.0 / 1.0 (for a product with the bins an agent uses)
_CAN_CROSS = {float(CROSSING_MIN_ANGLE_DEG): _can_cross(CROSSING_MIN_ANGLE_DEG)}
_CAN_CROSS_F = {a: c.astype(float) for a, c in _CAN_CROSS.items()}


def pet_values(traj: Trajectory, min_angle_deg: float = CROSSING_MIN_ANGLE_DEG
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Post-encroachment time of the ego with each other agent: ``(pet [s], t_first_leaves,
    t_second_enters)`` each ``(A-1,)``, +inf / NaN where their paths do not cross.

    PET is the time from the first road user leaving the ground both paths cover to the
    second reaching it: the smallest ``|t_i - t_j|`` over pairs of samples at which the ego's
    footprint at ``t_i`` overlaps the other's at ``t_j`` (0 when they meet at once: a
    collision), counting only pairs whose headings differ by at least ``min_angle_deg`` (a
    crossing, not following or oncoming traffic). Exact to the sampling step."""
    A1 = traj.n_agents - 1
    pet, t1, t2 = [math.inf] * A1, [math.nan] * A1, [math.nan] * A1

    def out():
        return np.array(pet, dtype=float), np.array(t1, dtype=float), np.array(t2, dtype=float)

    ok = traj.present & np.isfinite(traj.x) & np.isfinite(traj.y)
    ie = np.flatnonzero(ok[0])
    if A1 < 1 or ie.size == 0:
        return out()
    R = np.hypot(traj.length / 2, traj.width / 2).tolist()
    sin_min = math.sin(math.radians(min_angle_deg))
    can, can_f = _CAN_CROSS.get(min_angle_deg), _CAN_CROSS_F.get(min_angle_deg)
    if can is None:
        can = _can_cross(min_angle_deg)
        can_f = can.astype(float)
    bins = _heading_bins(np.where(ok, traj.heading, 0.0))
    T = traj.n_steps
    ebins, obins = (bins[0] if ie.size == T else bins[0, ie]), bins[1:]
    # keep only samples whose heading can cross one of the other path's (traffic along the
    # ego's lane never can, and is dropped here for every agent at once)
    e_bins = np.bincount(ebins, minlength=_NBINS) > 0  # the heading bins the ego uses
    o_ok_all = ok[1:] & can[:, e_bins].any(axis=1)[obins]
    rows, cols = np.nonzero(o_ok_all)
    if rows.size == 0:
        return out()
    seen = np.zeros((A1, _NBINS))  # the heading bins each agent's kept samples use (0 / 1)
    seen[rows, obins[rows, cols]] = 1.0
    # (A-1, bins): a bin of the ego's heading that crosses one of the agent's kept headings
    # (counts of small integers: exact in floating point)
    crossing = (seen @ can_f) > 0
    x, y, heading, t = traj.x, traj.y, traj.heading, traj.t
    lo, hi = np.minimum.reduce, np.maximum.reduce
    for a in (np.flatnonzero((crossing & e_bins).any(axis=1)) + 1).tolist():
        io, ie_a = np.flatnonzero(o_ok_all[a - 1]), ie[crossing[a - 1][ebins]]
        # (every sample of a row: the row itself, the same values)
        xe, ye = (x[0], y[0]) if ie_a.size == T else (x[0, ie_a], y[0, ie_a])
        reach = R[0] + R[a]
        xo, yo = (x[a], y[a]) if io.size == T else (x[a, io], y[a, io])
        # samples of each path within reach of the other path's bounding box
        ne = ((xe >= float(lo(xo)) - reach) & (xe <= float(hi(xo)) + reach)
              & (ye >= float(lo(yo)) - reach) & (ye <= float(hi(yo)) + reach))
        i = ie_a[ne]
        if i.size == 0:
            continue
        if i.size * io.size > 4096:  # the other's samples near the ego's path, when many
            xe, ye = xe[ne], ye[ne]
            no = ((xo >= float(lo(xe)) - reach) & (xo <= float(hi(xe)) + reach)
                  & (yo >= float(lo(ye)) - reach) & (yo <= float(hi(ye)) + reach))
            if not no.any():
                continue
            j = io[no]
        else:  # few pairs: the exact test below looks at them all
            j = io
        xi, yi, hi_ = x[0, i], y[0, i], heading[0, i]
        xj, yj, hj = x[a, j], y[a, j], heading[a, j]
        dx = xj[None, :] - xi[:, None]
        dy = yj[None, :] - yi[:, None]
        near = dx * dx + dy * dy <= reach * reach
        cross = np.abs(np.sin(hj[None, :] - hi_[:, None])) >= sin_min
        ii, jj = np.nonzero(near & cross)
        if ii.size == 0:
            continue
        sep = _sat_separation(xi[ii], yi[ii], hi_[ii], traj.length[0] / 2, traj.width[0] / 2,
                              xj[jj], yj[jj], hj[jj], traj.length[a] / 2, traj.width[a] / 2)
        hit = sep <= 1e-9
        if not hit.any():
            continue
        ti, tj = t[i[ii[hit]]], t[j[jj[hit]]]
        gap = np.abs(ti - tj)
        b = int(gap.argmin())
        pet[a - 1] = float(gap[b])
        t1[a - 1], t2[a - 1] = float(min(ti[b], tj[b])), float(max(ti[b], tj[b]))
    return out()


class PETMonitor(Monitor):
    invariant = False  # a later sample can lower the PET of an earlier pass

    def __init__(self, min_s: float = 1.0, *, min_angle_deg: float = CROSSING_MIN_ANGLE_DEG,
                 name: str = "post_encroachment_time"):
        self.threshold = check_positive(name, min_s, "min_s", allow_zero=True)
        self.min_angle = check_positive(name, min_angle_deg, "min_angle_deg")
        if not self.min_angle <= 90:
            raise MonitorError(f"{name}: min_angle_deg must be <= 90, got {min_angle_deg!r}")
        self.name = check_name(name)

    def _evaluate(self, traj: Trajectory) -> MonitorResult:
        check_present_finite(traj, self.name, ("x", "y", "heading"))
        pet, t1, t2 = pet_values(traj, self.min_angle)
        if pet.size == 0 or not np.isfinite(pet).any():
            return MonitorResult(self.name, math.inf, self.threshold, None, None,
                                 "no road user's path crosses the ego's")
        a = int(np.argmin(pet))
        who = traj.names[a + 1]
        return MonitorResult(
            self.name, float(pet[a]) - self.threshold, self.threshold, float(t2[a]), who,
            f"post-encroachment time {pet[a]:.3g} s with {who}: the first left the crossing "
            f"at t={t1[a]:.2f} s, the second reached it at t={t2[a]:.2f} s (required >= "
            f"{self.threshold:g} s)")


@factory
def post_encroachment_time(min_s: float = 1.0, *, min_angle_deg: float = CROSSING_MIN_ANGLE_DEG,
                           name: str = "post_encroachment_time") -> Monitor:
    """CriMe's PET at crossings: every road user whose path crosses the ego's (at
    ``min_angle_deg`` or more) reaches the shared ground at least ``min_s`` [s] after the
    other left it (see :func:`pet_values`). rho = min PET - ``min_s`` [s]; the result's
    ``t`` is when the second reached it; +inf when no path crosses."""
    return PETMonitor(min_s, min_angle_deg=min_angle_deg, name=name)

"""The safety metrics: the paper's four (distance, TTC, progress, lane keeping) and the ones
AV teams expect beside them (collision, time headway, off-road, reaching a place).

Each factory validates its arguments (a :class:`MonitorError` at construction, which becomes
a collection error) and returns a :class:`Monitor` whose robustness is computed with numpy
over the whole ``(agents, steps)`` grid at once. The ego is agent 0; "other agents" are all
the rest. A step where an agent is absent (``present`` False) is ignored: it can neither
satisfy nor violate a requirement. Exact definitions: /work/shared/DESIGN.md, "The paper's
definitions".
"""

from __future__ import annotations

import math
import warnings
from typing import Any

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
)

__all__ = [
    "distance", "ttc", "progress", "lane_keeping",
    "collision", "time_headway", "off_road", "reaches",
    "pairwise_distance", "pairwise_ttc", "footprint_gap", "footprint_separation",
    "swept_contacts", "critical_agent", "in_path", "path_distance", "footprint_ttc",
    "DISTANCE_KINDS", "TTC_KINDS", "PATH_MARGIN_M",
]


#: the circle [m] the paper's TTC extrapolates into (DESIGN.md, definition 2): ``ttc()``'s
#: default and the TTC shown when a test declares no TTC monitor
TTC_RADIUS_M = 5.0


#: [m] how far beside the ego's footprint another road user still counts as in its path
#: (:func:`in_path`): a car in the next lane of a 3.5 m road (1.5 m between two 2-m wide
#: cars) is beside it, one drifting to within half a metre of its side is in its way
PATH_MARGIN_M = 0.5
#: what ``distance(kind=...)`` measures; ``"path"`` is the default
DISTANCE_KINDS = ("path", "centre", "footprint")
#: what ``ttc(kind=...)`` measures; ``"path"`` is the default
TTC_KINDS = ("path", "centre")


# -- vectorized kernels (also used by the STL signal builders) --------------------------------

def _pair_mask(traj: Trajectory) -> np.ndarray:
    """``(A-1, T)``: ego and other agent both present."""
    return traj.present[0][None, :] & traj.present[1:]


def pairwise_distance(traj: Trajectory) -> np.ndarray:
    """``(A-1, T)`` centre distance [m] from the ego to each other agent; +inf where either
    is absent (absent agents are infinitely far, so they never decide a minimum)."""
    dx = traj.x[1:] - traj.x[0]
    dy = traj.y[1:] - traj.y[0]
    return np.where(_pair_mask(traj), np.hypot(dx, dy), np.inf)


def pairwise_ttc(traj: Trajectory, radius: float) -> np.ndarray:
    """``(A-1, T)`` time to collision [s] of each other agent with the ego.

    Constant-velocity extrapolation of both: the relative position ``dp + dv t`` reaches the
    circle of ``radius`` [m] at the roots ``t1 <= t2`` of ``|dv|² t² + 2 dp·dv t + |dp|² - r² = 0``.
    Already inside (``|dp| <= r``) gives 0; no real root, or both roots ``<= 0`` (receding),
    gives +inf; otherwise ``t1``. Absent pairs are +inf.
    """
    dpx = traj.x[1:] - traj.x[0]
    dpy = traj.y[1:] - traj.y[0]
    dvx = traj.vx[1:] - traj.vx[0]
    dvy = traj.vy[1:] - traj.vy[0]
    a = dvx * dvx + dvy * dvy
    b = 2.0 * (dpx * dvx + dpy * dvy)
    c = dpx * dpx + dpy * dpy - radius * radius
    disc = b * b - 4.0 * a * c
    # Outside the circle (c > 0) both roots have the sign of -b/a, so a finite TTC needs an
    # approaching pair (b < 0) and a real root (disc >= 0); then t1 = 2c / (-b + sqrt(disc)),
    # the cancellation-free form of (-b - sqrt(disc)) / 2a (it also covers a -> 0).
    approaching = (c > 0) & (b < 0) & (disc >= 0)
    # a vanishing closing speed overflows to TTC = inf, which is the right answer
    with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
        t1 = 2.0 * c / (-b + np.sqrt(np.where(approaching, disc, 0.0)))
    out = np.where(approaching, t1, np.inf)
    out = np.where(c <= 0, 0.0, out)
    # NaN kinematics while present must surface as NaN (an error), not as "no collision".
    bad = np.isnan(c) | np.isnan(b)
    out = np.where(bad, np.nan, out)
    return np.where(_pair_mask(traj), out, np.inf)


def _corners(traj: Trajectory) -> tuple[np.ndarray, np.ndarray]:
    """Footprint corner coordinates [m], x and y each ``(4, A, T)`` (NaN where absent).

    Components are kept apart with the step axis last so every numpy loop runs over steps
    (an ``(..., 2)`` layout spends its time in length-2 inner loops)."""
    c, s = np.cos(traj.heading), np.sin(traj.heading)
    hl = (traj.length / 2)[:, None]
    hw = (traj.width / 2)[:, None]
    sl = np.array([1.0, 1.0, -1.0, -1.0])[:, None, None]  # corners in counter-clockwise order
    sw = np.array([1.0, -1.0, -1.0, 1.0])[:, None, None]
    cx = traj.x + sl * hl * c - sw * hw * s
    cy = traj.y + sl * hl * s + sw * hw * c
    return cx, cy


def footprint_gap(traj: Trajectory) -> np.ndarray:
    """``(A-1, T)`` Euclidean gap [m] between the ego's footprint rectangle and each other
    agent's (0 when they touch or overlap; +inf where either is absent).

    Two disjoint convex polygons are closest at a vertex of one and an edge of the other, so
    the gap is the smallest of the 2 x 4 x 4 vertex-to-edge distances, computed for every
    agent and step at once (the same numbers as ``shapely.distance`` on the polygons, which
    the tests check, at a fraction of the cost)."""
    cx, cy = _corners(traj)
    ex, ey = cx[:, :1], cy[:, :1]                  # ego (4, 1, T), broadcasts over agents
    ox, oy = cx[:, 1:], cy[:, 1:]                  # others (4, A-1, T)
    gap = np.minimum(_vertex_edge_min(ex, ey, ox, oy), _vertex_edge_min(ox, oy, ex, ey))
    overlapping = footprint_separation(traj) <= 0
    return np.where(_pair_mask(traj), np.where(overlapping, 0.0, gap), np.inf)


def _vertex_edge_min(px: np.ndarray, py: np.ndarray, qx: np.ndarray, qy: np.ndarray) -> np.ndarray:
    """Smallest distance [m] from any vertex of polygons p to any edge of polygons q; inputs
    ``(4, ..., T)`` corner coordinates, output ``(..., T)``."""
    ax, ay = qx, qy                                              # edge starts (4, ...)
    exx, eyy = np.roll(qx, -1, axis=0) - ax, np.roll(qy, -1, axis=0) - ay
    ee = exx * exx + eyy * eyy
    inv = np.divide(1.0, ee, out=np.zeros_like(ee), where=ee > 0)  # zero-length edge: a point
    best = None
    # one vertex at a time keeps the temporaries small (a 4 x 4 x agents x steps block costs
    # more in fresh memory pages than in arithmetic); 4 iterations, not a loop over steps
    for i in range(px.shape[0]):
        vx, vy = px[i] - ax, py[i] - ay
        s = np.clip((vx * exx + vy * eyy) * inv, 0.0, 1.0)
        dx, dy = vx - s * exx, vy - s * eyy
        d2 = np.min(dx * dx + dy * dy, axis=0)
        best = d2 if best is None else np.minimum(best, d2)
    return np.sqrt(best)


def footprint_separation(traj: Trajectory) -> np.ndarray:
    """``(A-1, T)`` signed separation [m] of the ego's footprint from each other agent's by
    the separating-axis test: the largest gap of the two rectangles' projections over their
    four edge normals. Positive: apart (a lower bound of the gap, equal to it side by side);
    zero: touching; negative: overlapping, by minus the penetration depth (the shortest
    push that separates them). +inf where either agent is absent."""
    sep = _sat_separation(
        traj.x[0], traj.y[0], traj.heading[0], traj.length[0] / 2, traj.width[0] / 2,
        traj.x[1:], traj.y[1:], traj.heading[1:],
        (traj.length[1:] / 2)[:, None], (traj.width[1:] / 2)[:, None])
    return np.where(_pair_mask(traj), sep, np.inf)


def _sat_axes(x0, y0, h0, l0, w0, xa, ya, ha, la, wa) -> list[tuple[np.ndarray, np.ndarray]]:
    """For the four edge normals of rectangle 0 and rectangles a (centre, heading, half length
    and half width; all broadcast): the signed projection of the centre offset and the sum of
    the two half extents along the normal. The rectangles are apart along a normal by
    ``|projection| - extent``."""
    c0, s0 = np.cos(h0), np.sin(h0)
    ca, sa = np.cos(ha), np.sin(ha)
    dx = xa - x0
    dy = ya - y0
    # |cos| and |sin| of the angle between the two headings give every cross projection
    cr = np.abs(c0 * ca + s0 * sa)
    sr = np.abs(c0 * sa - s0 * ca)
    return [
        # the first rectangle's axes: along (c0, s0) and across (-s0, c0)
        (dx * c0 + dy * s0, l0 + la * cr + wa * sr),
        (-dx * s0 + dy * c0, w0 + la * sr + wa * cr),
        # the other's axes
        (dx * ca + dy * sa, la + l0 * cr + w0 * sr),
        (-dx * sa + dy * ca, wa + l0 * sr + w0 * cr),
    ]


def _sat_separation(*pose_and_size) -> np.ndarray:
    """Separating-axis separation [m] of rectangle 0 from rectangles a (see :func:`_sat_axes`)."""
    (p0, e0), (p1, e1), (p2, e2), (p3, e3) = _sat_axes(*pose_and_size)
    return np.maximum(np.maximum(np.abs(p0) - e0, np.abs(p1) - e1),
                      np.maximum(np.abs(p2) - e2, np.abs(p3) - e3))


def _swept_box_separation(traj: Trajectory, k: int) -> np.ndarray:
    """``(A-1,)`` highway-env's own "will they meet" test of the ego with each other agent over
    the step from sample ``k``, as a separation [m] (<= 0: it predicts a contact; +inf absent).

    Each agent moves on at its recorded velocity; along each of the four edge normals the
    projections must stay apart over the whole step. Unlike the exact test of
    :func:`swept_contacts` it never tries the axis across the relative motion, so it can
    predict a contact for two corners that pass within centimetres on a diagonal."""
    dt = float(traj.t[k + 1] - traj.t[k])
    hl, hw = traj.length / 2, traj.width / 2
    ego = (traj.x[0, k], traj.y[0, k], traj.heading[0, k], hl[0], hw[0])
    start = _sat_axes(*ego, traj.x[1:, k], traj.y[1:, k], traj.heading[1:, k], hl[1:], hw[1:])
    # the others' motion relative to the ego's: shift them by their displacement minus the ego's
    rx = traj.x[1:, k] + (traj.vx[1:, k] - traj.vx[0, k]) * dt
    ry = traj.y[1:, k] + (traj.vy[1:, k] - traj.vy[0, k]) * dt
    end = _sat_axes(*ego, rx, ry, traj.heading[1:, k], hl[1:], hw[1:])
    seps = []
    for (p_start, extent), (p_end, _) in zip(start, end):
        # distance from 0 to the projections swept from start to end
        reach = np.where(p_start * p_end <= 0, 0.0, np.minimum(np.abs(p_start), np.abs(p_end)))
        seps.append(reach - extent)
    out = np.max(seps, axis=0)
    both = traj.present[0, k] & traj.present[1:, k]
    return np.where(both & np.isfinite(out), out, np.inf)


#: [m] resolution of the swept-footprint search: a contact that only grazes, less than half
#: of this deep, may go unseen; contact times are found to within this much relative travel
SWEPT_TOL_M = 1e-3
#: equal sub-steps of a recorded interval among which the deepest moment of a between-steps
#: overlap is sought (then refined)
DEPTH_SUBSTEPS = 32
#: [m] footprints overlapping by less than this are touching: highway-env pushes crashed
#: vehicles exactly into contact, which rounding reads as a 1e-16 m overlap
CONTACT_EPS_M = 1e-9


def swept_contacts(traj: Trajectory, *, extrapolate: bool = False,
                   intervals: np.ndarray | None = None,
                   separation: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """``(A-1, T-1)`` first contact time [s] and depth [m] of the ego's footprint with each
    other agent's while they move between recorded steps ``k`` and ``k+1``; NaN where they
    stay apart (or either agent is absent at either end).

    The motion between two samples is continuous: by default centre and heading are
    interpolated linearly between the two recorded poses (highway-env's own Euler step moves
    a vehicle exactly so); with ``extrapolate`` each agent keeps its recorded velocity and
    heading from step ``k`` for the interval (the test highway-env makes to predict a contact,
    after which it pushes the pair apart). ``intervals`` (``(T-1,)`` bool) limits the search;
    ``separation`` is :func:`footprint_separation` of ``traj`` when the caller has it.

    The search is exact up to :data:`SWEPT_TOL_M`: a point of either footprint moves at most
    ``L = |relative displacement| + R_ego |heading change| + R_other |heading change|`` over an
    interval (R the half diagonals; measured in the frame that follows the other agent's
    centre), so the gap between the footprints changes by at most ``L`` per unit of interval,
    and the separating-axis separation at two instants (a lower bound of the gap) proves the
    stretch between them free when their sum reaches ``L`` times its length. Stretches not
    proved free are halved, all intervals of all agents in one numpy round per halving, until
    a probe overlaps or the stretch is too short to hide a contact deeper than half the
    tolerance. The contact time is the earliest overlapping probe (within ``SWEPT_TOL_M / L``
    of the true first contact); the depth is the largest penetration depth (minus the
    separation) over the interval: the deepest of :data:`DEPTH_SUBSTEPS` equal sub-steps,
    refined by a ternary search around it.
    """
    A1, T = traj.n_agents - 1, traj.n_steps
    t_contact = np.full((max(A1, 0), max(T - 1, 0)), np.nan)
    depth = t_contact.copy()
    if A1 < 1 or T < 2:
        return t_contact, depth
    both = _pair_mask(traj)
    ok = both[:, :-1] & both[:, 1:]
    if intervals is not None:
        ok &= np.asarray(intervals, dtype=bool)[None, :]
    # start and end poses per interval: ego (1, T-1), others (A-1, T-1)
    x0, y0, h0 = traj.x[:, :-1], traj.y[:, :-1], traj.heading[:, :-1]
    if extrapolate:
        dt = np.diff(traj.t)
        x1, y1, h1 = x0 + traj.vx[:, :-1] * dt, y0 + traj.vy[:, :-1] * dt, h0
    else:
        x1, y1, h1 = traj.x[:, 1:], traj.y[:, 1:], traj.heading[:, 1:]
    dx, dy = x1 - x0, y1 - y0
    dh = np.mod(h1 - h0 + np.pi, 2 * np.pi) - np.pi  # the shorter way round
    hl, hw = traj.length / 2, traj.width / 2
    radius = np.hypot(hl, hw)[:, None]
    with np.errstate(invalid="ignore"):
        lip = (np.hypot(dx[1:] - dx[0], dy[1:] - dy[0])
               + radius[0] * np.abs(dh[0]) + radius[1:] * np.abs(dh[1:]))
        sep = footprint_separation(traj) if separation is None else separation
        s_start = sep[:, :-1]
        if extrapolate:
            s_end = _sat_separation(x1[0], y1[0], h1[0], hl[0], hw[0], x1[1:], y1[1:], h1[1:],
                                    hl[1:, None], hw[1:, None])
        else:
            s_end = sep[:, 1:]
        # most intervals are proved free by their two ends alone
        ok &= ~(np.maximum(s_start, 0.0) + np.maximum(s_end, 0.0) >= lip)
    rows, cols = np.nonzero(ok)
    if rows.size == 0:
        return t_contact, depth
    L = lip[rows, cols]
    ego = (x0[0, cols], y0[0, cols], h0[0, cols], dx[0, cols], dy[0, cols], dh[0, cols])
    oth = (x0[1:][rows, cols], y0[1:][rows, cols], h0[1:][rows, cols],
           dx[1:][rows, cols], dy[1:][rows, cols], dh[1:][rows, cols])
    ohl, ohw = hl[1:][rows], hw[1:][rows]

    def sep_at(j: np.ndarray, u: np.ndarray) -> np.ndarray:
        ex, ey, eh, edx, edy, edh = (v[j] for v in ego)
        ox, oy, oh, odx, ody, odh = (v[j] for v in oth)
        return _sat_separation(ex + u * edx, ey + u * edy, eh + u * edh, hl[0], hw[0],
                               ox + u * odx, oy + u * ody, oh + u * odh, ohl[j], ohw[j])

    n = rows.size
    s_a, s_b = s_start[rows, cols], s_end[rows, cols]
    first = np.full(n, np.inf)  # earliest overlapping probe (fraction of the interval)
    first[s_b < -CONTACT_EPS_M] = 1.0
    first[s_a < -CONTACT_EPS_M] = 0.0
    j = np.arange(n)
    a, b = np.zeros(n), np.ones(n)
    for _ in range(64):  # halvings; L / 2**64 is far below any tolerance
        span = L[j] * (b - a)
        # a separation is a lower bound of the gap only where it is positive
        proved = np.maximum(s_a, 0.0) + np.maximum(s_b, 0.0) >= span
        live = (a < first[j]) & (span >= SWEPT_TOL_M) & ~proved
        if not live.any():
            break
        j, a, b, s_a, s_b = j[live], a[live], b[live], s_a[live], s_b[live]
        m = (a + b) / 2
        s_m = sep_at(j, m)
        hit = s_m < -CONTACT_EPS_M
        np.minimum.at(first, j[hit], m[hit])
        j, a, b = np.concatenate([j, j]), np.concatenate([a, m]), np.concatenate([m, b])
        s_a, s_b = np.concatenate([s_a, s_m]), np.concatenate([s_m, s_b])
    found = np.flatnonzero(np.isfinite(first))
    if found.size == 0:
        return t_contact, depth
    # the deepest moment: the best of a grid, then a ternary search around it (the overlap
    # deepens and recedes once while the footprints pass through each other)
    grid = np.linspace(0.0, 1.0, DEPTH_SUBSTEPS + 1)
    on_grid = sep_at(np.repeat(found, grid.size), np.tile(grid, found.size)).reshape(-1, grid.size)
    best = grid[np.argmin(on_grid, axis=1)]
    lo = np.maximum(best - 1.0 / DEPTH_SUBSTEPS, 0.0)
    hi = np.minimum(best + 1.0 / DEPTH_SUBSTEPS, 1.0)
    for _ in range(40):
        m1, m2 = lo + (hi - lo) / 3, hi - (hi - lo) / 3
        left = sep_at(found, m1) < sep_at(found, m2)
        hi, lo = np.where(left, m2, hi), np.where(left, lo, m1)
    deepest = np.minimum.reduce([on_grid.min(axis=1), sep_at(found, (lo + hi) / 2),
                                 sep_at(found, first[found])])
    r, c = rows[found], cols[found]
    t_contact[r, c] = traj.t[c] + first[found] * (traj.t[c + 1] - traj.t[c])
    depth[r, c] = -deepest
    return t_contact, depth


def _travel_sign(traj: Trajectory) -> np.ndarray:
    """``(T,)`` +1 where the ego drives forward (or stands), -1 where it reverses."""
    h = traj.heading[0]
    vlon = traj.vx[0] * np.cos(h) + traj.vy[0] * np.sin(h)
    return np.where(vlon < -0.1, -1.0, 1.0)


def in_path(traj: Trajectory, margin: float = PATH_MARGIN_M) -> np.ndarray:
    """``(A-1, T)`` whether each other agent is in the ego's path at each step.

    In the ego's frame (its heading; backwards while it reverses), the other agent's
    footprint must reach ahead of the ego's centre and come within ``margin`` [m] of the
    strip the ego's footprint sweeps when it drives straight on: ``|lateral offset| <
    ego half width + the other's half extent across the ego's heading + margin``. A car in
    the next lane (centres 3.5 m or more apart across, two 2-m wide cars) is not in the path;
    one ahead in the ego's lane, one cutting into it, or a pedestrian crossing in front of it
    is. Absent pairs are False. Needs x, y, heading, vx, vy."""
    h = traj.heading[0][None, :]
    c, s = np.cos(h), np.sin(h)
    dx = traj.x[1:] - traj.x[0]
    dy = traj.y[1:] - traj.y[0]
    lon = (dx * c + dy * s) * _travel_sign(traj)[None, :]
    lat = -dx * s + dy * c
    rel = traj.heading[1:] - h
    cr, sr = np.abs(np.cos(rel)), np.abs(np.sin(rel))
    hl, hw = (traj.length[1:] / 2)[:, None], (traj.width[1:] / 2)[:, None]
    across = hl * sr + hw * cr      # the other's half extent across the ego's heading
    along = hl * cr + hw * sr       # ... and along it
    beside = np.abs(lat) < traj.width[0] / 2 + across + margin
    ahead = lon + along > 0
    return beside & ahead & _pair_mask(traj)


def path_distance(traj: Trajectory, margin: float = PATH_MARGIN_M) -> np.ndarray:
    """``(A-1, T)`` centre distance [m] from the ego to each other agent while it is in the
    ego's path (:func:`in_path`), +inf otherwise: the paper's distance, restricted to the road
    users the ego could drive into."""
    return np.where(in_path(traj, margin), pairwise_distance(traj), np.inf)


def footprint_ttc(traj: Trajectory) -> np.ndarray:
    """``(A-1, T)`` time [s] until the ego's footprint and each other agent's in its path
    meet, both moving on at their current velocities with their current headings; +inf when
    they never meet (parallel in neighbouring lanes, receding, or a path that misses), 0 when
    they overlap already, +inf where either is absent or the agent is behind the ego.

    Exact for two rectangles in uniform motion: along each of the four edge normals the
    projected gap closes at the projected relative speed, giving the interval of times in
    which the projections overlap; the footprints meet at the latest entry, when it comes
    before the earliest exit. For two cars in line it is the paper's TTC with a circle of one
    car length (bumper to bumper); unlike the paper's circle it ignores a car passing in the
    next lane and counts a car whose lateral motion carries it into the ego's path."""
    hl, hw = traj.length / 2, traj.width / 2
    pose0 = (traj.heading[0], hl[0], hw[0])
    hla, hwa = hl[1:, None], hw[1:, None]
    at = _sat_axes(traj.x[0], traj.y[0], *pose0, traj.x[1:], traj.y[1:], traj.heading[1:], hla, hwa)
    # the same projections of the relative velocity (the other's minus the ego's)
    rate = _sat_axes(0.0, 0.0, *pose0, traj.vx[1:] - traj.vx[0], traj.vy[1:] - traj.vy[0],
                     traj.heading[1:], hla, hwa)
    enter = np.full(at[0][0].shape, -np.inf)
    leave = np.full(at[0][0].shape, np.inf)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        for (p, e), (v, _) in zip(at, rate):
            still = np.abs(v) < 1e-12
            t1, t2 = (-e - p) / v, (e - p) / v
            lo = np.where(still, np.where(np.abs(p) < e, -np.inf, np.inf), np.minimum(t1, t2))
            hi = np.where(still, np.where(np.abs(p) < e, np.inf, -np.inf), np.maximum(t1, t2))
            enter, leave = np.maximum(enter, lo), np.minimum(leave, hi)
    meet = (enter < leave) & (leave > 0)
    out = np.where(meet, np.maximum(enter, 0.0), np.inf)
    bad = np.isnan(at[0][0]) | np.isnan(rate[0][0])
    out = np.where(bad, np.nan, out)
    ahead = in_path(traj, math.inf)  # ahead of the ego's centre; beside-ness is the motion's
    return np.where(_pair_mask(traj) & (ahead | bad), out, np.inf)


def _argmin_2d(values: np.ndarray) -> tuple[int, int]:
    """(agent row, step) of the smallest value, earliest step first on ties."""
    flat = int(np.argmin(values.T))
    step, row = divmod(flat, values.shape[0])
    return row, step


def critical_agent(traj: Trajectory, agent: str | None, t: float | None = None) -> int | None:
    """Index of the critical agent: ``agent`` when it is another road user of ``traj``,
    else the one nearest the ego at ``t`` (or over the run); None when the ego is alone."""
    if traj.n_agents < 2:
        return None
    if agent is not None and agent in traj.names[1:]:
        return traj.names.index(agent)
    d = pairwise_distance(traj)
    k = int(np.argmin(np.abs(traj.t - t))) if t is not None else None
    col = d[:, k] if k is not None else d.min(axis=1)
    if not np.isfinite(col).any():
        col = d.min(axis=1)
    return 1 + int(np.argmin(col))


# -- the paper's four --------------------------------------------------------------------------

class _PairwiseMin(Monitor):
    """rho = min over steps and other agents of (value - threshold)."""

    _what = ""
    _unit = ""

    invariant = True  # must hold at every step (first_violation bisects prefixes)

    def _values(self, traj: Trajectory) -> np.ndarray:
        raise NotImplementedError

    def _fields(self) -> tuple[str, ...]:
        return ("x", "y")

    def series(self, traj: Trajectory) -> np.ndarray:
        """(value - threshold) toward the nearest other agent at each step: ρ(t); +inf at a
        step with no other agent, NaN where no value is defined (absent agents)."""
        vals = self._values(traj)
        if vals.shape[0] == 0:
            return np.full(traj.n_steps, np.inf)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)  # an all-NaN step stays NaN
            return np.nanmin(vals, axis=0) - self.threshold

    def _evaluate(self, traj: Trajectory) -> MonitorResult:
        check_present_finite(traj, self.name, self._fields())
        vals = self._values(traj)
        if vals.size == 0 or np.all(vals == np.inf):
            who = "no other agent" if traj.n_agents == 1 else "no agent came near"
            return MonitorResult(self.name, math.inf, self.threshold, None, None,
                                 f"{who}: {self._what} infinite")
        row, step = _argmin_2d(vals)
        v = float(vals[row, step])
        who = traj.names[row + 1]
        return MonitorResult(
            self.name, v - self.threshold, self.threshold, fmt_t(traj, step), who,
            f"min {self._what} {v:.3g} {self._unit} to {who} at t={traj.t[step]:.2f} s "
            f"(required >= {self.threshold:g} {self._unit})",
        )


class DistanceMonitor(_PairwiseMin):
    """Always ``distance(ego, other) >= threshold`` [m] for every other agent (in the ego's
    path for ``kind="path"``)."""

    _unit = "m"
    _WHAT = {"path": "centre distance in the ego's path", "centre": "centre distance",
             "footprint": "footprint gap"}

    def __init__(self, threshold: float = 5.0, *, kind: str = "path", name: str = "distance"):
        self.threshold = check_threshold(name, threshold)
        self.kind = _check_kind(name, kind, DISTANCE_KINDS)
        self.name = check_name(name)
        self._what = self._WHAT[self.kind]

    @property
    def footprint(self) -> bool:
        return self.kind == "footprint"

    def _fields(self) -> tuple[str, ...]:
        return {"path": ("x", "y", "heading", "vx", "vy"), "centre": ("x", "y"),
                "footprint": ("x", "y", "heading")}[self.kind]

    def _values(self, traj: Trajectory) -> np.ndarray:
        if self.kind == "footprint":
            return footprint_gap(traj)
        return pairwise_distance(traj) if self.kind == "centre" else path_distance(traj)


class TTCMonitor(_PairwiseMin):
    """Always ``TTC(ego, other) >= threshold`` [s] for every other agent (footprints meeting
    in the ego's path for ``kind="path"``, the paper's circle for ``kind="centre"``)."""

    _unit = "s"

    def __init__(self, threshold: float = 2.0, *, kind: str = "path", radius: float | None = None,
                 name: str = "ttc"):
        self.threshold = check_threshold(name, threshold)
        self.kind = _check_kind(name, kind, TTC_KINDS)
        self.name = check_name(name)
        if self.kind == "path" and radius is not None:
            raise MonitorError(
                f"{name}: radius applies to the paper's circle, ttc(kind='centre', radius="
                f"{radius!r}); the default kind='path' extrapolates the vehicles' footprints")
        #: the circle [m] of kind="centre"; None for kind="path"
        self.radius = (check_positive(name, TTC_RADIUS_M if radius is None else radius, "radius")
                       if self.kind == "centre" else None)
        self._what = "TTC (footprints, in the ego's path)" if self.kind == "path" else "TTC"

    def _fields(self) -> tuple[str, ...]:
        return ("x", "y", "vx", "vy", "heading") if self.kind == "path" else ("x", "y", "vx", "vy")

    def _values(self, traj: Trajectory) -> np.ndarray:
        return footprint_ttc(traj) if self.kind == "path" else pairwise_ttc(traj, self.radius)


def _check_kind(name: str, kind: Any, kinds: tuple[str, ...]) -> str:
    if kind not in kinds:
        raise MonitorError(f"{name}: kind must be one of {', '.join(repr(k) for k in kinds)}, "
                           f"got {kind!r}")
    return kind


@factory
def distance(threshold: float = 5.0, *, kind: str = "path", footprint: bool = False,
             name: str = "distance") -> Monitor:
    """Keep ``threshold`` [m] from other road users: rho = min over steps and agents of
    (value - ``threshold``) [m]; +inf when no agent counts. ``kind``:

    * ``"path"`` (default) — the centre distance to agents in the ego's path
      (:func:`in_path`: ahead of it and within half a metre of the strip it drives along);
      a car passing in the next lane does not count, one ahead in the lane or cutting in does;
    * ``"centre"`` — the paper's distance metric: the centre distance to every other agent,
      whatever lane it is in (use it to reproduce the paper's table);
    * ``"footprint"`` — the gap between the vehicles' rectangles (0 when they overlap), to
      every other agent; ``footprint=True`` is the same."""
    if footprint:
        if kind not in ("path", "footprint"):
            raise MonitorError(f"{name}: footprint=True and kind={kind!r} contradict each other; "
                               "write kind='footprint'")
        kind = "footprint"
    return DistanceMonitor(threshold, kind=kind, name=name)


@factory
def ttc(threshold: float = 2.0, *, kind: str = "path", radius: float | None = None,
        name: str = "ttc") -> Monitor:
    """Keep a time to collision of ``threshold`` [s]: rho = min over steps and agents of
    (TTC - ``threshold``) [s]; +inf when no agent is on a collision course. ``kind``:

    * ``"path"`` (default) — the time until the ego's footprint and another road user's meet
      when both move on at constant velocity (:func:`footprint_ttc`), for agents ahead of
      the ego: infinite for a car passing in the next lane (never on a collision course),
      the bumper-to-bumper TTC for a car ahead in the lane, finite for one cutting in;
    * ``"centre"`` — the paper's TTC: constant-velocity extrapolation of the centres reaching
      a circle of ``radius`` [m] (default 5 m; see :func:`pairwise_ttc`), any agent; a car
      in the next lane closer than the radius gives TTC 0. Use it to reproduce the paper's
      table."""
    return TTCMonitor(threshold, kind=kind, radius=radius, name=name)


class ProgressMonitor(Monitor):
    def __init__(self, threshold: float = 11.0, *, name: str = "progress"):
        self.threshold = check_threshold(name, threshold)
        self.name = check_name(name)

    def _evaluate(self, traj: Trajectory) -> MonitorResult:
        present = np.flatnonzero(traj.present[0])
        if present.size == 0:
            raise MonitorError(f"monitor {self.name!r}: the ego is never present")
        check_present_finite(traj, self.name, ("x", "y"), [0])
        first, last = present[0], present[-1]
        d = float(np.hypot(traj.x[0, last] - traj.x[0, first], traj.y[0, last] - traj.y[0, first]))
        return MonitorResult(
            self.name, d - self.threshold, self.threshold, fmt_t(traj, last), traj.names[0],
            f"ego moved {d:.3g} m from t={traj.t[first]:.2f} s to t={traj.t[last]:.2f} s "
            f"(required >= {self.threshold:g} m)",
        )


@factory
def progress(threshold: float = 11.0, *, name: str = "progress") -> Monitor:
    """The paper's progress metric: rho = ||X_1 - X_N|| - ``threshold`` [m], X the ego's
    centre at its first and last present step (straight-line displacement, not path
    length)."""
    return ProgressMonitor(threshold, name=name)


class LaneKeepingMonitor(Monitor):
    invariant = False  # a mean over the run: its first violation is not a prefix's
    def __init__(self, threshold: float = 0.5, *, name: str = "lane_keeping"):
        self.threshold = check_threshold(name, threshold)
        self.name = check_name(name)

    def _evaluate(self, traj: Trajectory) -> MonitorResult:
        present = traj.present[0]
        off = traj.lane_offset[0]
        known = np.isfinite(off)
        # A present step with a lane id but no offset is a broken recording; a step without
        # any lane (off the map) has no centre line to measure from and is left to off_road().
        broken = present & ~known & (traj.lane[0] != "")
        if broken.any():
            k = int(np.flatnonzero(broken)[0])
            raise MonitorError(
                f"monitor {self.name!r}: ego lane_offset is {off[k]} at t={traj.t[k]:.3f} s "
                f"on lane {traj.lane[0, k]!r}"
            )
        use = present & known
        if not use.any():
            raise MonitorError(
                f"monitor {self.name!r}: the trajectory has no lane offset for the ego at any "
                "step; record lane/lane_offset (Trajectory.from_arrays(..., lane_offset=...))"
            )
        absoff = np.abs(np.where(use, off, 0.0))
        mean = float(absoff.sum() / use.sum())
        k = int(np.argmax(absoff))
        return MonitorResult(
            self.name, self.threshold - mean, self.threshold, fmt_t(traj, k), traj.names[0],
            f"mean |lane offset| {mean:.3g} m over {int(use.sum())} steps, max "
            f"{absoff[k]:.3g} m at t={traj.t[k]:.2f} s (required <= {self.threshold:g} m)",
        )


@factory
def lane_keeping(threshold: float = 0.5, *, name: str = "lane_keeping") -> Monitor:
    """The paper's lane-keeping metric: rho = ``threshold`` - mean over steps of the ego's
    distance [m] to the centre line of its current lane (``|lane_offset|``). Steps where the
    ego is absent, or on no lane at all, are left out of the mean."""
    return LaneKeepingMonitor(threshold, name=name)


# -- the ones AV teams expect beside them ----------------------------------------------------

class CollisionMonitor(Monitor):
    threshold = 0.0
    #: robustness [m] charged for a recorded crash flag without an overlap to measure: one the
    #: simulator's coarser test predicted, or with something not in the trajectory
    FLAG_RHO = -0.01
    CONTACT_EPS = CONTACT_EPS_M

    invariant = True  # must hold at every step (first_violation bisects prefixes)

    def __init__(self, *, use_crash_flag: bool = True, name: str = "collision"):
        self.use_crash_flag = bool(use_crash_flag)
        self.name = check_name(name)

    def _evaluate(self, traj: Trajectory) -> MonitorResult:
        check_present_finite(traj, self.name, ("x", "y", "heading"))
        sep = footprint_separation(traj)
        sep = np.where(np.abs(sep) < self.CONTACT_EPS, 0.0, sep)
        if not (sep.size and np.isfinite(sep).any()):
            res = MonitorResult(self.name, math.inf, 0.0, None, None, "no other agent present")
        else:
            row, step = _argmin_2d(sep)
            v = float(sep[row, step])
            who = traj.names[row + 1]
            if v < 0:
                return MonitorResult(self.name, v, 0.0, fmt_t(traj, step), who,
                                     f"overlap {-v:.3g} m deep with {who} at t={traj.t[step]:.2f} s"
                                     + self._earlier_flag(traj, sep))
            res = MonitorResult(self.name, v, 0.0, fmt_t(traj, step), who,
                                f"min footprint separation {v:.3g} m to {who} at t={traj.t[step]:.2f} s")
        found = [self._between_steps(traj, swept_contacts(traj, separation=sep), "interpolated")]
        flagged = traj.crashed[0] & traj.present[0] if self.use_crash_flag else np.zeros(0, bool)
        k = int(np.argmax(flagged)) if flagged.any() else None
        if k:  # an onset after the first sample has a step before it to explain it
            # highway-env tests each step whether the footprints, moving on at their velocities,
            # would meet within the next step; if so it pushes them apart and flags both as
            # crashed, so no recorded step need show the overlap
            only = np.arange(traj.n_steps - 1) == k - 1
            found.append(self._between_steps(
                traj, swept_contacts(traj, extrapolate=True, intervals=only, separation=sep),
                "extrapolated", flag_t=float(traj.t[k])))
        found = [r for r in found if r is not None]
        if found:
            return min(found, key=lambda r: r.rho)
        if k is None:
            return res
        if k:
            box = _swept_box_separation(traj, k - 1)
            if np.any(box <= self.CONTACT_EPS):
                row = int(np.argmin(box))
                who = traj.names[row + 1]
                return MonitorResult(
                    self.name, self.FLAG_RHO, 0.0, fmt_t(traj, k), who,
                    f"simulator reports an ego crash with {who} at t={traj.t[k]:.2f} s: its "
                    f"swept-box test from t={traj.t[k - 1]:.2f} s predicted a contact, though the "
                    "footprints moving at their recorded velocities pass without overlapping "
                    "(the test does not try the axis across their relative motion)")
        return MonitorResult(self.name, self.FLAG_RHO, 0.0, fmt_t(traj, k), None,
                             f"simulator reports an ego crash at t={traj.t[k]:.2f} s, but no "
                             "recorded agent's footprint meets the ego's, at the recorded steps "
                             "or swept between them (a static object or an unrecorded vehicle)")

    def _earlier_flag(self, traj: Trajectory, sep: np.ndarray) -> str:
        """A note when the simulator flagged the ego's crash before any recorded step overlaps
        (the overlaps that follow are what is left after highway-env pushed the pair apart)."""
        flagged = traj.crashed[0] & traj.present[0]
        if not (self.use_crash_flag and flagged.any()):
            return ""
        k, first = int(np.argmax(flagged)), int(np.argmax((sep < 0).any(axis=0)))
        if k >= first:
            return ""
        return (f"; the simulator flagged the ego's crash earlier, at t={traj.t[k]:.2f} s "
                "(first_violation names that contact)")

    def _between_steps(self, traj: Trajectory, contact: tuple[np.ndarray, np.ndarray],
                       motion: str, flag_t: float | None = None) -> MonitorResult | None:
        """The deepest contact of :func:`swept_contacts` as a result, or None."""
        t_contact, depth = contact
        depth = np.where(depth > self.CONTACT_EPS, depth, np.nan)
        if not np.isfinite(depth).any():
            return None
        row, k = np.unravel_index(np.nanargmax(depth), depth.shape)
        d, who = float(depth[row, k]), traj.names[row + 1]
        # rho is the deepest overlap; the moment named is that agent's first contact (an
        # earlier interval may overlap about as deeply: two passes through each other)
        k = int(np.flatnonzero(np.isfinite(depth[row]))[0])
        tc = float(t_contact[row, k])
        span = f"between the recorded steps t={traj.t[k]:.2f} and {traj.t[k + 1]:.2f} s"
        if motion == "interpolated":
            detail = (f"footprints overlap {span}: {who} meets the ego at t={tc:.3f} s "
                      f"(poses interpolated linearly), {d:.3g} m deep")
        else:
            detail = (f"simulator reports an ego crash at t={flag_t:.2f} s: {who} meets the ego "
                      f"at t={tc:.3f} s, {span}, moving at their recorded velocities (the "
                      f"simulator's own test; it then pushed them apart), {d:.3g} m deep")
        return MonitorResult(self.name, -d, 0.0, tc, who, detail)


@factory
def collision(*, use_crash_flag: bool = True, name: str = "collision") -> Monitor:
    """No footprint overlap between the ego and any other agent, ever — at the recorded steps
    and between them.

    rho [m]: when the footprints overlap at a recorded step, minus the deepest penetration
    depth (separating-axis) over the steps, as it always was. Otherwise, when they overlap
    between two recorded steps with centres and headings interpolated linearly (a fast or
    oblique pass that the samples straddle; see :func:`swept_contacts`), minus the deepest
    penetration depth of the interpolated footprints; the result's ``t`` is then the moment
    [s] that agent first meets the ego, between the steps, and ``agent`` the one met.
    Otherwise the smallest separation at the recorded steps (positive: how far apart they
    stayed). Overlaps shallower than 1e-9 m count as touching.

    With ``use_crash_flag`` a crash the simulator recorded for the ego also fails when no
    footprint overlap shows it. highway-env predicts each step whether two vehicles moving
    on at their velocities meet within the next step, then pushes them apart and flags both,
    so a side swipe at dt = 0.2 s is often recorded as a flag and two footprints centimetres
    apart. The agent whose footprint, moving on from the step before the flag at its recorded
    velocity and heading, meets the ego's within that step is named, with the contact time
    and rho = minus the depth that swept overlap reaches. Failing that, an agent that
    highway-env's coarser swept-box test (edge normals only) finds is named with rho = -0.01
    m; when nothing explains the flag (a static object or an unrecorded vehicle), rho =
    -0.01 m and no agent."""
    return CollisionMonitor(use_crash_flag=use_crash_flag, name=name)


class TimeHeadwayMonitor(Monitor):
    invariant = True  # must hold at every step (first_violation bisects prefixes)

    def __init__(self, seconds: float = 1.0, *, min_speed: float = 0.1, name: str = "time_headway"):
        self.threshold = check_positive(name, seconds, "seconds", allow_zero=True)
        self.min_speed = check_positive(name, min_speed, "min_speed")
        self.name = check_name(name)

    def _evaluate(self, traj: Trajectory) -> MonitorResult:
        check_present_finite(traj, self.name, ("x", "y", "heading", "speed"))
        thw = headway(traj, self.min_speed)
        if thw.size == 0 or not np.isfinite(thw).any():
            return MonitorResult(self.name, math.inf, self.threshold, None, None,
                                 "no vehicle ahead in the ego's lane")
        row, step = _argmin_2d(thw)
        v = float(thw[row, step])
        who = traj.names[row + 1]
        return MonitorResult(
            self.name, v - self.threshold, self.threshold, fmt_t(traj, step), who,
            f"min time headway {v:.3g} s behind {who} at t={traj.t[step]:.2f} s "
            f"(required >= {self.threshold:g} s)",
        )


def headway(traj: Trajectory, min_speed: float = 0.1) -> np.ndarray:
    """``(A-1, T)`` time headway [s] of the ego behind each other agent: bumper-to-bumper gap
    along the ego's heading divided by the ego's speed. Only agents ahead and in the ego's
    lane count (same lane id when both are known, else overlapping lateral corridors); others
    and absent ones are +inf. A gap <= 0 gives 0; an ego slower than ``min_speed`` [m/s] has
    infinite headway."""
    h = traj.heading[0]
    dx = traj.x[1:] - traj.x[0]
    dy = traj.y[1:] - traj.y[0]
    lon = dx * np.cos(h) + dy * np.sin(h)
    lat = -dx * np.sin(h) + dy * np.cos(h)
    lanes_known = (traj.lane[0] != "")[None, :] & (traj.lane[1:] != "")
    same_lane = traj.lane[1:] == traj.lane[0][None, :]
    corridor = np.abs(lat) < (traj.width[0] + traj.width[1:, None]) / 2
    ahead = (lon > 0) & np.where(lanes_known, same_lane, corridor) & _pair_mask(traj)
    gap = lon - (traj.length[0] + traj.length[1:, None]) / 2
    speed = traj.speed[0][None, :]
    with np.errstate(divide="ignore", invalid="ignore"):
        thw = np.where(speed > min_speed, gap / speed, np.inf)
    thw = np.where(gap <= 0, 0.0, thw)
    return np.where(ahead, thw, np.inf)


@factory
def time_headway(seconds: float = 1.0, *, min_speed: float = 0.1,
                 name: str = "time_headway") -> Monitor:
    """Always keep ``seconds`` [s] of time headway to the vehicle ahead in the ego's lane:
    rho = min over steps of (headway - ``seconds``) [s] (see :func:`headway`); +inf when
    nothing is ever ahead."""
    return TimeHeadwayMonitor(seconds, min_speed=min_speed, name=name)


class OffRoadMonitor(Monitor):
    threshold = 0.0

    invariant = True  # must hold at every step (first_violation bisects prefixes)

    def __init__(self, *, name: str = "off_road"):
        self.name = check_name(name)

    def _evaluate(self, traj: Trajectory) -> MonitorResult:
        off = traj.present[0] & ~traj.on_road[0]
        if not off.any():
            return MonitorResult(self.name, 0.0, 0.0, None, traj.names[0], "ego always on the road")
        k = int(np.argmax(off))
        n = int(off.sum())
        dt = traj.dt
        dur = n * dt if dt > 0 else float(n)
        unit = "s" if dt > 0 else "steps"
        return MonitorResult(self.name, -dur, 0.0, fmt_t(traj, k), traj.names[0],
                             f"ego off the road for {dur:.3g} {unit}, first at t={traj.t[k]:.2f} s")


@factory
def off_road(*, name: str = "off_road") -> Monitor:
    """The ego's centre stays on some lane (the recorded ``on_road`` flag) at every step.
    rho = 0 when it holds, else minus the time spent off the road [s] (steps × dt)."""
    return OffRoadMonitor(name=name)


class ReachesMonitor(Monitor):
    threshold = 0.0

    def __init__(self, place: Any, radius: float | None = None, *, name: str = "reaches"):
        self.name = check_name(name)
        self.place, self.radius, self._desc = _parse_place(name, place, radius)

    def _evaluate(self, traj: Trajectory) -> MonitorResult:
        check_present_finite(traj, self.name, ("x", "y"), [0])
        present = traj.present[0]
        d = signed_distance_to(self.place, traj.x[0], traj.y[0])
        margin = np.where(present, self.radius - d, -np.inf)
        if not present.any():
            raise MonitorError(f"monitor {self.name!r}: the ego is never present")
        k = int(np.argmax(margin))
        v = float(margin[k])
        where = (f"{-d[k]:.3g} m inside {self._desc}" if d[k] < 0
                 else f"{d[k]:.3g} m from {self._desc}")
        radius = f" (radius {self.radius:g} m)" if self.radius else ""
        return MonitorResult(self.name, v, 0.0, fmt_t(traj, k), traj.names[0],
                             f"ego's best approach: {where}{radius} at t={traj.t[k]:.2f} s")


def _parse_place(name: str, place: Any, radius: float | None) -> tuple[Any, float, str]:
    try:
        import shapely
        is_geom = isinstance(place, shapely.Geometry)
    except ImportError:  # pragma: no cover - shapely is a dependency
        is_geom = False
    if is_geom:
        if place.is_empty:
            raise MonitorError(f"{name}: the place geometry is empty")
        r = 0.0 if radius is None else check_positive(name, radius, "radius", allow_zero=True)
        return place, r, f"{place.geom_type} place"
    try:
        xy = np.asarray(place, dtype=float)
    except (TypeError, ValueError):
        xy = None
    if xy is None or xy.shape != (2,) or not np.isfinite(xy).all():
        raise MonitorError(
            f"{name}: place must be an (x, y) point [m] with a radius, or a shapely geometry; "
            f"got {place!r:.80}"
        )
    if radius is None:
        raise MonitorError(f"{name}: a point place needs a radius [m], e.g. reaches((x, y), radius=3.0)")
    r = check_positive(name, radius, "radius")
    return (float(xy[0]), float(xy[1])), r, f"({xy[0]:g}, {xy[1]:g})"


def signed_distance_to(place: Any, x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Distance [m] from each point to ``place`` (a point tuple or shapely geometry), negative
    inside a polygon by the distance to its boundary. NaN where x/y are NaN."""
    if isinstance(place, tuple):
        return np.hypot(x - place[0], y - place[1])
    import shapely

    ok = np.isfinite(x) & np.isfinite(y)
    xs, ys = np.where(ok, x, 0.0), np.where(ok, y, 0.0)
    pts = shapely.points(xs, ys)
    d = shapely.distance(place, pts)
    if place.area > 0:
        inside = shapely.contains_xy(place, xs, ys)
        d = np.where(inside, -shapely.distance(place.boundary, pts), d)
    return np.where(ok, d, np.nan)


@factory
def reaches(place: Any, radius: float | None = None, *, name: str = "reaches") -> Monitor:
    """Eventually the ego's centre reaches ``place``: an ``(x, y)`` point [m] with a
    ``radius`` [m], or a shapely geometry (optionally grown by ``radius``). rho = max over
    steps of (radius - signed distance to the place) [m]: positive by how deep the ego got,
    negative by how far its closest approach stayed."""
    return ReachesMonitor(place, radius, name=name)

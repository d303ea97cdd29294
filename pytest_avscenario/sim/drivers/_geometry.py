"""Geometry the built-in autopilot plans on: the route as one resampled centre line.

The simulator hands the autopilot its route as a tuple of highway-env lane objects. Calling
``lane.position`` per query costs microseconds each, far too much inside a 50-µs control
step, so :class:`RoutePath` samples the whole route once, at a uniform arc-length spacing,
into flat numpy arrays (and Python lists for scalar look-ups). Every per-step question the
autopilot asks — where is the point L metres ahead, which route point is nearest to these
agents, how curved is the road ahead — is then an index computation or one small vectorized
numpy expression. Also here: the two-arc parallel-parking path (pure geometry, no state).
"""

from __future__ import annotations

import math
from typing import Any, Sequence

import numpy as np

from ..geometry import poses_hit_boxes

__all__ = ["RoutePath", "bicycle_steering", "parking_moves", "parking_path", "pursuit_steering"]

_ARC_SAMPLE_M = 1.0  # [m] sampling step for curved lanes before resampling (chord error ds²/8R)


def bicycle_steering(curvature: float, length: float, max_steering: float) -> float:
    """Front-wheel angle [rad] making highway-env's bicycle model drive a given curvature.

    highway-env moves the vehicle *centre* along heading + beta with beta =
    arctan(tan(delta)/2) and turns the heading at v sin(beta) / (length/2), so the centre's
    path curvature is 2 sin(beta) / length [1/m]. Inverted here and clipped to
    ``max_steering`` [rad].
    """
    sin_beta = max(-0.999, min(0.999, 0.5 * curvature * length))
    beta = math.asin(sin_beta)
    delta = math.atan(2.0 * math.tan(beta))
    return max(-max_steering, min(max_steering, delta))


def pursuit_steering(dx: float, dy: float, heading: float, length: float,
                     max_steering: float) -> float:
    """Pure-pursuit front-wheel angle [rad] toward a target (dx, dy) [m] from the centre.

    highway-env's centre moves along heading + beta, and beta is set by *this* command, so
    the arc to the target must be tangent to heading + beta rather than to the heading: with
    A the target's bearing from the heading and k = length / distance, sin(beta) =
    k sin(A - beta), i.e. tan(beta) = k sin(A) / (1 + k cos(A)). (Using the previous step's
    beta instead closes a loop of gain ~k through beta that oscillates at every step when the
    look-ahead is shorter than the car.)
    """
    dist = math.hypot(dx, dy)
    if dist < 1e-6:
        return 0.0
    k = length / dist
    a = math.atan2(dy, dx) - heading
    den = 1.0 + k * math.cos(a)
    if den <= 1e-6:  # target behind: turn toward it as hard as allowed
        return max_steering if math.sin(a) >= 0 else -max_steering
    tan_beta = k * math.sin(a) / den
    delta = math.atan(2.0 * tan_beta)
    return max(-max_steering, min(max_steering, delta))


def _is_straight(lane: Any) -> bool:
    # Duck-typed so highway-env stays out of this module's imports: highway-env's
    # StraightLane and its subclasses expose start/end/direction; SineLane, a subclass that
    # wiggles, adds an amplitude.
    return (hasattr(lane, "start") and hasattr(lane, "end") and hasattr(lane, "direction")
            and not hasattr(lane, "amplitude"))


class RoutePath:
    """The route's centre line resampled every ``ds`` metres, extended straight at both ends.

    Arc length ``S`` [m] is counted from the start of ``route[0]``; lane ``k`` of the route
    starts at ``offsets[k]``, so a point at longitudinal ``s`` on lane ``k`` sits at
    ``offsets[k] + s``. Arrays (all of one length): ``S``, ``x``, ``y`` [m], unit tangent
    ``tx``, ``ty``, and ``curvature`` [1/m] (signed, left positive).
    """

    def __init__(self, route: Sequence[Any], ds: float = 1.0, extension: float = 150.0,
                 start: tuple[int, float] = (0, 0.0), change_length: float = 25.0):
        """``start`` = (route index, s [m]) where the ego is when the path is built: a lane
        change the route asks for (a lane followed by a parallel neighbour rather than by
        its successor) begins 2 m ahead of it and blends over ``change_length`` metres."""
        if not route:
            raise ValueError("the autopilot needs a route with at least one lane")
        self.ds = float(ds)
        knots_s: list[np.ndarray] = []
        knots_xy: list[np.ndarray] = []
        offsets: list[float] = []
        acc = 0.0
        s_from = 0.0  # where on the current lane the path enters it
        for k, lane in enumerate(route):
            length = float(lane.length)
            s_to = length
            nxt = route[k + 1] if k + 1 < len(route) else None
            change = None
            if nxt is not None:
                end = np.asarray(lane.position(length, 0.0), dtype=float)
                if float(np.hypot(*(np.asarray(nxt.position(0.0, 0.0)) - end))) > 1.0:
                    s1, r1 = nxt.local_coordinates(end)
                    if abs(r1) < 2.5 * float(nxt.width_at(s1)) and -1.0 < s1 <= nxt.length + 1.0:
                        # A parallel neighbour: change lanes from here (or from the entry).
                        here = start[1] + 2.0 if start[0] == k else s_from
                        s_to = min(max(here, s_from), max(s_from, length - change_length))
                        change = s_to
            offsets.append(acc - s_from)
            n = 1 if _is_straight(lane) else max(2, int(math.ceil((s_to - s_from) / _ARC_SAMPLE_M)))
            ss = np.linspace(s_from, s_to, n + 1)
            xy = np.array([lane.position(float(s), 0.0) for s in ss], dtype=float)
            # Consecutive lanes share their junction point; drop the duplicate knot so the
            # interpolation below sees strictly increasing arc length.
            if knots_s:
                ss, xy = ss[1:], xy[1:]
            knots_s.append(acc + ss - s_from)
            knots_xy.append(xy)
            acc += s_to - s_from
            s_from = 0.0
            if change is not None:
                # Smoothstep blend between the two centre lines over change_length.
                m = max(4, int(math.ceil(change_length)))
                u = np.linspace(0.0, 1.0, m + 1)[1:]
                w = u * u * (3.0 - 2.0 * u)
                pts = []
                for ui, wi in zip(u, w):
                    s = change + ui * change_length
                    a = np.asarray(lane.position(s, 0.0), dtype=float)
                    s_n, _ = nxt.local_coordinates(a)
                    bpt = np.asarray(nxt.position(s_n, 0.0), dtype=float)
                    pts.append((1.0 - wi) * a + wi * bpt)
                knots_s.append(acc + u * change_length)
                knots_xy.append(np.array(pts))
                acc += change_length
                s_from = float(nxt.local_coordinates(pts[-1])[0])
        self.offsets = tuple(offsets)
        self.route_length = acc
        ks = np.concatenate(knots_s)
        kxy = np.concatenate(knots_xy)
        # Straight extensions so look-ahead, prediction and projection never run off the
        # route's ends (the ego keeps driving after its last lane, and may start behind it).
        h0 = float(route[0].heading_at(0.0))
        h1 = float(route[-1].heading_at(float(route[-1].length)))
        pre = kxy[0] - extension * np.array([math.cos(h0), math.sin(h0)])
        post = kxy[-1] + extension * np.array([math.cos(h1), math.sin(h1)])
        ks = np.concatenate([[-extension], ks, [acc + extension]])
        kxy = np.vstack([pre, kxy, post])
        self.S0 = -extension
        grid = np.arange(-extension, acc + extension + 0.5 * self.ds, self.ds)
        self.S = grid
        self.x = np.interp(grid, ks, kxy[:, 0])
        self.y = np.interp(grid, ks, kxy[:, 1])
        dx = np.gradient(self.x)
        dy = np.gradient(self.y)
        norm = np.hypot(dx, dy)
        norm[norm == 0.0] = 1.0
        self.tx = dx / norm
        self.ty = dy / norm
        heading = np.unwrap(np.arctan2(self.ty, self.tx))
        curv = np.gradient(heading) / self.ds
        # A 5-m moving average: the resampled polyline's kinks would otherwise show up as
        # curvature spikes and spurious curve-speed limits.
        k = max(1, int(round(5.0 / self.ds)))
        self.curvature = np.convolve(curv, np.ones(k) / k, mode="same")
        self.max_abs_curvature = float(np.max(np.abs(self.curvature)))
        self.n = len(grid)
        self._xl = self.x.tolist()
        self._yl = self.y.tolist()
        self._txl = self.tx.tolist()
        self._tyl = self.ty.tolist()

    # -- scalar look-ups (plain Python floats: numpy scalars are slow in scalar math) ------
    def index(self, s: float) -> int:
        """Index of the grid point at or just before arc length ``s`` [m] (clamped)."""
        i = int((s - self.S0) / self.ds)
        return 0 if i < 0 else (self.n - 2 if i > self.n - 2 else i)

    def point(self, s: float) -> tuple[float, float]:
        """Centre-line point (x, y) [m] at arc length ``s`` [m], linear between samples.

        Beyond either end the line goes on straight, so an ego that outlives its route keeps
        driving ahead instead of circling back to the last point.
        """
        i = self.index(s)
        f = (s - self.S0) / self.ds - i
        xl, yl = self._xl, self._yl
        if 0.0 <= f <= 1.0:
            return xl[i] + f * (xl[i + 1] - xl[i]), yl[i] + f * (yl[i + 1] - yl[i])
        j = 0 if f < 0.0 else i + 1
        extra = (s - self.S0) - j * self.ds
        return xl[j] + extra * self._txl[j], yl[j] + extra * self._tyl[j]

    def tangent(self, s: float) -> tuple[float, float]:
        """Unit tangent (cos, sin of the heading) at arc length ``s`` [m]."""
        i = self.index(s)
        return self._txl[i], self._tyl[i]

    def window(self, s_from: float, s_to: float) -> slice:
        """Slice of grid indices covering arc lengths [s_from, s_to] [m]."""
        i0 = self.index(s_from)
        i1 = min(self.n, self.index(s_to) + 2)
        return slice(i0, i1)

    def project_near(self, x: float, y: float, s_guess: float) -> tuple[float, float, float, float]:
        """Arc length, lateral offset [m] and unit tangent of the route point nearest (x, y).

        Local search from ``s_guess`` [m]: repeatedly slides along the tangent by the
        point's along-track offset (exact on straight parts, a few steps on curves). Far
        from the route on a tight curve it may settle on a local nearest point — good enough
        to tell whether an agent is on our path.
        """
        s = s_guess
        xl, yl, txl, tyl = self._xl, self._yl, self._txl, self._tyl
        for _ in range(4):
            i = self.index(s)
            f = (s - self.S0) / self.ds - i
            f = 0.0 if f < 0.0 else (1.0 if f > 1.0 else f)
            qx = xl[i] + f * (xl[i + 1] - xl[i])
            qy = yl[i] + f * (yl[i + 1] - yl[i])
            tx, ty = txl[i], tyl[i]
            along = (x - qx) * tx + (y - qy) * ty
            s += along
            if -0.05 < along < 0.05:
                break
        return s, tx * (y - qy) - ty * (x - qx), tx, ty

    def project(self, x: float, y: float) -> tuple[float, float]:
        """Arc length and signed lateral offset [m] of a world point, over the whole path."""
        d2 = (self.x - x) ** 2 + (self.y - y) ** 2
        j = int(np.argmin(d2))
        dx, dy = x - self._xl[j], y - self._yl[j]
        tx, ty = self._txl[j], self._tyl[j]
        return float(self.S[j]) + dx * tx + dy * ty, tx * dy - ty * dx


def parking_path(
    start_x: float,
    lateral: float,
    end_x: float,
    radius: float,
    length: float,
    step: float = 0.2,
    min_radius: float | None = None,
) -> np.ndarray:
    """Reverse parking reference in the slot frame, as rows (x, y, body heading) [m, m, rad].

    Slot frame: origin on the slot's centre line, +x along the traffic direction, the
    driving lane at +y (``lateral`` [m] > 0 from the slot's centre line). The car starts at
    (``start_x``, ``lateral``) heading 0 and ends near (``end_x``, 0) heading 0, reversing all
    the way: straight while the start is further forward than needed, then steering so the
    body turns at 1/``radius`` per metre (tail toward the kerb), then the mirrored counter-
    steer until the body is straight again.

    The points are produced by integrating highway-env's own kinematics (the *centre* moves
    along heading + beta + pi when reversing), not by drawing circles: with a constant slip
    angle -b the centre's path is an arc of radius R cos(b) whose tangent is offset from the
    body by b, and each steering change kinks it. Two such arcs turning the body by phi shift
    the car 2 R cos(b) (1 - cos phi) sideways over 2 R cos(b) sin phi lengthwise. When the
    start is too close for ``radius`` the turn is tightened to fit, down to ``min_radius``
    [m] (the steering limit; default just above the car's half length).
    """
    if lateral <= 0.0:
        raise ValueError("parking_path expects the car on the +y side of the slot")
    half = 0.5 * length

    def solve(r: float) -> tuple[float, float, float]:
        b = math.asin(min(0.99, half / r))
        reff = r * math.cos(b)
        phi = math.acos(max(-1.0, 1.0 - lateral / (2.0 * reff)))
        return b, phi, 2.0 * reff * math.sin(phi)

    b, phi, need = solve(radius)
    span = start_x - end_x
    if span < need:
        # Tighten: bisect the radius whose manoeuvre fits in the available length.
        lo = half * 1.01 if min_radius is None else min(min_radius, radius)
        hi = radius
        for _ in range(40):
            mid = 0.5 * (lo + hi)
            if solve(mid)[2] > span:
                hi = mid
            else:
                lo = mid
        radius = lo
        b, phi, need = solve(radius)
    ds = 0.01
    x, y, h = start_x, lateral, 0.0
    pts = [(x, y, h)]
    travelled = 0.0
    next_mark = step
    straight = max(0.0, span - need)
    # Phases as (slip angle, end test); reversing: the centre moves along h + beta + pi and
    # the body turns at -v sin(beta) / (L/2) per unit time, i.e. -2 sin(beta)/L per metre.
    phases = ((0.0, lambda: travelled >= straight),
              (-b, lambda: h >= phi),
              (b, lambda: h <= 0.0))
    for beta, done in phases:
        while not done():
            x -= ds * math.cos(h + beta)
            y -= ds * math.sin(h + beta)
            h -= ds * math.sin(beta) / half
            travelled += ds
            if travelled >= next_mark:
                pts.append((x, y, h))
                next_mark += step
    pts.append((x, y, 0.0))
    return np.array(pts)


def _arc_poses(x0: float, y0: float, h0: float, direction: float, beta: float, half: float,
               s: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Poses after travelling arc lengths ``s`` [m] at a constant slip angle ``beta`` [rad].

    Closed form of highway-env's kinematics: the heading turns at direction sin(beta)/half
    per metre and the centre moves along heading + beta (backward when direction < 0).
    """
    if abs(beta) < 1e-9:
        c, sn = math.cos(h0), math.sin(h0)
        return x0 + direction * s * c, y0 + direction * s * sn, np.full_like(s, h0)
    k = math.sin(beta) / half
    h = h0 + direction * k * s
    x = x0 + (np.sin(h + beta) - math.sin(h0 + beta)) / k
    y = y0 - (np.cos(h + beta) - math.cos(h0 + beta)) / k
    return x, y, h


def parking_moves(
    x: float, y: float, length: float, width: float, max_beta: float,
    boxes: Sequence[tuple[float, float, float, float]], step: float = 0.2,
) -> list[tuple[np.ndarray, float]] | None:
    """A multi-move parallel-parking plan in the slot frame, or None if none is found.

    Frame as for :func:`parking_path` (goal at the origin heading 0, the car at (``x``,
    ``y``) heading 0 with y > 0); ``boxes`` are the obstacles, already inflated by the
    wanted clearance. The plan: reverse (straight to x1, then full lock swinging the tail in
    until the body is at phi), then counter-lock; while the body is not yet straight,
    alternately pull forward on the kerb-side lock and reverse on the counter-lock, each
    move running until the body is straight or the next step would touch an obstacle; then
    a straight move to x = 0. x1 and phi are searched on a grid, preferring a final lateral
    error under 0.15 m and few moves. Returns [(points (x, y, body heading), direction)],
    points every ``step`` metres, direction -1 reversing, +1 forward.
    """
    half, half_w = 0.5 * length, 0.5 * width
    ds = 0.05
    s_grid = np.arange(ds, 15.0, ds)

    def run(x0, y0, h0, direction, beta, stop_h):
        X, Y, H = _arc_poses(x0, y0, h0, direction, beta, half, s_grid)
        bad = poses_hit_boxes(X, Y, H, half, half_w, boxes)
        n = len(s_grid)
        i = int(np.argmax(bad)) if bad.any() else n
        if stop_h is not None and beta:
            turn = direction * math.sin(beta)
            done = (H - stop_h) * (1.0 if turn > 0 else -1.0) >= 0.0
            if done.any():
                i = min(i, int(np.argmax(done)) + 1)
        if i == 0:
            return x0, y0, h0, 0.0
        return float(X[i - 1]), float(Y[i - 1]), float(H[i - 1]), float(s_grid[i - 1])

    best = None
    for x1 in np.arange(x, -2.0, -0.5):
        # The straight reverse to x1 must itself be clear.
        if poses_hit_boxes(np.array([x1]), np.array([y]), np.array([0.0]), half, half_w, boxes)[0]:
            break
        for phi in np.arange(0.3, 1.0, 0.05):
            moves = [(x, y, 0.0, -1.0, 0.0, x - x1)]
            cx, cy, ch, s = run(x1, y, 0.0, -1.0, -max_beta, phi)
            if ch < phi - 0.01:
                continue
            moves.append((x1, y, 0.0, -1.0, -max_beta, s))
            ok = False
            for _ in range(8):
                for direction, beta in ((-1.0, max_beta), (1.0, -max_beta)):
                    nx, ny, nh, s = run(cx, cy, ch, direction, beta, 0.0)
                    if s < 0.05:
                        break
                    moves.append((cx, cy, ch, direction, beta, s))
                    cx, cy, ch = nx, ny, nh
                    if abs(ch) < 0.02:
                        ok = True
                        break
                else:
                    continue
                break
            if not ok:
                continue
            # Final straight move to x = 0 must be clear too.
            xs = np.linspace(cx, 0.0, 20)
            if poses_hit_boxes(xs, np.full_like(xs, cy), np.full_like(xs, ch), half, half_w, boxes).any():
                continue
            cost = 10.0 * abs(cy) + len(moves)
            if best is None or cost < best[0]:
                best = (cost, moves, (cx, cy, ch))
        if best is not None and best[0] < 10.0 * 0.15 + 4:
            break  # good enough: stop searching further back
    if best is None or abs(best[2][1]) > 0.3:
        return None
    # Sample the moves into tracks; consecutive moves in the same direction merge.
    tracks: list[tuple[list, float]] = []
    for x0, y0, h0, direction, beta, s in best[1]:
        n = max(1, int(math.ceil(s / step)))
        ss = np.linspace(0.0, s, n + 1)
        X, Y, H = _arc_poses(x0, y0, h0, direction, beta, half, ss)
        pts = list(zip(X.tolist(), Y.tolist(), H.tolist()))
        if tracks and tracks[-1][1] == direction:
            tracks[-1][0].extend(pts[1:])
        else:
            tracks.append((pts, direction))
    cx, cy, ch = best[2]
    if abs(cx) > 0.1:
        direction = 1.0 if cx < 0.0 else -1.0
        n = max(2, int(math.ceil(abs(cx) / step)))
        pts = [(cx + (0.0 - cx) * i / n, cy, ch) for i in range(n + 1)]
        if tracks and tracks[-1][1] == direction:
            tracks[-1][0].extend(pts[1:])
        else:
            tracks.append((pts, direction))
    return [(np.array(p), d) for p, d in tracks if len(p) >= 2]

"""The route as the built-in autopilot plans on it: one resampled centre line, and the
steering laws that follow it.

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

__all__ = ["RoutePath", "bicycle_steering", "pursuit_steering"]

_ARC_SAMPLE_M = 1.0  # [m] sampling step for curved lanes before resampling (chord error ds²/8R)
_KBLOCK = 16  # grid points per block of the curvature bound


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


def _memo(lane: Any) -> dict | None:
    # a lane that never changes (a map's, shared by every world on it) offers a dict for
    # what is computed from it alone: a route through it then samples it once per process
    return getattr(lane, "memo", None)


def _end(lane: Any, length: float) -> np.ndarray:
    memo = _memo(lane)
    got = memo.get("end") if memo is not None else None
    if got is None:
        got = np.asarray(lane.position(length, 0.0), dtype=float)
        if memo is not None:
            memo["end"] = got
    return got


def _start(lane: Any) -> np.ndarray:
    memo = _memo(lane)
    got = memo.get("start") if memo is not None else None
    if got is None:
        got = np.asarray(lane.position(0.0, 0.0))
        if memo is not None:
            memo["start"] = got
    return got


def _samples(lane: Any, s_from: float, s_to: float, n: int) -> tuple[np.ndarray, np.ndarray]:
    """``n + 1`` arc lengths from ``s_from`` to ``s_to`` [m] on ``lane`` and its centre line
    there (N, 2) [m]."""
    memo = _memo(lane)
    key = ("samples", s_from, s_to, n)
    got = memo.get(key) if memo is not None else None
    if got is None:
        ss = np.linspace(s_from, s_to, n + 1)
        if hasattr(lane, "centre_points"):  # a map lane samples its centre line at once
            xy = np.asarray(lane.centre_points(ss), dtype=float)
        else:
            xy = np.array([lane.position(float(s), 0.0) for s in ss], dtype=float)
        got = (ss, xy)
        if memo is not None and len(memo) < 64:
            memo[key] = got
    return got


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
                end = _end(lane, length)
                if float(np.hypot(*(_start(nxt) - end))) > 1.0:
                    s1, r1 = nxt.local_coordinates(end)
                    if abs(r1) < 2.5 * float(nxt.width_at(s1)) and -1.0 < s1 <= nxt.length + 1.0:
                        # A parallel neighbour: change lanes from here (or from the entry).
                        here = start[1] + 2.0 if start[0] == k else s_from
                        s_to = min(max(here, s_from), max(s_from, length - change_length))
                        change = s_to
            offsets.append(acc - s_from)
            n = 1 if _is_straight(lane) else max(2, int(math.ceil((s_to - s_from) / _ARC_SAMPLE_M)))
            ss, xy = _samples(lane, s_from, s_to, n)
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
        # |curvature|'s maximum per block of _KBLOCK points: a bound over any window in a few
        # list look-ups (most of a map's route is straight enough to need no curve limit)
        ak = np.abs(self.curvature)
        pad = (-len(ak)) % _KBLOCK
        self._kmax = np.concatenate([ak, np.zeros(pad)]).reshape(-1, _KBLOCK).max(axis=1).tolist()
        self.n = len(grid)
        self._xl = self.x.tolist()
        self._curve_base: dict[float, np.ndarray] = {}
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

    def max_curvature_bound(self, w: slice) -> float:
        """An upper bound of |curvature| [1/m] over the grid indices of ``w`` (a slice from
        :meth:`window`): the largest of the blocks it touches."""
        b0, b1 = w.start // _KBLOCK, (max(w.stop, w.start + 1) - 1) // _KBLOCK
        return max(self._kmax[b0:b1 + 1])

    def curve_speed_min(self, w: slice, s: float, lateral_accel: float, decel: float) -> float:
        """``min sqrt(lateral_accel / max(|curvature|, 1e-6) + 2 decel d)`` [m/s] over the
        grid indices of ``w``, ``d`` [m] each point's distance ahead of ``s`` (0 behind it);
        the first term is computed once per path (the same numbers as point by point)."""
        base = self._curve_base.get(lateral_accel)
        if base is None:
            base = self._curve_base[lateral_accel] = \
                lateral_accel / np.maximum(np.abs(self.curvature), 1e-6)
        d = self.S[w] - s
        np.maximum(d, 0.0, out=d)
        d *= 2 * decel
        d += base[w]
        return math.sqrt(float(d.min()))  # sqrt is monotonic: the root of the least

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

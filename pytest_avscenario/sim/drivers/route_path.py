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
from collections.abc import Sequence
from typing import Any

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


_PIECE_M = 100.0  # [m] of route built beyond what a look-up asks for, per piece


class _Offsets(Sequence):
    """``RoutePath.offsets``: one entry per route lane, each worked out when first asked."""

    __slots__ = ("_path",)

    def __init__(self, path: "RoutePath") -> None:
        self._path = path

    def __len__(self) -> int:
        return len(self._path._route)

    def __getitem__(self, k: Any) -> Any:
        path = self._path
        if isinstance(k, slice):
            return tuple(self[i] for i in range(*k.indices(len(self))))
        if k < 0:
            k += len(path._route)
        if not 0 <= k < len(path._route):
            raise IndexError("route lane index out of range")
        if k >= len(path._offsets):
            path._plan(k + 1)
        return path._offsets[k]

    def __repr__(self) -> str:
        return f"offsets({list(self)!r})"


class RoutePath:
    """The route's centre line resampled every ``ds`` metres, extended straight at both ends.

    Arc length ``S`` [m] is counted from the start of ``route[0]``; lane ``k`` of the route
    starts at ``offsets[k]``, so a point at longitudinal ``s`` on lane ``k`` sits at
    ``offsets[k] + s``. Arrays (all of one length): ``S``, ``x``, ``y`` [m], unit tangent
    ``tx``, ``ty``, and ``curvature`` [1/m] (signed, left positive).

    The path is built piece by piece, as far as the look-ups ask plus :data:`_PIECE_M`: a
    map's default route runs on for kilometres, of which a case drives a few hundred metres.
    The arrays hold what is built so far, and each look-up builds on first when it needs
    more. Every number is the one building the whole route at once gives: a piece ends a few
    grid points before the last centre-line sample known, so each interpolation, gradient
    and moving average sees the same neighbours in the same order, and the heading's
    unwrapping carries its running sum of corrections from piece to piece.
    """

    def __init__(self, route: Sequence[Any], ds: float = 1.0, extension: float = 150.0,
                 start: tuple[int, float] = (0, 0.0), change_length: float = 25.0):
        """``start`` = (route index, s [m]) where the ego is when the path is built: a lane
        change the route asks for (a lane followed by a parallel neighbour rather than by
        its successor) begins 2 m ahead of it and blends over ``change_length`` metres."""
        if not route:
            raise ValueError("the autopilot needs a route with at least one lane")
        self.ds = float(ds)
        self._route = route
        self._start = start
        self._extension = float(extension)
        self._change_length = change_length
        # the plan, lane by lane: offsets, the part of each lane driven, lane-change blends
        self._offsets: list[float] = []
        self._parts: list[tuple] = []  # (lane, s_from, s_to, n, acc, blend s, blend xy)
        self._acc = 0.0
        self._s_from = 0.0
        self.offsets: Sequence[float] = _Offsets(self)
        # the knots (arc length, x, y) sampled and not yet behind the interpolated grid
        self._sampled = 0
        self._ks = np.empty(0)
        self._kx = np.empty(0)
        self._ky = np.empty(0)
        self._complete = False
        self.S0 = -self._extension
        self._grid = np.empty(0)
        self._smooth = max(1, int(round(5.0 / self.ds)))
        self._kernel = np.ones(self._smooth) / self._smooth
        # buffers, grown by doubling, and how far each quantity is final
        self._buf: dict[str, np.ndarray] = {}
        self._m_xy = 0  # x, y final below this grid index
        self._m_t = 0  # tx, ty, wrapped heading
        self._m_u = 0  # unwrapped heading
        self._carry = 0.0  # the heading corrections' running sum, up to grid index _m_u - 2
        self._m_c = 0  # curvature before the moving average
        self._ready = 0  # every array is final below this index
        self._kmax: list[float] = []  # max |curvature| per block of _KBLOCK points, final ones
        self._curve_base: dict[float, np.ndarray] = {}
        self._xl: list[float] = []
        self._yl: list[float] = []
        self._txl: list[float] = []
        self._tyl: list[float] = []
        #: :attr:`max_abs_curvature` once the whole path is built, None until then (read per
        #: step: a built road's straight route needs no curve look-up at all)
        self.known_max_abs_curvature: float | None = None
        self._grow(2)

    # -- building ------------------------------------------------------------------------------
    def _plan(self, k_end: int) -> None:
        """Plan route lanes up to ``k_end`` (excluded): each one's offset, the part of it the
        path runs on, and the blend of a lane change after it (made here: where the next
        lane's part starts depends on it)."""
        route, start, change_length = self._route, self._start, self._change_length
        acc, s_from = self._acc, self._s_from
        for k in range(len(self._offsets), min(k_end, len(route))):
            lane = route[k]
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
            self._offsets.append(acc - s_from)
            n = 1 if _is_straight(lane) else max(2, int(math.ceil((s_to - s_from) / _ARC_SAMPLE_M)))
            part = [lane, s_from, s_to, n, acc, None, None]
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
                part[5] = acc + u * change_length
                part[6] = np.array(pts)
                acc += change_length
                s_from = float(nxt.local_coordinates(pts[-1])[0])
            self._parts.append(tuple(part))
        self._acc, self._s_from = acc, s_from
        if len(self._offsets) == len(route) and not isinstance(self.offsets, tuple):
            self.offsets = tuple(self._offsets)  # all known: a plain tuple is faster to read

    def _sample(self, s_need: float) -> None:
        """Sample route lanes until the knots reach past ``s_need`` [m] (or the route ends,
        then add the straight extension after it and learn the grid's length)."""
        ks, kx, ky = [self._ks], [self._kx], [self._ky]
        route = self._route
        last = float(self._ks[-1]) if len(self._ks) else -math.inf
        while last <= s_need and self._sampled < len(route):
            k = self._sampled
            if k >= len(self._parts):
                self._plan(k + 1)
            lane, s_from, s_to, n, acc, blend_s, blend_xy = self._parts[k]
            ss, xy = _samples(lane, s_from, s_to, n)
            # Consecutive lanes share their junction point; drop the duplicate knot so the
            # interpolation sees strictly increasing arc length.
            if k > 0:
                ss, xy = ss[1:], xy[1:]
            elif len(xy):
                # the straight extension before the route, so look-ahead, prediction and
                # projection never run off its start (the ego may start behind it)
                h0 = float(lane.heading_at(0.0))
                pre = xy[0] - self._extension * np.array([math.cos(h0), math.sin(h0)])
                ks.append(np.array([-self._extension]))
                kx.append(pre[:1])
                ky.append(pre[1:])
            ks.append(acc + ss - s_from)
            kx.append(xy[:, 0])
            ky.append(xy[:, 1])
            if blend_s is not None:
                ks.append(blend_s)
                kx.append(blend_xy[:, 0])
                ky.append(blend_xy[:, 1])
            self._sampled = k + 1
            last = float(ks[-1][-1]) if len(ks[-1]) else last
        if self._sampled == len(route) and not self._complete:
            # ... and after its end (the ego keeps driving after its last lane)
            h1 = float(route[-1].heading_at(float(route[-1].length)))
            end = np.array([kx[-1][-1], ky[-1][-1]]) if len(kx[-1]) else \
                np.array([self._kx[-1], self._ky[-1]])
            post = end + self._extension * np.array([math.cos(h1), math.sin(h1)])
            ks.append(np.array([self._acc + self._extension]))
            kx.append(post[:1])
            ky.append(post[1:])
            self._complete = True
            self._grid = np.arange(-self._extension,
                                   self._acc + self._extension + 0.5 * self.ds, self.ds)
        self._ks, self._kx, self._ky = np.concatenate(ks), np.concatenate(kx), np.concatenate(ky)

    def _reserve(self, n: int) -> None:
        cap = len(self._buf["x"]) if self._buf else 0
        if n <= cap:
            return
        cap = max(n, 2 * cap, 512)
        for name in ("S", "x", "y", "tx", "ty", "p", "up", "curv", "curvature"):
            old = self._buf.get(name)
            new = np.empty(cap)
            if old is not None:
                new[:len(old)] = old
            self._buf[name] = new

    def _grow(self, need: int) -> None:
        """Build until grid points ``[0, need)`` are final, or the whole route is."""
        while self._ready < need and not (self._complete and self._ready == len(self._grid)):
            s_need = self.S0 + (need + 2 * self._smooth + 8) * self.ds
            self._sample(s_need + _PIECE_M)
            self._derive()

    def _derive(self) -> None:
        """Interpolate the grid points the knots now bracket and bring every quantity as far
        as its neighbours are known (all of them once the route's end is known)."""
        b = self._buf
        if self._complete:
            m = len(self._grid)
        else:
            # the grid's values do not depend on where it stops: numpy's arange fills
            # start + i * step
            top = self._ks[-1]
            hi = int((top - self.S0) / self.ds) + 2
            if hi > len(self._grid):
                self._grid = np.arange(-self._extension, self.S0 + (2 * hi + 2) * self.ds,
                                       self.ds)
            m = int(np.searchsorted(self._grid[:hi], top, "left"))  # S < the last knot
        m0 = self._m_xy
        if m <= m0:
            return
        self._reserve(m)
        g = self._grid[m0:m]
        b["S"][m0:m] = g
        ks = self._ks
        b["x"][m0:m] = np.interp(g, ks, self._kx)
        b["y"][m0:m] = np.interp(g, ks, self._ky)
        self._m_xy = m
        # keep the knots from the last one at or before the next grid point on
        if not self._complete:
            j = max(int(np.searchsorted(ks, self._grid[m], "right")) - 1, 0)
            self._ks, self._kx, self._ky = ks[j:], self._kx[j:], self._ky[j:]
        final = self._complete
        # tangent and heading: a central difference (one-sided at the path's two ends)
        lo, hi = self._m_t, (m if final else m - 1)
        if hi > lo:
            dx = _gradient(b["x"], lo, hi, m if final else -1)
            dy = _gradient(b["y"], lo, hi, m if final else -1)
            norm = np.hypot(dx, dy)
            norm[norm == 0.0] = 1.0
            tx = b["tx"][lo:hi] = dx / norm
            ty = b["ty"][lo:hi] = dy / norm
            b["p"][lo:hi] = np.arctan2(ty, tx)
            self._m_t = hi
        # unwrapped heading (numpy's unwrap, its running sum carried over pieces)
        lo, hi = self._m_u, self._m_t
        if hi > lo:
            p = b["p"]
            if lo == 0:
                b["up"][0] = p[0]
                lo = 1
            if hi > lo:
                dd = p[lo:hi] - p[lo - 1:hi - 1]
                fix = _phase_corrections(dd)
                run = np.cumsum(fix) if lo == 1 else \
                    np.cumsum(np.concatenate(([self._carry], fix)))[1:]
                b["up"][lo:hi] = p[lo:hi] + run
                self._carry = float(run[-1])
            self._m_u = hi
        # curvature: the heading's gradient, then a moving average
        lo, hi = self._m_c, (m if final else self._m_u - 1)
        if hi > lo:
            b["curv"][lo:hi] = _gradient(b["up"], lo, hi, m if final else -1) / self.ds
            self._m_c = hi
        k = self._smooth
        lo, hi = self._ready, (m if final else self._m_c - k)
        if hi > lo:
            a = max(lo - k, 0)
            top = min(hi + k, self._m_c)
            b["curvature"][lo:hi] = np.convolve(b["curv"][a:top], self._kernel,
                                                mode="same")[lo - a:hi - a]
            self._ready = hi
            self._extend(lo, hi)
            if self.complete:
                self.known_max_abs_curvature = float(np.max(np.abs(self.curvature)))

    def _extend(self, lo: int, hi: int) -> None:
        """Publish grid points [lo, hi), now final."""
        b = self._buf
        self.S = b["S"][:hi]
        self.x = b["x"][:hi]
        self.y = b["y"][:hi]
        self.tx = b["tx"][:hi]
        self.ty = b["ty"][:hi]
        self.curvature = b["curvature"][:hi]
        self._xl += b["x"][lo:hi].tolist()
        self._yl += b["y"][lo:hi].tolist()
        self._txl += b["tx"][lo:hi].tolist()
        self._tyl += b["ty"][lo:hi].tolist()
        # |curvature|'s maximum per block of _KBLOCK points: a bound over any window in a few
        # list look-ups (most of a map's route is straight enough to need no curve limit)
        b0 = len(self._kmax)
        whole = self._complete and hi == len(self._grid)
        b1 = -(-hi // _KBLOCK) if whole else hi // _KBLOCK
        if b1 > b0:
            ak = np.abs(b["curvature"][b0 * _KBLOCK:min(b1 * _KBLOCK, hi)])
            pad = (-len(ak)) % _KBLOCK
            self._kmax += np.concatenate([ak, np.zeros(pad)]).reshape(-1, _KBLOCK) \
                .max(axis=1).tolist()

    def offset(self, k: int) -> float | None:
        """``offsets[k]`` [m], or None when ``k`` is not the index of a route lane (one call
        where ``0 <= k < len(offsets)`` and ``offsets[k]`` take three, every step)."""
        got = self._offsets
        if 0 <= k < len(got):
            return got[k]
        if 0 <= k < len(self._route):
            self._plan(k + 1)
            return self._offsets[k]
        return None

    @property
    def n(self) -> int:
        """Number of grid points of the whole path (builds it all)."""
        self._grow(1 << 62)
        return self._ready

    @property
    def complete(self) -> bool:
        """Whether the whole route is built."""
        return self._complete and self._ready == len(self._grid)

    @property
    def route_length(self) -> float:
        """Length [m] of the route's centre line as driven (lane-change blends included)."""
        self._plan(len(self._route))
        return self._acc

    @property
    def max_abs_curvature(self) -> float:
        """Largest |curvature| [1/m] over the whole path (builds it all)."""
        if self.known_max_abs_curvature is None:
            self._grow(1 << 62)
        return self.known_max_abs_curvature


    # -- scalar look-ups (plain Python floats: numpy scalars are slow in scalar math) ------
    def index(self, s: float) -> int:
        """Index of the grid point at or just before arc length ``s`` [m] (clamped)."""
        i = int((s - self.S0) / self.ds)
        if i < 0:
            return 0
        if i > self._ready - 2:
            self._grow(i + 2)
            if i > self._ready - 2:  # beyond the route's end
                return self._ready - 2
        return i

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
        i1 = self.index(s_to) + 2  # (first: it may build on)
        i1 = min(self._ready, i1)
        return slice(i0, i1)

    def curve_window(self, s_from: float, s_to: float) -> tuple[slice, float]:
        """:meth:`window` and its :meth:`max_curvature_bound` in one call (the autopilot asks
        both every step on a curved route)."""
        S0, ds = self.S0, self.ds
        i0 = int((s_from - S0) / ds)
        i1 = int((s_to - S0) / ds)
        if i0 < 0 or i1 < 0 or i0 > self._ready - 2 or i1 > self._ready - 2:
            w = self.window(s_from, s_to)
        else:
            w = slice(i0, i1 + 2)
        b0, b1 = w.start // _KBLOCK, (max(w.stop, w.start + 1) - 1) // _KBLOCK
        kmax = self._kmax
        if b1 >= len(kmax):
            self._grow((b1 + 1) * _KBLOCK)
        return w, (kmax[b0] if b0 == b1 else max(kmax[b0:b1 + 1]))

    def max_curvature_bound(self, w: slice) -> float:
        """An upper bound of |curvature| [1/m] over the grid indices of ``w`` (a slice from
        :meth:`window`): the largest of the blocks it touches."""
        b0, b1 = w.start // _KBLOCK, (max(w.stop, w.start + 1) - 1) // _KBLOCK
        if b1 >= len(self._kmax):
            self._grow((b1 + 1) * _KBLOCK)
        return max(self._kmax[b0:b1 + 1])

    def curve_speed_min(self, w: slice, s: float, lateral_accel: float, decel: float) -> float:
        """``min sqrt(lateral_accel / max(|curvature|, 1e-6) + 2 decel d)`` [m/s] over the
        grid indices of ``w``, ``d`` [m] each point's distance ahead of ``s`` (0 behind it);
        the first term is computed once per grid point (the same numbers as point by point)."""
        base = self._curve_base.get(lateral_accel)
        if base is None or len(base) < w.stop:
            done = 0 if base is None else len(base)
            more = lateral_accel / np.maximum(np.abs(self.curvature[done:]), 1e-6)
            base = self._curve_base[lateral_accel] = \
                more if base is None else np.concatenate([base, more])
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
        # the lists grow in place when a look-up builds more: these names stay valid
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
        """Arc length and signed lateral offset [m] of a world point, over the whole path
        (builds it all)."""
        self._grow(1 << 62)
        d2 = (self.x - x) ** 2 + (self.y - y) ** 2
        j = int(np.argmin(d2))
        dx, dy = x - self._xl[j], y - self._yl[j]
        tx, ty = self._txl[j], self._tyl[j]
        return float(self.S[j]) + dx * tx + dy * ty, tx * dy - ty * dx


def _gradient(f: np.ndarray, lo: int, hi: int, n: int) -> np.ndarray:
    """``numpy.gradient(f[:n])[lo:hi]`` (unit spacing) for ``n`` the array's length, or
    ``n = -1`` when ``f`` goes on past ``hi``: the same expressions (central differences
    halved, one-sided ones at the two ends), without its per-call overhead."""
    a, b = max(lo, 1), (hi if n < 0 or hi < n else n - 1)
    out = np.empty(hi - lo)
    out[a - lo:b - lo] = (f[a + 1:b + 1] - f[a - 1:b - 1]) / 2.0
    if lo == 0:
        out[0] = (f[1] - f[0]) / 1.0
    if b < hi:
        out[-1] = (f[n - 1] - f[n - 2]) / 1.0
    return out


def _phase_corrections(dd: np.ndarray) -> np.ndarray:
    """What ``numpy.unwrap`` adds, cumulatively, after each step ``dd`` [rad] of a heading
    (the same expressions, so a heading unwrapped piece by piece is the same to the bit)."""
    period = 2 * np.pi
    high = period / 2
    low = -high
    wrapped = np.mod(dd - low, period) + low
    wrapped[(wrapped == low) & (dd > 0)] = high
    fix = wrapped - dd
    fix[abs(dd) < high] = 0
    return fix

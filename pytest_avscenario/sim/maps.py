"""A map file as the world's road: OpenDRIVE lanes as highway-env lanes, routes through junctions.

``world.map("maps/Town06.xodr")`` gives a :class:`MapRoad`. Its lanes (the drivable ones:
driving, ramps, parking; see :data:`.opendrive.DRIVABLE`) are :class:`MapLaneShape` lanes —
highway-env ``AbstractLane`` subclasses with the width the file gives at every point (highway-env's
own ``PolyLane`` fixes every lane at 4 m) — joined in a highway-env ``RoadNetwork`` whose nodes
are the points where one lane continues into the next, so highway-env's IDM follows a route
across lane sections and junctions, and the world's lane tracking, the autopilot and the
monitors see the map's real centre lines and widths::

    town = world.map("maps/Town06.xodr")
    lane = town.lane(case.lane)                  # "road/section/lane", e.g. from MapLane(...)
    world.ego(lane, s=10, speed=20, route=town.route(lane, town.lane("5/0/-1")))
    world.car(town.ahead(lane.at(10), 40), speed=15)   # 40 m further along the default route

Everything built from one map file (the lane shapes, the network, the lane index) is made once
per process and shared by every world that loads it: nothing of it changes during a run.
"""

from __future__ import annotations

import bisect
import copy
import heapq
import math
import threading
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from .errors import SimError
from .lanes import LaneIndex
from .opendrive import (DRIVABLE, LaneData, MapData, MapError, default_successor, load,
                        why_no_successor)
from .places import Lane, Route, Spot

__all__ = ["MapRoad", "MapLaneShape", "RoadLane", "MapLaneIndex", "DEFAULT_SPEED_LIMIT"]

DEFAULT_SPEED_LIMIT = 13.9  # [m/s] (50 km/h) for lanes whose file gives no limit
_BLOCK = 10  # segments per block of MapLaneShape's nearest-foot search
_CELL = 5.0  # [m] grid cell of the nearest-foot search's block lists
_NEAR = 4.0  # [m] points this close to a lane's centre line find its blocks in their cell


def _abstract_lane() -> type:
    from ._hwenv import load_core

    load_core()
    from highway_env.road.lane import AbstractLane

    return AbstractLane


def _shape_class() -> type:
    global _SHAPE
    if _SHAPE is None:
        from highway_env.road.lane import LineType

        base = _abstract_lane()

        class MapLaneShape(base):
            """A lane along a sampled centre line with the file's width at every sample.

            ``position``/``heading_at``/``width_at`` interpolate between samples
            (:data:`.opendrive.STEP` apart); ``local_coordinates`` projects onto the
            polyline, extending its first and last segments so that points before the start
            or past the end get ``s < 0`` or ``s > length`` (highway-env moves on to the next
            lane there).
            """

            DEFAULT_WIDTH = 3.5
            VEHICLE_LENGTH = 5.0

            def __init__(self, data: LaneData, speed_limit: float) -> None:
                self.data = data
                self._s = data.s.astype(float)
                self._sl = self._s.tolist()
                self._xy = data.xy.astype(float)
                self._h = data.heading.astype(float)
                self._w = data.width.astype(float)
                # lateral offsets run square to the reference line (OpenDRIVE's t axis),
                # so position(s, +-width/2) is exactly the lane's edge
                rh = data.ref_heading.astype(float)
                self._rh = rh
                mid = rh[:-1] + 0.5 * np.angle(np.exp(1j * (rh[1:] - rh[:-1])))
                self._tau = np.stack([np.cos(mid), np.sin(mid)], axis=1)  # per segment
                self._dc = np.diff(self._xy, axis=0)
                self._along = np.einsum("ij,ij->i", self._dc, self._tau)
                self._along[np.abs(self._along) < 1e-12] = 1e-12
                # scalar look-ups go through lists: indexing numpy arrays per call costs more
                # than the arithmetic
                self._hl, self._wl, self._rhl = self._h.tolist(), self._w.tolist(), rh.tolist()
                # The nearest-foot search runs on the centre line with runs of collinear
                # segments of one reference direction merged (exact: the lane's s is linear
                # along them), in blocks with a bounding circle each: local_coordinates scans
                # the blocks nearest first and stops when no further block can hold a nearer
                # foot.
                tau, dc = self._tau, self._dc
                u = dc / np.maximum(np.hypot(dc[:, 0], dc[:, 1]), 1e-12)[:, None]
                same = ((np.abs(tau[1:] - tau[:-1]).max(axis=1) < 1e-12)
                        & (np.abs(u[1:, 0] * u[:-1, 1] - u[1:, 1] * u[:-1, 0]) < 1e-9)
                        & ((u[1:] * u[:-1]).sum(axis=1) > 0))
                keep = np.concatenate([[0], np.flatnonzero(~same) + 1, [len(self._xy) - 1]])
                kx, ky = self._xy[keep, 0], self._xy[keep, 1]
                st = tau[keep[:-1]]
                sdc = np.stack([np.diff(kx), np.diff(ky)], axis=1)
                salong = np.einsum("ij,ij->i", sdc, st)
                salong[np.abs(salong) < 1e-12] = 1e-12
                self._xl, self._yl = kx.tolist(), ky.tolist()
                self._txl, self._tyl = st[:, 0].tolist(), st[:, 1].tolist()
                self._dcx, self._dcy = sdc[:, 0].tolist(), sdc[:, 1].tolist()
                self._alongl = salong.tolist()
                self._ssl = self._s[keep].tolist()
                nseg = self._nseg = len(sdc)
                self._blocks = [(i, min(i + _BLOCK, nseg)) for i in range(0, nseg, _BLOCK)]
                centres, radii = [], []
                kxy = self._xy[keep]
                for i, j in self._blocks:
                    pts = kxy[i:j + 1]
                    c = (pts.min(axis=0) + pts.max(axis=0)) / 2
                    centres.append(c)
                    radii.append(float(np.hypot(*(pts - c).T).max()))
                self._bc = np.asarray(centres)
                self._bcz = self._bc[:, 0] + 1j * self._bc[:, 1]
                self._br = np.asarray(radii)
                self._bl = [(float(c[0]), float(c[1]), r) for c, r in zip(centres, radii)]
                self._hl, self._wl, self._rhl = self._h.tolist(), self._w.tolist(), rh.tolist()
                self._xfl, self._yfl = self._xy[:, 0].tolist(), self._xy[:, 1].tolist()
                self.length = float(self._s[-1])
                self.width = float(np.median(self._w))
                self._wconst = float(self._w[0]) if np.ptp(self._w) == 0 else None
                #: the width is one number all along (to a micrometre): what the recording
                #: needs to know to write a width per point or not
                self.width_constant = bool(np.ptp(np.round(self._w, 6)) == 0)
                self.line_types = (LineType.STRIPED, LineType.STRIPED)
                self.speed_limit = float(speed_limit)
                self.forbidden = False
                self.priority = 0
                self.radius = math.inf  # per-point curvature lives in the samples
                # A lane that is one straight line of one width (half of Town06's driving
                # lanes) answers local_coordinates in closed form.
                chord = self._xy[-1] - self._xy[0]
                clen = float(np.hypot(*chord))
                self._line = None
                if clen > 0 and np.ptp(self._w) < 1e-9 and np.ptp(rh) < 1e-9:
                    ux, uy = chord / clen
                    off = (self._xy[:, 0] - self._xy[0, 0]) * -uy + (self._xy[:, 1] - self._xy[0, 1]) * ux
                    if float(np.abs(off).max()) < 1e-6 and abs(math.atan2(uy, ux) - rh[0]) % (2 * math.pi) < 1e-6:
                        self._line = (float(self._xy[0, 0]), float(self._xy[0, 1]), float(ux), float(uy),
                                      clen / self.length)
                self._memo: tuple | None = None
                self._grid: dict | None = None  # see _local_near: cells filled on first use
                self._hints = (0, -1)  # recent feet's segments (_local_warm); agents enter at 0
                self._clear: list | None = None  # see _turning, made on first use
                # for what other modules compute from this lane alone (the autopilot's route
                # samples): the lane never changes and is shared by every world on the map
                self.memo: dict = {}

            def _at(self, s: float) -> tuple[int, float]:
                k = bisect.bisect_right(self._sl, s) - 1
                k = min(max(k, 0), len(self._sl) - 2)
                return k, (s - self._sl[k]) / (self._sl[k + 1] - self._sl[k])

            def position(self, longitudinal: float, lateral: float) -> np.ndarray:
                k, f = self._at(float(longitudinal))
                xl, yl, rh = self._xfl, self._yfl, self._rhl
                g = min(max(f, 0.0), 1.0)
                h = rh[k] + g * (rh[k + 1] - rh[k])
                return np.array([xl[k] + f * (xl[k + 1] - xl[k]) - lateral * math.sin(h),
                                 yl[k] + f * (yl[k + 1] - yl[k]) + lateral * math.cos(h)])

            def heading_at(self, longitudinal: float) -> float:
                # (_at written out: drivers ask this of their lane every step)
                s, sl = float(longitudinal), self._sl
                k = bisect.bisect_right(sl, s) - 1
                k = min(max(k, 0), len(sl) - 2)
                f = (s - sl[k]) / (sl[k + 1] - sl[k])
                f = min(max(f, 0.0), 1.0)
                hl = self._hl
                return hl[k] + f * (hl[k + 1] - hl[k])

            def width_at(self, longitudinal: float) -> float:
                if self._wconst is not None:
                    return self._wconst
                k, f = self._at(float(longitudinal))
                f = min(max(f, 0.0), 1.0)
                return self._wl[k] + f * (self._wl[k + 1] - self._wl[k])

            def widths_at(self, ss: Any) -> np.ndarray:
                """``width_at(s)`` [m] for every ``s`` of ``ss`` [m], vectorized with the
                same arithmetic."""
                ss = np.asarray(ss, dtype=float)
                if self._wconst is not None:
                    return np.full(ss.shape, self._wconst)
                s0, w = self._s, self._w
                k = np.clip(np.searchsorted(s0, ss, side="right") - 1, 0, len(s0) - 2)
                f = np.clip((ss - s0[k]) / (s0[k + 1] - s0[k]), 0.0, 1.0)
                return w[k] + f * (w[k + 1] - w[k])

            def positions(self, ss: Any, lateral: float = 0.0) -> np.ndarray:
                """``position(s, lateral)`` for every ``s`` of ``ss`` [m] as an (N, 2) array
                [m], vectorized with the same arithmetic (bit-identical)."""
                ss = np.asarray(ss, dtype=float)
                k = np.clip(np.searchsorted(self._s, ss, side="right") - 1, 0, len(self._s) - 2)
                s0, x, y, rh = self._s, self._xy[:, 0], self._xy[:, 1], self._rh
                f = (ss - s0[k]) / (s0[k + 1] - s0[k])
                g = np.clip(f, 0.0, 1.0)
                h = rh[k] + g * (rh[k + 1] - rh[k])
                lat = float(lateral)
                return np.stack([x[k] + f * (x[k + 1] - x[k]) - lat * np.sin(h),
                                 y[k] + f * (y[k + 1] - y[k]) + lat * np.cos(h)], axis=1)

            def centre_points(self, ss: Any) -> np.ndarray:
                """Centre-line points (N, 2) [m] at arc lengths ``ss`` [m] (vectorized)."""
                ss = np.asarray(ss, dtype=float)
                return np.stack([np.interp(ss, self._s, self._xy[:, 0]),
                                 np.interp(ss, self._s, self._xy[:, 1])], axis=1)

            def local_coordinates(self, position: Any) -> tuple[float, float]:
                # a pure function of the position: the last answer serves a repeated question
                # (tracking, route progress and the driver ask about the same point)
                px, py = float(position[0]), float(position[1])
                memo = self._memo
                if memo is not None and memo[0] == px and memo[1] == py:
                    return memo[2], memo[3]
                line = self._line
                if line is not None:
                    ex, ey = px - line[0], py - line[1]
                    return (ex * line[2] + ey * line[3]) / line[4], ey * line[2] - ex * line[3]
                s, r = self._local(px, py)
                self._memo = (px, py, s, r)
                return s, r

            def _local(self, px: float, py: float) -> tuple[float, float]:
                # On each segment, the point of the centre line from which the position lies
                # square to the reference line: f = (p - c_k).tau / (dc.tau); of the segments
                # that hold it (0 <= f <= 1), the nearest. First near a recent foot (see
                # _local_warm), else the search below; the same answer whatever was asked
                # before.
                got = self._local_warm(px, py)
                if got is None:
                    got = self._local_search(px, py)
                    k = bisect.bisect_right(self._ssl, got[0]) - 1
                    self._hints = (min(max(k, 0), self._nseg - 1), self._hints[0])
                return got

            def _local_warm(self, px: float, py: float) -> tuple[float, float] | None:
                # An agent moves less than a metre or two a step: its foot is on or near the
                # segment k of a recent one (two are kept: two agents take turns on a lane).
                # The foot on k at distance d is the answer when nothing else can be as near:
                # the two segments touching k are measured, and everything else of the centre
                # line (with the straight extensions past its ends) keeps at least clear[k]
                # from segment k (see _turning), so more than d from the point when
                # 2 d < clear[k]. None when no hint proves its answer (then the search).
                clear = self._clear
                if clear is None:
                    clear = self._turning()
                xl, yl, tx, ty = self._xl, self._yl, self._txl, self._tyl
                along, dcx, dcy, sl = self._alongl, self._dcx, self._dcy, self._ssl
                last = self._nseg - 1
                hints = self._hints
                for slot in (0, 1):
                    k = hints[slot]
                    if k < 0:
                        continue
                    ex, ey = px - xl[k], py - yl[k]
                    f = (ex * tx[k] + ey * ty[k]) / along[k]
                    if (f > 1.0 and k < last) or (f < 0.0 and k > 0):
                        # moved on: to the segment at the arc length the hint's line gives,
                        # and one further if the foot is not on that one
                        j = bisect.bisect_right(sl, sl[k] + f * (sl[k + 1] - sl[k])) - 1
                        k = 0 if j < 0 else (last if j > last else j)
                        for _ in range(2):
                            ex, ey = px - xl[k], py - yl[k]
                            f = (ex * tx[k] + ey * ty[k]) / along[k]
                            if f > 1.0 and k < last:
                                k += 1
                            elif f < 0.0 and k > 0:
                                k -= 1
                            else:
                                break
                    if not 0.0 <= f <= 1.0:
                        continue
                    dx, dy = ex - f * dcx[k], ey - f * dcy[k]
                    d2 = dx * dx + dy * dy
                    c = clear[k]
                    if 4.0 * d2 >= c * c or c <= 0.0:
                        continue
                    for j in (k - 1, k + 1):
                        if not 0 <= j <= last:
                            continue
                        ex, ey = px - xl[j], py - yl[j]
                        fj = (ex * tx[j] + ey * ty[j]) / along[j]
                        ray = not 0.0 <= fj <= 1.0
                        if ray and ((fj < 0.0 and j != 0) or (fj > 1.0 and j != last)):
                            continue  # not held there
                        ex, ey = ex - fj * dcx[j], ey - fj * dcy[j]
                        dj = ex * ex + ey * ey
                        if dj < d2 or (dj == d2 and j < k):
                            if ray:  # past an end of the lane: the search's to answer
                                return None
                            d2, k, f, dx, dy = dj, j, fj, ex, ey
                    if k != hints[0]:
                        self._hints = (k, hints[1] if slot == 0 else hints[0])
                    return sl[k] + f * (sl[k + 1] - sl[k]), tx[k] * dy - ty[k] * dx
                return None

            def _turning(self) -> list[float]:
                # clear[k] [m]: how close anything of the centre line that does not touch
                # segment k comes to it, from below (less a micrometre for rounding). The
                # segments of k's block and the blocks either side run, from k on, in
                # directions within the spread of those blocks' directions (cos c), so their
                # points lie at least c times the touching segment's length from k's; further
                # blocks lie beyond their bounding circles, and the straight extensions past
                # the lane's ends (when not within those blocks) beyond their distance from
                # the circle of k's block. Made on first use.
                n = self._nseg
                dcx, dcy = np.asarray(self._dcx), np.asarray(self._dcy)
                ang = np.arctan2(dcy, dcx)
                if n > 1:  # unwrapped: each turn from one segment to the next within +-pi
                    turn = np.diff(ang)
                    turn -= (2 * math.pi) * np.round(turn / (2 * math.pi))
                    ang[1:] = ang[0] + np.cumsum(turn)
                starts = np.arange(0, n, _BLOCK)
                lo, hi = np.minimum.reduceat(ang, starts), np.maximum.reduceat(ang, starts)
                spread = _either_side(hi, np.maximum) - _either_side(lo, np.minimum)
                cos3 = np.where(spread < math.radians(80), np.cos(spread), 0.0)
                length = np.hypot(dcx, dcy)
                blk = np.arange(n) // _BLOCK
                near = cos3[blk] * _beside(length)
                # blocks two or more apart, by their circles
                bc, br = self._bc, self._br
                nb = len(br)
                gap = np.hypot(bc[:, None, 0] - bc[None, :, 0], bc[:, None, 1] - bc[None, :, 1]) \
                    - br[:, None] - br[None, :]
                idx = np.arange(nb)
                gap[np.abs(idx[:, None] - idx[None, :]) <= 1] = math.inf
                far = gap.min(axis=1)
                # the extensions: rays from the first point back and from the last point on
                for seg, start, sign, outside in ((0, 0, -1.0, idx >= 2),
                                                  (n - 1, n, 1.0, idx <= nb - 3)):
                    if outside.any():
                        u = np.array([dcx[seg], dcy[seg]]) * (sign / max(length[seg], 1e-12))
                        rel = bc - (self._xl[start], self._yl[start])
                        t = np.maximum(rel[:, 0] * u[0] + rel[:, 1] * u[1], 0.0)
                        ray = np.hypot(rel[:, 0] - t * u[0], rel[:, 1] - t * u[1]) - br
                        far = np.where(outside, np.minimum(far, ray), far)
                self._clear = (np.minimum(near, far[blk]) - 1e-6).tolist()
                return self._clear

            def _local_search(self, px: float, py: float) -> tuple[float, float]:
                # The block whose bounding circle is nearest is searched first, then only
                # blocks that could hold a nearer foot: the same answer as a scan of every
                # segment.
                if len(self._bl) > 8:
                    got = self._local_near(px, py)
                    if got is not None:
                        return got
                if len(self._bl) <= 8:  # few blocks: plain Python beats numpy's call overhead
                    lower = [math.hypot(cx - px, cy - py) - r for cx, cy, r in self._bl]
                    b0 = min(range(len(lower)), key=lower.__getitem__)
                else:
                    lower = np.abs(self._bcz - complex(px, py)) - self._br
                    b0 = int(lower.argmin())
                best = self._foot(px, py, *self._blocks[b0]) + (b0,)
                if best[0] >= 1e9:  # no segment holds the foot there: look everywhere
                    cands = range(len(self._blocks))
                elif isinstance(lower, list):
                    reach = math.sqrt(best[0])
                    cands = [b for b, lo in enumerate(lower) if lo <= reach]
                else:
                    cands = (lower <= math.sqrt(best[0])).nonzero()[0].tolist()
                for b in cands:
                    if b != b0:
                        got = self._foot(px, py, *self._blocks[b]) + (b,)
                        if (got[0], got[3]) < (best[0], best[3]):
                            best = got
                return best[1], best[2]

            def _local_near(self, px: float, py: float) -> tuple[float, float] | None:
                # A point within _NEAR of the centre line (a vehicle on or beside the lane):
                # every block that could hold its foot is listed in its cell of a grid, so
                # the blocks are not all measured. Searched nearest first, stopping when no
                # further block can hold a nearer foot: the same answer as a scan of every
                # segment. None for a point further out (the caller scans).
                key = (math.floor(px / _CELL), math.floor(py / _CELL))
                grid = self._grid
                cell = grid.get(key) if grid is not None else None
                if cell is None:
                    cell = self._cell(key)
                if not cell:
                    return None
                if len(cell) == 1:  # one block near: nothing to order or to stop early
                    best = self._foot(px, py, *self._blocks[cell[0]])
                    return None if best[0] > _NEAR * _NEAR else (best[1], best[2])
                bl = self._bl
                order = sorted((math.hypot(bl[b][0] - px, bl[b][1] - py) - bl[b][2], b)
                               for b in cell)
                best = None
                reach = math.inf
                for lo, b in order:
                    if lo > reach:
                        break
                    got = self._foot(px, py, *self._blocks[b]) + (b,)
                    if best is None or (got[0], got[3]) < (best[0], best[3]):
                        best = got
                        if best[0] < 1e9:
                            reach = math.sqrt(best[0])
                if best is None or best[0] > _NEAR * _NEAR:
                    return None
                return best[1], best[2]

            def _cell(self, key: tuple[int, int]) -> list[int]:
                # The blocks whose bounding circle comes within _NEAR of the grid cell ``key``
                # (its square of cells covers the cell), in block order. Cells are filled as
                # agents reach them and kept with the lane: a long lane's whole grid (tens of
                # thousands of cells) would cost more than the cases that use it.
                grid = self._grid
                if grid is None:
                    e = self._br + _NEAR
                    cx, cy = self._bc[:, 0], self._bc[:, 1]
                    self._span = (np.floor((cx - e) / _CELL), np.floor((cx + e) / _CELL),
                                  np.floor((cy - e) / _CELL), np.floor((cy + e) / _CELL))
                    grid = self._grid = {}
                x0, x1, y0, y1 = self._span
                ix, iy = key
                got = grid[key] = np.flatnonzero((x0 <= ix) & (ix <= x1)
                                                 & (y0 <= iy) & (iy <= y1)).tolist()
                return got

            def _foot(self, px: float, py: float, i: int, j: int) -> tuple[float, float, float]:
                """(squared distance, s, r) of the foot on segments i..j-1, 1e9 added to the
                distance when no segment holds it unclipped (then the nearest clipped end)."""
                xl, yl, tx, ty = self._xl, self._yl, self._txl, self._tyl
                dcx, dcy, along = self._dcx, self._dcy, self._alongl
                last = self._nseg - 1
                best_d2, best_k, best_f, best_dx, best_dy = math.inf, i, 0.0, 0.0, 0.0
                for k in range(i, j):
                    ex, ey = px - xl[k], py - yl[k]
                    f = (ex * tx[k] + ey * ty[k]) / along[k]
                    if f < 0.0:
                        if k != 0:
                            if best_d2 < 1e9:
                                continue  # clipped: 1e9 or more, never nearer than a held foot
                            fc = 0.0
                        else:
                            fc = f  # before the start: the first segment's line
                    elif f > 1.0:
                        if k != last:
                            if best_d2 < 1e9:
                                continue
                            fc = 1.0
                        else:
                            fc = f  # past the end: the last segment's line
                    else:
                        fc = f
                    dx, dy = ex - fc * dcx[k], ey - fc * dcy[k]
                    d2 = dx * dx + dy * dy
                    if fc != f:
                        d2 += 1e9  # a segment holding the foot beats one whose end is near
                    if d2 < best_d2:
                        best_d2, best_k, best_f, best_dx, best_dy = d2, k, fc, dx, dy
                r = tx[best_k] * best_dy - ty[best_k] * best_dx
                sl = self._ssl
                return best_d2, sl[best_k] + best_f * (sl[best_k + 1] - sl[best_k]), r

            def to_config(self) -> dict:
                return {"class_path": "pytest_avscenario.sim.maps.MapLaneShape",
                        "config": {"lane": self.data.id}}

            def __repr__(self) -> str:
                return f"MapLaneShape({self.data.id!r}, {self.length:.1f} m)"

        MapLaneShape.__module__ = __name__
        _SHAPE = MapLaneShape
    return _SHAPE


_SHAPE: Any = None


def _either_side(a: np.ndarray, op: Any) -> np.ndarray:
    """``op`` (numpy.minimum or maximum) of each entry of ``a`` and its two neighbours."""
    out = a.copy()
    op(out[1:], a[:-1], out=out[1:])
    op(out[:-1], a[1:], out=out[:-1])
    return out


def _beside(a: np.ndarray) -> np.ndarray:
    """The lesser of each entry's two neighbours in ``a`` (inf past the ends)."""
    out = np.full(len(a), math.inf)
    out[1:] = a[:-1]
    np.minimum(out[:-1], a[1:], out=out[:-1])
    return out


def __getattr__(name: str) -> Any:
    if name == "MapLaneShape":
        return _shape_class()
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


@dataclass(frozen=True, eq=False)
class RoadLane(Lane):
    """A lane of a map: ``id`` is ``"road/section/lane"``, ``kind`` its OpenDRIVE type,
    ``data`` the :class:`~.opendrive.LaneData` it was made from (width along s, successors…)."""

    data: Any = field(default=None, repr=False)

    @property
    def junction(self) -> str:
        """The id of the junction this lane is inside, "" when none."""
        return self.data.junction

    @property
    def speed_limit(self) -> float:
        """[m/s] what IDM drivers cap their target speed at on this lane."""
        return float(self.geometry.speed_limit)

    def __repr__(self) -> str:
        return f"RoadLane({self.id!r})"


class MapLaneIndex(LaneIndex):
    """The lane index of a map: successors as the file links them, neighbours beside each
    lane in its lane section, boxes over the whole sampled lane."""

    def __init__(self, lanes: list[RoadLane], by_id: dict[str, RoadLane]) -> None:
        self.lanes = {l.index: l for l in lanes}
        self.order = list(lanes)
        self.code = {l.index: i for i, l in enumerate(self.order)}
        self.stop_marks = {}
        self.straight_on = {}
        self.drops: dict[tuple, str] = {}
        # what the recorder writes of each lane, shared by every world on the map (its lanes
        # never change): the lane ids by code, and road_meta's entry per lane once computed
        self.id_array = np.asarray([l.id for l in self.order] + [""])
        self.id_code = {l.id: i for i, l in enumerate(self.order)}
        self.lane_records: dict[str, Any] = {}
        boxes = []
        for lane in self.order:
            d = lane.data
            pad = float(d.width.max()) / 2 + 0.05
            boxes.append([d.xy[:, 0].min() - pad, d.xy[:, 1].min() - pad,
                          d.xy[:, 0].max() + pad, d.xy[:, 1].max() + pad])
        self._box = np.asarray(boxes, dtype=float).reshape(-1, 4)
        self.boxes = self._box
        self.successors = {}
        preds: dict[tuple, list[RoadLane]] = {}
        for lane in self.order:
            succ = [by_id[i] for i in lane.data.successors if i in by_id]
            self.successors[lane.index] = succ
            preds[lane.index] = [by_id[i] for i in lane.data.predecessors if i in by_id]
        groups: dict[str, list[RoadLane]] = {}
        for lane in self.order:
            groups.setdefault(lane.group, []).append(lane)
        self._beside = {}
        for lane in self.order:
            self._beside[lane.index] = [o for o in groups[lane.group]
                                        if abs(o.number - lane.number) == 1]
        self.near = {}
        datas = {l.id: l.data for l in self.order}
        for lane in self.order:
            near: list[RoadLane] = []
            cands = (self.successors[lane.index] + preds[lane.index] + self._beside[lane.index]
                     + [s for p in preds[lane.index] for s in self.successors[p.index]]
                     + [p for s in self.successors[lane.index] for p in preds[s.index]])
            for other in cands:
                if other is not lane and other not in near:
                    near.append(other)
            self.near[lane.index] = tuple(near)
            if self.successors[lane.index]:
                # the rule MapLane(ahead=) checks routes by at collection
                self.straight_on[lane.index] = by_id[default_successor(lane.data, datas).id]
            elif float(lane.data.width[-1]) < 0.5:
                # a lane that narrows to nothing with a lane beside it (an acceleration
                # lane, a lane drop): its traffic merges there (behaviours' keep_lane does)
                numbers = {o.number for o in self._beside[lane.index]}
                if lane.number - 1 in numbers:
                    self.drops[lane.index] = "left"
                elif lane.number + 1 in numbers:
                    self.drops[lane.index] = "right"

    def _parallel(self, i: int) -> list[Lane]:
        return list(self._beside[self.order[i].index])

    def fresh(self) -> "MapLaneIndex":
        """A copy for one world: its own stop marks and links, the shared lanes."""
        twin = copy.copy(self)
        twin.stop_marks = {}
        twin.straight_on = dict(self.straight_on)
        twin.drops = dict(self.drops)
        twin.relinked = False
        return twin

    #: whether this world declared a link of its own (:meth:`link`): its routes straight on
    #: are then no longer the map's, which every other world shares
    relinked = True

    def link(self, lane: Lane, nxt: Lane) -> None:
        self.relinked = True
        super().link(lane, nxt)


@dataclass
class _Built:
    """What one map file makes, shared by every world that loads it."""

    data: MapData
    net: Any
    lanes: list[RoadLane]
    by_id: dict[str, RoadLane]
    index: MapLaneIndex
    whole_routes: set = field(default_factory=set)
    routes: dict = field(default_factory=dict)  # lane index -> its default route's lanes


_BUILT: dict[tuple, _Built] = {}
_LOCK = threading.Lock()


def _build(data: MapData, speed_limit: float) -> _Built:
    key = (data.digest, data.path, speed_limit)
    with _LOCK:
        got = _BUILT.get(key)
        if got is None:
            got = _BUILT[key] = _make(data, speed_limit)
    return got


def _make(data: MapData, speed_limit: float) -> _Built:
    from highway_env.road.road import RoadNetwork

    shape = _shape_class()
    drivable = [l for l in data.lanes.values() if l.kind in DRIVABLE]
    # Nodes: the point where a lane ends is the node its successors start from.
    parent: dict[str, str] = {}

    def find(a: str) -> str:
        while parent.setdefault(a, a) != a:
            parent[a] = parent[parent[a]]
            a = parent[a]
        return a

    ids = {l.id for l in drivable}
    for l in drivable:
        for s in l.successors:
            if s in ids:
                parent[find(f"{l.id}>")] = find(f"<{s}")
    names: dict[str, str] = {}

    def node(key: str) -> str:
        root = find(key)
        return names.setdefault(root, f"n{len(names)}")

    # group and number: lanes side by side in a lane section travelling the same way,
    # numbered from the left of the direction of travel
    groups: dict[str, list[LaneData]] = {}
    for l in drivable:
        groups.setdefault(f"{l.road}/{l.section}/{'+' if l.forward else '-'}", []).append(l)
    number: dict[str, int] = {}
    for g, members in groups.items():
        members.sort(key=lambda l: abs(l.lane) if (l.lane < 0) == l.forward else -abs(l.lane))
        for i, l in enumerate(members):
            number[l.id] = i
    net = RoadNetwork()
    lanes: list[RoadLane] = []
    for l in drivable:
        frm, to = node(f"<{l.id}"), node(f"{l.id}>")
        lim = l.speed_limit if math.isfinite(l.speed_limit) else speed_limit
        geom = shape(l, lim)
        net.add_lane(frm, to, geom)
        i = len(net.graph[frm][to]) - 1
        lanes.append(RoadLane(l.id, (frm, to, i), geom, kind=l.kind,
                              direction="forward" if l.forward else "backward",
                              group=f"{l.road}/{l.section}/{'+' if l.forward else '-'}",
                              number=number[l.id], data=l))
    by_id = {l.id: l for l in lanes}
    return _Built(data, net, lanes, by_id, MapLaneIndex(lanes, by_id))


class MapRoad:
    """The lanes of a map file as the world's road (``world.map(path)``)."""

    kind = "map"

    def __init__(self, world: Any, path: Any, *, base: Any = None,
                 speed_limit: float = DEFAULT_SPEED_LIMIT, evaluator: str = "numpy") -> None:
        self.world = world
        try:
            self.data = load(path, base=base, evaluator=evaluator)
        except MapError as exc:
            raise MapError(str(exc), test=world.name) from None
        built = _build(self.data, float(speed_limit))
        self._built = built
        self.net = built.net
        self.all_lanes: list[RoadLane] = built.lanes
        self.crosswalks: list = []
        self.stop_lines: list = []
        self.path = self.data.path
        #: routes (tuples of lanes) whose joints were found to meet, shared by every world on
        #: the map (its lanes never change)
        self.whole_routes: set = built.whole_routes

    def make_index(self) -> MapLaneIndex:
        return self._built.index.fresh()

    # -- places ------------------------------------------------------------------------------------
    def lane(self, lane_id: str) -> RoadLane:
        """The lane ``"road/section/lane"`` (a drivable one)."""
        got = self._built.by_id.get(str(lane_id))
        if got is None:
            other = self.data.lanes.get(str(lane_id))
            why = (f"it is a {other.kind} lane, not a drivable one" if other is not None
                   else f"the map has {len(self._built.by_id)} drivable lanes, e.g. "
                   f"{', '.join(list(self._built.by_id)[:3])}")
            raise SimError(f"{self.path}: no lane {lane_id!r} to drive on ({why})",
                           test=self.world.name)
        return got

    def lanes(self, kind: Any = "driving", min_length: float = 0.0) -> list[RoadLane]:
        """The drivable lanes of ``kind`` (None: all) at least ``min_length`` [m] long."""
        kinds = None if kind is None else ({kind} if isinstance(kind, str) else set(kind))
        return [l for l in self.all_lanes
                if (kinds is None or l.kind in kinds) and l.length >= min_length]

    def closest(self, x: float, y: float) -> Spot:
        """The spot on the drivable lane nearest (x, y) [m] (a shapely STRtree query)."""
        lane = self._built.by_id[self.data.closest(x, y).id]
        s, r = lane.local((x, y))
        return Spot(lane, min(max(s, 0.0), lane.length), r)

    def ahead(self, spot: Spot, d: float, route: Route | None = None) -> Spot:
        """The spot ``d`` [m] further along ``route`` (default: straight on from the spot)."""
        lanes = list(route.lanes) if route is not None else list(
            self.default_route(spot.lane).lanes)
        k = lanes.index(spot.lane) if spot.lane in lanes else 0
        s = spot.s + float(d)
        while s > lanes[k].length and k + 1 < len(lanes):
            s -= lanes[k].length
            k += 1
        if s > lanes[k].length:
            raise SimError(f"{self.path}: {d:g} m ahead of {spot.lane.id!r} at s={spot.s:g} m "
                           f"runs past the end of {lanes[k].id!r}, which has no successor "
                           f"({why_no_successor(self.data, lanes[k].id)}); declare the road "
                           "needed with MapLane(..., ahead=...) to draw only lanes that have it",
                           test=self.world.name)
        return Spot(lanes[k], s, spot.r)

    # -- routes ------------------------------------------------------------------------------------
    def successors(self, lane: RoadLane) -> list[RoadLane]:
        """The lanes traffic on ``lane`` may drive on into (several at a junction)."""
        return list(self.world.lane_index.successors[lane.index])

    def default_route(self, lane: Lane) -> Route:
        """Straight on from ``lane`` (the least turning way through each junction), up to
        64 lanes."""
        index = self.world.lane_index
        # the map's own routes straight on are worked out once per lane and process
        shared = self._built.routes if not getattr(index, "relinked", True) else None
        got = shared.get(lane.index) if shared is not None else None
        if got is None:
            got = tuple(index.continue_route(lane, limit=64))
            if shared is not None:
                shared[lane.index] = got
        return Route(got)

    def route(self, *via: Any) -> Route:
        """The shortest way (by length) from the first lane through each of ``via`` in turn
        (lanes or their ids), across lane sections and junctions."""
        if len(via) < 2:
            raise SimError("map.route(from_lane, to_lane): give at least two lanes",
                           test=self.world.name)
        stops = [self.lane(v) if isinstance(v, str) else v for v in via]
        out: list[RoadLane] = [stops[0]]
        for a, b in zip(stops, stops[1:]):
            out.extend(self._way(a, b)[1:])
        return Route(tuple(out))

    def _way(self, a: RoadLane, b: RoadLane) -> list[RoadLane]:
        succ = self.world.lane_index.successors
        if a is b:
            return [a]
        if not succ.get(a.index):
            raise SimError(f"{self.path}: no way from {a.id!r} to {b.id!r}: {a.id!r} has no "
                           f"successor ({why_no_successor(self.data, a.id)})",
                           test=self.world.name)
        dist = {a.index: 0.0}
        prev: dict[tuple, RoadLane] = {}
        heap = [(0.0, a.id, a)]
        while heap:
            d, _, lane = heapq.heappop(heap)
            if lane is b:
                break
            if d > dist.get(lane.index, math.inf):
                continue
            for nxt in succ.get(lane.index, ()):
                nd = d + lane.length
                if nd < dist.get(nxt.index, math.inf):
                    dist[nxt.index] = nd
                    prev[nxt.index] = lane
                    heapq.heappush(heap, (nd, nxt.id, nxt))
        if b.index not in prev:
            raise SimError(f"{self.path}: no way from {a.id!r} to {b.id!r} along the lanes' "
                           "successors (they are not connected in the driving direction)",
                           test=self.world.name)
        way = [b]
        while way[-1] is not a:
            way.append(prev[way[-1].index])
        return way[::-1]

    def junction_of(self, lane: Lane) -> str:
        """The id of the junction ``lane`` lies in, "" when none."""
        return getattr(lane, "data", None).junction if hasattr(lane, "data") else ""

    def __repr__(self) -> str:
        return f"MapRoad({self.path!r}, {len(self.all_lanes)} drivable lanes)"

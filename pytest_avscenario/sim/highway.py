"""Highways: a one-way carriageway of straight and curved segments, lane drops and on-ramps.

A scenario lays the road out as a list of segments, the way highway-env's own road networks
chain ``StraightLane`` and ``CircularLane`` pieces::

    from pytest_avscenario.sim.highway import arc, straight

    road = world.highway(lanes=3, segments=[straight(200), arc(radius=300, angle=20),
                                            straight(200, lanes=2)], lane_width=3.75)
    ramp = road.on_ramp(at=60, merge_length=80)     # joins the rightmost lane of segment 0
    world.ego(road.at(10, lane=1), speed=25)
    world.car(ramp, s=40, speed=18)                 # merges on its own

Frame and numbering as every road here: the carriageway starts at the origin heading east
(x east, y north [m], headings counter-clockwise), lanes are numbered 0 (leftmost) to the
right, lane 0's centre line is the road's reference line. An ``arc`` turns left for a
positive ``angle`` [deg] and right for a negative one; its ``radius`` [m] is that of the
reference line. A segment with fewer lanes than the one before drops the rightmost lanes
at the boundary (their traffic has to merge left before the end); one with more adds lanes
on the right. An on-ramp (highway-env's ``merge-v0`` layout: a straight approach, a
``SineLane`` S-bend, an acceleration lane beside the rightmost lane that ends) joins a
straight segment. Vehicles on a lane that ends merge into the lane beside it when the gap
there is safe, and wait at the end of their lane when it never is (``b.keep_lane`` does
this on its own; see :mod:`.behaviors`).

Each segment's lanes are highway-env lanes between two nodes (``h0 -> h1 -> ...``), so
highway-env's own vehicles and ``neighbour_vehicles`` (with connected lanes) work on it.
Importing this module imports nothing of highway-env; building a road does.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from .errors import SimError
from .places import Lane, Spot

__all__ = ["Segment", "straight", "arc", "Highway"]


@dataclass(frozen=True)
class Segment:
    """One piece of a highway: ``kind`` "straight" (``length`` [m]) or "arc" (``radius`` [m]
    of the reference line, ``angle`` [deg], positive turning left); ``lanes`` None keeps the
    previous segment's count."""

    kind: str
    length: float = 0.0
    radius: float = math.inf
    angle: float = 0.0
    lanes: int | None = None


def straight(length: float, lanes: int | None = None) -> Segment:
    """A straight segment of ``length`` [m] (``lanes``: a new lane count from here on)."""
    return Segment("straight", length=length, lanes=lanes)


def arc(radius: float, angle: float, lanes: int | None = None) -> Segment:
    """A circular segment: ``radius`` [m] of lane 0's centre line, ``angle`` [deg] turned
    (positive: to the left). Its length along lane 0 is ``radius * angle``."""
    return Segment("arc", radius=radius, angle=angle, lanes=lanes)


def _number(value: Any) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError):
        return math.nan
    return v


class Highway:
    """A one-way highway of segments (see the module); ``kind`` "highway".

    ``lane(i, segment=k)`` is lane ``i`` of segment ``k``; ``at(s, lane=i)`` the spot ``s``
    metres along the road (measured along lane 0, the reference line) in lane ``i``;
    ``on_ramp(...)`` adds a ramp; ``segments`` holds each segment's lanes.
    """

    kind = "highway"

    def __init__(self, world: Any, net: Any, lanes: Any, segments: Any, lane_width: Any,
                 speed_limit: Any) -> None:
        from .engine import Arc, LineType, Straight

        self.world = world
        self.net = net
        self.all_lanes: list[Lane] = []
        self.crosswalks: list = []
        self.stop_lines: list = []
        self.lane_ends: list[Spot] = []  # where a lane ends with traffic in it (drawn)
        self.ramps: list[tuple[Lane, ...]] = []
        self._links: list[tuple[Lane, Lane]] = []
        self._drops: list[Lane] = []
        name = world.name
        n = _number(lanes)
        if not (math.isfinite(n) and n >= 1 and int(n) == n):
            raise SimError(f"highway(lanes={lanes!r}): need a whole number >= 1", test=name)
        w = _number(lane_width)
        if not (math.isfinite(w) and w > 0):
            raise SimError(f"highway(lane_width={lane_width!r}): need a width > 0 [m]", test=name)
        v = _number(speed_limit)
        if not (math.isfinite(v) and v > 0):
            raise SimError(f"highway(speed_limit={speed_limit!r}): need a speed > 0 [m/s]",
                           test=name)
        if segments is None:
            segments = [straight(1000.0)]
        try:
            segments = list(segments)
        except TypeError:
            segments = None
        if not segments or not all(isinstance(g, Segment) for g in segments):
            raise SimError(f"highway(segments={segments!r}): give a non-empty list of "
                           "straight(length) and arc(radius, angle) from "
                           "pytest_avscenario.sim.highway", test=name)
        self.lane_width = w
        self.speed_limit = v
        self.segments: list[list[Lane]] = []
        self.seg_specs: list[Segment] = []
        self._starts: list[float] = []  # station [m] (along lane 0) where each segment starts
        # CONTINUOUS_LINE is drawn as one straight stroke (a chord on a curve); CONTINUOUS in
        # short pieces that follow it.
        N, S, C, CC = (LineType.NONE, LineType.STRIPED, LineType.CONTINUOUS_LINE,
                       LineType.CONTINUOUS)
        p = np.array([0.0, 0.0])  # lane 0's centre at the segment start
        h = 0.0  # heading there [rad]
        count = int(n)
        station = 0.0
        for k, seg in enumerate(segments):
            what = f"highway segment {k} ({seg.kind})"
            if seg.lanes is not None:
                c = _number(seg.lanes)
                if not (math.isfinite(c) and c >= 1 and int(c) == c):
                    raise SimError(f"{what}: lanes={seg.lanes!r}: need a whole number >= 1",
                                   test=name)
                count = int(c)
            left = np.array([-math.sin(h), math.cos(h)])
            lanes_k: list[Lane] = []
            if seg.kind == "straight":
                L = _number(seg.length)
                if not (math.isfinite(L) and L > 0):
                    raise SimError(f"{what}: length={seg.length!r}: need > 0 [m]", test=name)
                u = np.array([math.cos(h), math.sin(h)])
                for i in range(count):
                    a = p - left * (i * w)
                    g = Straight(a, a + u * L, width=w, speed_limit=v,
                                 line_types=(C if i == count - 1 else S, C if i == 0 else N))
                    lanes_k.append(self._lane(k, i, g))
                p_next, h_next, length0 = p + u * L, h, L
            elif seg.kind == "arc":
                R = _number(seg.radius)
                ang = _number(seg.angle)
                span = (count - 1) * w + w / 2
                if not (math.isfinite(ang) and ang != 0 and abs(ang) < 360):
                    raise SimError(f"{what}: angle={seg.angle!r}: need a non-zero angle "
                                   "[deg] within (-360, 360), positive to the left", test=name)
                if not (math.isfinite(R) and R > 0):
                    raise SimError(f"{what}: radius={seg.radius!r}: need > 0 [m]", test=name)
                if ang > 0 and R <= w / 2:
                    raise SimError(f"{what}: radius={R:g} m is too small for the lane width",
                                   test=name)
                if ang < 0 and R <= span:
                    raise SimError(f"{what}: radius={R:g} m is too small for {count} lanes "
                                   f"of {w:g} m turning right (need > {span:g} m)", test=name)
                phi = math.radians(ang)
                sign = 1.0 if ang > 0 else -1.0
                centre = p + left * (sign * R)
                start_phase = h - sign * math.pi / 2
                for i in range(count):
                    radius = R + sign * i * w  # lanes to the right lie outside a left turn
                    g = Arc(centre, radius, start_phase, start_phase + phi,
                            clockwise=ang > 0, width=w, speed_limit=v,
                            line_types=(CC if i == count - 1 else S, CC if i == 0 else N))
                    lanes_k.append(self._lane(k, i, g))
                h_next = h + phi
                p_next = centre + R * np.array([math.cos(start_phase + phi),
                                                math.sin(start_phase + phi)])
                length0 = R * abs(phi)
            else:
                raise SimError(f"{what}: unknown segment kind; use straight() or arc()",
                               test=name)
            if self.segments:
                prev = self.segments[-1]
                for i, lane in enumerate(prev):
                    if i < len(lanes_k):
                        self._links.append((lane, lanes_k[i]))
                    else:
                        self._drops.append(lane)
                        self.lane_ends.append(lane.end)
            self.segments.append(lanes_k)
            self.seg_specs.append(seg)
            self._starts.append(station)
            station += length0
            p, h = p_next, h_next
        self.length = station  # [m] along lane 0

    def _lane(self, k: int, i: int, g: Any, frm: str | None = None, to: str | None = None,
              lane_id: str | None = None, group: str | None = None) -> Lane:
        frm = frm if frm is not None else f"h{k}"
        to = to if to is not None else f"h{k + 1}"
        self.net.add_lane(frm, to, g)
        idx = len(self.net.graph[frm][to]) - 1
        lane = Lane(lane_id or f"lane[{i}]@{k}", (frm, to, idx), g, kind="travel",
                    direction="forward", group=group if group is not None else f"seg{k}",
                    number=i)
        self.all_lanes.append(lane)
        return lane

    def _after_index(self) -> None:
        idx = self.world.lane_index
        for a, b in self._links:
            idx.link(a, b)
        for lane in self._drops:
            idx.add_drop(lane, "left")

    # -- places ----------------------------------------------------------------------------------
    def lane(self, i: int = 0, segment: int = 0) -> Lane:
        """Lane ``i`` (0 leftmost) of segment ``segment`` (0 first)."""
        try:
            lanes = self.segments[segment]
        except (IndexError, TypeError):
            raise SimError(f"highway.lane(segment={segment!r}): segments 0.."
                           f"{len(self.segments) - 1}", test=self.world.name) from None
        try:
            if isinstance(i, bool) or int(i) != i or i < 0:
                raise IndexError
            return lanes[int(i)]
        except (IndexError, TypeError, ValueError):
            raise SimError(f"highway.lane({i!r}): segment {segment} has lanes "
                           f"0..{len(lanes) - 1}", test=self.world.name) from None

    @property
    def lanes(self) -> list[Lane]:
        """The lanes of the first segment, 0 leftmost."""
        return self.segments[0]

    def at(self, s: float, lane: int = 0) -> Spot:
        """The spot ``s`` [m] along the road (measured along lane 0) in lane ``lane``.

        On an arc the lanes to the outside are longer than lane 0: the spot is at the same
        angle into the arc as station ``s`` on lane 0.
        """
        st = _number(s)
        if not (math.isfinite(st) and 0.0 <= st <= self.length):
            raise SimError(f"highway.at(s={s!r}): the road runs 0..{self.length:g} m along "
                           "lane 0", test=self.world.name)
        k = max(j for j, start in enumerate(self._starts) if start <= st + 1e-9)
        into = st - self._starts[k]
        target = self.lane(lane, k)
        lane0 = self.segments[k][0]
        if self.seg_specs[k].kind == "arc":
            into *= target.length / lane0.length
        return Spot(target, min(into, target.length))

    # -- on-ramps ------------------------------------------------------------------------------------
    def on_ramp(self, at: float, merge_length: float = 100.0, *, ramp_length: float = 100.0,
                bend_length: float = 60.0, offset: float | None = None) -> Lane:
        """Add an on-ramp joining the rightmost lane; returns the ramp's first lane.

        The acceleration lane runs beside the rightmost lane from station ``at`` [m] for
        ``merge_length`` [m] and then ends; before it, an S-bend (highway-env's
        ``SineLane``) of ``bend_length`` [m] brings the ramp in from ``offset`` [m] further
        right (default 1.75 lane widths), after a straight approach of ``ramp_length`` [m].
        The acceleration lane must lie on one straight segment. Build ramps before placing
        agents.
        """
        from .engine import LineType, Sine, Straight

        name = self.world.name
        if self.world.agents:
            raise SimError("highway.on_ramp(): add ramps before placing agents", test=name)
        vals = {"at": at, "merge_length": merge_length, "ramp_length": ramp_length,
                "bend_length": bend_length}
        for key, val in vals.items():
            x = _number(val)
            if not (math.isfinite(x) and (x >= 0 if key == "at" else x > 0)):
                raise SimError(f"highway.on_ramp({key}={val!r}): need a finite length "
                               f"{'>= 0' if key == 'at' else '> 0'} [m]", test=name)
        at, merge_length = float(at), float(merge_length)
        w = self.lane_width
        off = 1.75 * w if offset is None else _number(offset)
        if not (math.isfinite(off) and off >= w):
            raise SimError(f"highway.on_ramp(offset={offset!r}): need >= the lane width "
                           f"({w:g} m) so the ramp starts off the carriageway", test=name)
        ks = [j for j, start in enumerate(self._starts) if start <= at + 1e-9]
        k = max(ks) if ks else 0
        seg_end = self._starts[k] + self.segments[k][0].length
        if self.seg_specs[k].kind != "straight" or at + merge_length > seg_end + 1e-6:
            raise SimError(f"highway.on_ramp(at={at:g}, merge_length={merge_length:g}): the "
                           f"acceleration lane must lie on one straight segment (segment {k} "
                           f"is a {self.seg_specs[k].kind} from {self._starts[k]:g} to "
                           f"{seg_end:g} m)", test=name)
        right = self.segments[k][-1]
        s0 = at - self._starts[k]
        g_r = right.geometry
        N, C, CC = LineType.NONE, LineType.CONTINUOUS_LINE, LineType.CONTINUOUS
        j = len(self.ramps)
        v = self.speed_limit
        a0 = g_r.position(s0 - bend_length - float(ramp_length), -w - off)
        a1 = g_r.position(s0 - bend_length, -w - off)
        ramp = self._lane(k, 0, Straight(a0, a1, width=w, line_types=(C, C), speed_limit=v),
                          frm=f"ramp{j}.a", to=f"ramp{j}.b", lane_id=f"ramp{j}",
                          group=f"ramp{j}")
        # S-bend: centre line -off/2 * cos(pi s / L) about a base line off/2 right of the
        # acceleration lane, so it starts ``off`` right of it and ends on it, both tangent.
        b0 = g_r.position(s0 - bend_length, -w - off / 2)
        b1 = g_r.position(s0, -w - off / 2)
        bend = self._lane(k, 0, Sine(b0, b1, off / 2, math.pi / bend_length, -math.pi / 2,
                                     width=w, line_types=(CC, CC), speed_limit=v),
                          frm=f"ramp{j}.b", to=f"ramp{j}.c", lane_id=f"ramp{j}.bend",
                          group=f"ramp{j}.bend")
        c0 = g_r.position(s0, -w)
        c1 = g_r.position(s0 + merge_length, -w)
        accel = self._lane(k, len(self.segments[k]), Straight(
            c0, c1, width=w, line_types=(C, N), speed_limit=v), frm=f"ramp{j}.c",
            to=f"ramp{j}.d", lane_id=f"ramp{j}.merge", group=f"seg{k}")
        self._drops.append(accel)
        self.lane_ends.append(accel.end)
        self.ramps.append((ramp, bend, accel))
        self.world.reindex(self.all_lanes)
        self._after_index()
        return ramp

    def merge_lane(self, ramp: int = 0) -> Lane:
        """The acceleration lane of on-ramp ``ramp`` (0 the first added)."""
        try:
            return self.ramps[ramp][2]
        except (IndexError, TypeError):
            raise SimError(f"highway.merge_lane({ramp!r}): this highway has "
                           f"{len(self.ramps)} on-ramp(s)", test=self.world.name) from None

    def default_route(self, lane: Lane) -> Any:
        """Straight on from ``lane`` to the end of the road (or of its lane)."""
        from .places import Route

        return Route(tuple(self.world.lane_index.continue_route(lane, limit=256)))

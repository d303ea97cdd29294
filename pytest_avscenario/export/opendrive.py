"""The road a case was built on, written as ASAM OpenDRIVE (.xodr) with scenariogeneration.

The world's frame is OpenDRIVE's inertial frame as it is: x east, y north [m], headings
counter-clockwise from east (highway-env only *draws* y down; its numbers are these), so no
coordinate changes. What is written per road kind:

* ``straight`` (one-way, n lanes): one road whose reference line is the left edge of lane 0,
  lanes ``-1..-n`` (lane i of the world is OpenDRIVE lane ``-(i + 1)``).
* ``two_way``: one road whose reference line is the centre line; forward lanes (east) are the
  right lanes ``-1..-n``, backward lanes the left lanes ``1..n``, a parking lane outermost on
  each side; a median is a ``median`` lane of half its width on each side of the centre line.
* ``highway``: one road of straight and arc geometries (reference line: the left edge of
  lane 0), one lane section per segment so lane drops keep their lane counts. An on-ramp is
  not written (its agents are exported as trajectories in world coordinates, which do not
  need the road).
* ``intersection``: its four arms, each a two-way road from the box edge outward; the
  junction's connecting roads are not written, so every agent is exported as its recorded
  trajectory (world positions) and the file says so in a comment.

:func:`road_xodr` returns the document and a :class:`RoadMap` saying which OpenDRIVE lane
each world lane became (for lane-change targets) and what was left out (``notes``).
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from dataclasses import dataclass, field
from typing import Any

__all__ = ["RoadMap", "road_xodr"]


@dataclass
class RoadMap:
    """Where the world's lanes went: ``lanes`` maps a world lane id (``"lane[0]"``) to
    ``(road id, OpenDRIVE lane id)``; ``exact`` False when the road was written only in part
    (its agents then follow trajectories); ``notes`` say what was left out."""

    kind: str
    lanes: dict[str, tuple[int, int]] = field(default_factory=dict)
    exact: bool = True
    notes: list[str] = field(default_factory=list)


def _xodr() -> Any:
    from scenariogeneration import xodr

    return xodr


def _driving(w: float, solid: bool = False, kind: str = "driving") -> Any:
    xodr = _xodr()
    lane = xodr.Lane(getattr(xodr.LaneType, kind), a=float(w))
    mark = xodr.RoadMarkType.solid if solid else xodr.RoadMarkType.broken
    lane.add_roadmark(xodr.RoadMark(mark, 0.15))
    return lane


def _centre(solid: bool = True) -> Any:
    xodr = _xodr()
    lane = xodr.Lane()
    lane.add_roadmark(xodr.RoadMark(xodr.RoadMarkType.solid if solid else xodr.RoadMarkType.none,
                                    0.15))
    return lane


def _one_way_section(s: float, n: int, w: float) -> Any:
    xodr = _xodr()
    sec = xodr.LaneSection(float(s), _centre())
    for i in range(n):
        sec.add_right_lane(_driving(w, solid=i == n - 1))
    return sec


def _two_way_section(n: int, w: float, parking: float, median: float,
                     kinds: tuple[str, str] = ("driving", "driving")) -> tuple[Any, int]:
    """A lane section with ``n`` lanes each way; returns it and the id offset of lane 0
    (1 with a median lane, else 0)."""
    xodr = _xodr()
    sec = xodr.LaneSection(0.0, _centre(solid=median == 0))
    off = 0
    if median > 0:
        sec.add_right_lane(_driving(median / 2, solid=True, kind="median"))
        sec.add_left_lane(_driving(median / 2, solid=True, kind="median"))
        off = 1
    for i in range(n):
        last = i == n - 1 and not parking
        sec.add_right_lane(_driving(w, solid=last))
        sec.add_left_lane(_driving(w, solid=last))
    if parking:
        sec.add_right_lane(_driving(parking, solid=True, kind="parking"))
        sec.add_left_lane(_driving(parking, solid=True, kind="parking"))
    return sec, off


def _road(rid: int, x: float, y: float, h: float, geometries: list[Any], sections: list[Any],
          name: str) -> Any:
    xodr = _xodr()
    pv = xodr.PlanView(float(x), float(y), float(h))
    for g in geometries:
        pv.add_geometry(g)
    lanes = xodr.Lanes()
    for sec in sections:
        lanes.add_lanesection(sec)
    return xodr.Road(rid, pv, lanes, name=name)


def road_xodr(road: Any, name: str = "road") -> tuple[bytes, RoadMap]:
    """The OpenDRIVE document (UTF-8 bytes) of a world's road and where its lanes went.

    ``road`` is the world's road object (``world.road``); an unknown kind (a road network of
    several intersections) is written as an empty OpenDRIVE document with a note."""
    xodr = _xodr()
    odr = xodr.OpenDrive(name, revMajor="1", revMinor="7")
    kind = getattr(road, "kind", "") or type(road).__name__
    rmap = RoadMap(kind=kind)
    if kind == "straight":
        n, w = len(road.lanes), float(road.lane_width)
        odr.add_road(_road(1, 0.0, w / 2, 0.0, [xodr.Line(float(road.length))],
                           [_one_way_section(0.0, n, w)], "straight"))
        rmap.lanes = {lane.id: (1, -(i + 1)) for i, lane in enumerate(road.lanes)}
    elif kind == "two_way":
        n, w = len(road.forward), float(road.lane_width)
        parking = road._parking.get("forward")
        pw = parking.width if parking is not None else 0.0
        sec, off = _two_way_section(n, w, pw, float(road.median))
        odr.add_road(_road(1, 0.0, 0.0, 0.0, [xodr.Line(float(road.length))], [sec], "two_way"))
        for i in range(n):
            rmap.lanes[road.forward[i].id] = (1, -(i + 1 + off))
            rmap.lanes[road.backward[i].id] = (1, i + 1 + off)
        if parking is not None:
            rmap.lanes[parking.id] = (1, -(n + 1 + off))
            rmap.lanes[road._parking["backward"].id] = (1, n + 1 + off)
    elif kind == "highway":
        _highway(odr, road, rmap)
    elif kind == "intersection":
        _intersection_arms(odr, road, rmap)
    else:
        rmap.exact = False
        rmap.notes.append(f"a {kind} road is not written as OpenDRIVE; every agent follows "
                          "its recorded trajectory in world coordinates")
    if odr.roads:
        odr.adjust_roads_and_lanes()
    root = odr.get_element()
    header = root.find("header")
    if header is not None:
        header.set("date", "1970-01-01T00:00:00")  # the same road writes the same file
    for note in rmap.notes:
        root.insert(1, ET.Comment(f" {note} ".replace("--", "- ")))
    ET.indent(root)
    return ET.tostring(root, encoding="utf-8", xml_declaration=True) + b"\n", rmap


def _highway(odr: Any, road: Any, rmap: RoadMap) -> None:
    xodr = _xodr()
    w = float(road.lane_width)
    geoms, sections = [], []
    s = 0.0  # along the reference line (the left edge of lane 0)
    for k, (seg, lanes) in enumerate(zip(road.seg_specs, road.segments)):
        sections.append(_one_way_section(s, len(lanes), w))
        for i, lane in enumerate(lanes):
            rmap.lanes[lane.id] = (1, -(i + 1))
        if seg.kind == "straight":
            geoms.append(xodr.Line(float(seg.length)))
            s += float(seg.length)
        else:
            phi = math.radians(float(seg.angle))
            sign = 1.0 if phi > 0 else -1.0
            # the left edge lies w/2 nearer the centre of a left turn, farther from a right one
            radius = float(seg.radius) - sign * w / 2
            geoms.append(xodr.Arc(sign / radius, length=radius * abs(phi)))
            s += radius * abs(phi)
    odr.add_road(_road(1, 0.0, w / 2, 0.0, geoms, sections, "highway"))
    if road.ramps:
        rmap.notes.append(f"{len(road.ramps)} on-ramp(s) not written; agents on them follow "
                          "their recorded trajectories")


_UNIT = {"north": (0.0, 1.0), "east": (1.0, 0.0), "south": (0.0, -1.0), "west": (-1.0, 0.0)}


def _intersection_arms(odr: Any, inter: Any, rmap: RoadMap) -> None:
    xodr = _xodr()
    rmap.exact = False
    rmap.notes.append("intersection: the four arms are written as roads, the junction's "
                      "connecting roads are not; every agent follows its recorded trajectory "
                      "(world positions), so the scenario replays as recorded")
    o = inter.origin
    for k, d in enumerate(("north", "east", "south", "west")):
        u = _UNIT[d]
        start = (o[0] + u[0] * inter.half, o[1] + u[1] * inter.half)
        sec, off = _two_way_section(inter.n_lanes, float(inter.lane_width), 0.0,
                                    2 * float(inter.median))
        rid = k + 1
        odr.add_road(_road(rid, start[0], start[1], math.atan2(u[1], u[0]),
                           [xodr.Line(float(inter.approach_length))], [sec], f"{d} arm"))
        # driving away from the centre is the road's direction: exits on the right
        for i in range(inter.n_lanes):
            rmap.lanes[inter.exit(d, i).id] = (rid, -(i + 1 + off))
            rmap.lanes[inter.approach(d, i).id] = (rid, i + 1 + off)

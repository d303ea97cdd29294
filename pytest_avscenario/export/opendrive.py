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
* ``intersection``: a junction (id 100). Its four arms are two-way roads 1-4 (north, east,
  south, west) from the box edge outward, whose predecessor is the junction; each of the
  world's connectors (straight from every lane, left from lane 0, right from the outermost)
  is a connecting road (101…) of one right lane whose reference line is that lane's left
  edge: a line across the box or a quarter arc about the box corner, so its lane centre is
  the connector's path exactly. Each connecting road runs from its incoming arm (contact
  point ``start``) to its outgoing arm's start, with lane links and one junction
  ``connection`` per connecting road. Crosswalks, stop lines and the speed limit are not
  written.

Every built road also records its reference line and lane centres
(:attr:`RoadMap.refs`, :attr:`RoadMap.centre_t`), so :func:`lane_position` places a world
point by road, lane, s and offset (OpenSCENARIO's ``LanePosition``) and :func:`world_xy`
goes back.

:func:`road_xodr` returns the document and a :class:`RoadMap` saying which OpenDRIVE lane
each world lane became (for lane-change targets) and what was left out (``notes``).
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from dataclasses import dataclass, field
from typing import Any

import numpy as np

__all__ = ["RoadMap", "road_xodr", "lane_position", "JUNCTION_ID"]


@dataclass
class RoadMap:
    """Where the world's lanes went: ``lanes`` maps a world lane id (``"lane[0]"``) to
    ``(road id, OpenDRIVE lane id)``; ``exact`` False when the road was written only in part
    (its agents then follow trajectories); ``notes`` say what was left out."""

    kind: str
    lanes: dict[str, tuple[int, int]] = field(default_factory=dict)
    exact: bool = True
    notes: list[str] = field(default_factory=list)
    #: road id -> its reference line as ``(s0, x0, y0, h0, length, curvature)`` pieces
    refs: dict[int, list[tuple]] = field(default_factory=dict)
    #: (road id, lane id) -> t [m] of the lane's centre (constant along the built roads)
    centre_t: dict[tuple[int, int], float] = field(default_factory=dict)
    junction: int | None = None
    #: the junction's connections: (incoming road, connecting road, incoming lane)
    connections: list[tuple[int, int, int]] = field(default_factory=list)
    #: a map's file (its path as the world loaded it); its lanes are placed by ``locate``
    map_path: str = ""
    locate: Any = None


def _xodr() -> Any:
    from ._writers import load

    return load()[0]


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


#: the header name of every road this module writes (a replay tells them from map files so)
HEADER_NAME = "pytest-avscenario built road"


def road_xodr(road: Any, name: str = HEADER_NAME) -> tuple[bytes, RoadMap]:
    """The OpenDRIVE document (UTF-8 bytes) of a world's road and where its lanes went.

    ``road`` is the world's road object (``world.road``); NotImplementedError for a kind
    not written (a road network of several intersections: OpenDRIVE needs at least one road,
    so there is no empty document to write)."""
    xodr = _xodr()
    odr = xodr.OpenDrive(name, revMajor="1", revMinor="7")
    kind = getattr(road, "kind", "") or type(road).__name__
    rmap = RoadMap(kind=kind)
    links: list[tuple] = []
    if kind == "straight":
        n, w = len(road.lanes), float(road.lane_width)
        odr.add_road(_road(1, 0.0, w / 2, 0.0, [xodr.Line(float(road.length))],
                           [_one_way_section(0.0, n, w)], "straight"))
        rmap.lanes = {lane.id: (1, -(i + 1)) for i, lane in enumerate(road.lanes)}
        rmap.refs[1] = [(0.0, 0.0, w / 2, 0.0, float(road.length), 0.0)]
        rmap.centre_t = {(1, -(i + 1)): -(i + 0.5) * w for i in range(n)}
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
        m2 = float(road.median) / 2
        rmap.refs[1] = [(0.0, 0.0, 0.0, 0.0, float(road.length), 0.0)]
        for i in range(n):
            rmap.centre_t[(1, -(i + 1 + off))] = -(m2 + (i + 0.5) * w)
            rmap.centre_t[(1, i + 1 + off)] = m2 + (i + 0.5) * w
        if parking is not None:
            rmap.centre_t[(1, -(n + 1 + off))] = -(m2 + n * w + pw / 2)
            rmap.centre_t[(1, n + 1 + off)] = m2 + n * w + pw / 2
    elif kind == "highway":
        _highway(odr, road, rmap)
    elif kind == "intersection":
        links = _intersection(odr, road, rmap)
    else:
        raise NotImplementedError(f"a {kind} road is not written as OpenDRIVE")
    if odr.roads:
        odr.adjust_roads_and_lanes()
    root = odr.get_element()
    header = root.find("header")
    if header is not None:
        header.set("date", "1970-01-01T00:00:00")  # the same road writes the same file
    if links:
        _add_links(root, links, rmap)
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
            if geoms and geoms[-1][0] == "line":  # one line across lane sections: two in a
                geoms[-1] = ("line", geoms[-1][1] + float(seg.length))  # row are redundant
            else:
                geoms.append(("line", float(seg.length)))
            s += float(seg.length)
        else:
            phi = math.radians(float(seg.angle))
            sign = 1.0 if phi > 0 else -1.0
            # the left edge lies w/2 nearer the centre of a left turn, farther from a right one
            radius = float(seg.radius) - sign * w / 2
            geoms.append(("arc", radius * abs(phi), sign / radius))
            s += radius * abs(phi)
    odr.add_road(_road(1, 0.0, w / 2, 0.0,
                       [xodr.Line(g[1]) if g[0] == "line" else xodr.Arc(g[2], length=g[1])
                        for g in geoms], sections, "highway"))
    x, y, h, s0 = 0.0, w / 2, 0.0, 0.0
    pieces = []
    for g in geoms:  # where each piece starts, for LanePositions
        k = 0.0 if g[0] == "line" else g[2]
        pieces.append((s0, x, y, h, g[1], k))
        if k == 0.0:
            x, y = x + g[1] * math.cos(h), y + g[1] * math.sin(h)
        else:
            h1 = h + k * g[1]
            x, y, h = x + (math.sin(h1) - math.sin(h)) / k, y - (math.cos(h1) - math.cos(h)) / k, h1
        s0 += g[1]
    rmap.refs[1] = pieces
    n = max(len(lanes) for lanes in road.segments)
    rmap.centre_t = {(1, -(i + 1)): -(i + 0.5) * w for i in range(n)}
    if road.ramps:
        rmap.notes.append(f"{len(road.ramps)} on-ramp(s) not written; agents on them follow "
                          "their recorded trajectories")


_UNIT = {"north": (0.0, 1.0), "east": (1.0, 0.0), "south": (0.0, -1.0), "west": (-1.0, 0.0)}
_ARMS = ("north", "east", "south", "west")
JUNCTION_ID = 100  # the intersection's junction; its connecting roads are 101, 102…


def _intersection(odr: Any, inter: Any, rmap: RoadMap) -> list[tuple]:
    """The four arms as two-way roads from the box edge outward and the junction's connecting
    roads (one lane each, along the lane centre the world's connector follows); returns the
    links to add once the document exists: ``(road id, predecessor, successor, lane links)``."""
    xodr = _xodr()
    o = np.asarray(inter.origin, dtype=float)
    n, w, L = int(inter.n_lanes), float(inter.lane_width), float(inter.approach_length)
    m2, H = float(inter.median), float(inter.half)
    off = 1 if m2 > 0 else 0
    arm_id = {d: k + 1 for k, d in enumerate(_ARMS)}
    links: list[tuple] = []
    for d in _ARMS:
        u = np.array(_UNIT[d])
        start = o + u * H
        rid = arm_id[d]
        h = math.atan2(u[1], u[0])
        sec, _ = _two_way_section(n, w, 0.0, 2 * m2)
        odr.add_road(_road(rid, start[0], start[1], h, [xodr.Line(L)], [sec], f"{d} arm"))
        rmap.refs[rid] = [(0.0, float(start[0]), float(start[1]), h, L, 0.0)]
        # driving away from the centre is the road's direction: exits on the right
        for i in range(n):
            t = m2 + (i + 0.5) * w
            rmap.lanes[inter.exit(d, i).id] = (rid, -(i + 1 + off))
            rmap.lanes[inter.approach(d, i).id] = (rid, i + 1 + off)
            rmap.centre_t[(rid, -(i + 1 + off))] = -t
            rmap.centre_t[(rid, i + 1 + off)] = t
        links.append((rid, ("junction", JUNCTION_ID, None), None, {}))
    rid = JUNCTION_ID
    for d in _ARMS:
        u = np.array(_UNIT[d])
        right_in = np.array([-u[1], u[0]])
        for turn in ("straight", "left", "right"):
            d2 = inter.turn_target(d, turn)
            for i in range(n):
                key = (d, turn, i)
                if key not in inter._conn:
                    continue
                lane = inter._conn[key]
                rid += 1
                c = m2 + (i + 0.5) * w  # the lane centre's distance from the centre line
                # reference line: the connector lane's left edge (half a lane left of its centre)
                p = o + u * H + right_in * (c - w / 2)
                h = math.atan2(-u[1], -u[0])
                if turn == "straight":
                    geom, length, curv = xodr.Line(2 * H), 2 * H, 0.0
                else:
                    radius = H + c - w / 2 if turn == "left" else H - c + w / 2
                    curv = (1.0 if turn == "left" else -1.0) / radius
                    length = radius * math.pi / 2
                    geom = xodr.Arc(curv, length=length)
                odr.add_road(_connecting_road(rid, p, h, geom, w, f"{d} to {d2} ({turn})"))
                rmap.refs[rid] = [(0.0, float(p[0]), float(p[1]), h, float(length), curv)]
                rmap.lanes[lane.id] = (rid, -1)
                rmap.centre_t[(rid, -1)] = -w / 2
                j = min(i, n - 1)
                links.append((rid, ("road", arm_id[d], "start"), ("road", arm_id[d2], "start"),
                              {-1: (i + 1 + off, -(j + 1 + off))}))
                rmap.connections.append((arm_id[d], rid, i + 1 + off))
    rmap.junction = JUNCTION_ID
    return links


def _connecting_road(rid: int, p: Any, h: float, geom: Any, w: float, name: str) -> Any:
    xodr = _xodr()
    sec = xodr.LaneSection(0.0, _centre(solid=False))
    lane = xodr.Lane(xodr.LaneType.driving, a=float(w))
    lane.add_roadmark(xodr.RoadMark(xodr.RoadMarkType.none, 0.15))
    sec.add_right_lane(lane)
    pv = xodr.PlanView(float(p[0]), float(p[1]), float(h))
    pv.add_geometry(geom)
    lanes = xodr.Lanes()
    lanes.add_lanesection(sec)
    return xodr.Road(rid, pv, lanes, road_type=JUNCTION_ID, name=name)


def _link_element(kind: str, ref: tuple) -> ET.Element:
    el = ET.Element(kind, elementType=ref[0], elementId=str(ref[1]))
    if ref[2]:
        el.set("contactPoint", ref[2])
    return el


def _add_links(root: ET.Element, links: list[tuple], rmap: RoadMap) -> None:
    """Road and lane links, and the junction's connections, written into the document."""
    roads = {int(r.get("id")): r for r in root.findall("road")}
    for rid, pred, succ, lane_links in links:
        road = roads[rid]
        old = road.find("link")
        if old is not None:
            road.remove(old)
        link = ET.Element("link")
        if pred is not None:
            link.append(_link_element("predecessor", pred))
        if succ is not None:
            link.append(_link_element("successor", succ))
        road.insert(0, link)
        for lane in road.iter("lane"):
            ids = lane_links.get(int(lane.get("id")))
            if ids is None:
                continue
            old = lane.find("link")
            if old is not None:
                lane.remove(old)
            ll = ET.Element("link")
            ET.SubElement(ll, "predecessor", id=str(ids[0]))
            ET.SubElement(ll, "successor", id=str(ids[1]))
            lane.insert(0, ll)
    if rmap.junction is not None:
        junction = ET.SubElement(root, "junction", name="intersection", id=str(rmap.junction),
                                 type="default")
        for k, (incoming, connecting, from_lane) in enumerate(rmap.connections):
            con = ET.SubElement(junction, "connection", id=str(k), incomingRoad=str(incoming),
                                connectingRoad=str(connecting), contactPoint="start")
            ET.SubElement(con, "laneLink", attrib={"from": str(from_lane), "to": "-1"})


# ------------------------------------------------------------------ positions on the roads


def _project(geoms: list[tuple], x: float, y: float) -> tuple[float, float, float]:
    """``(s, t, distance outside the road's length)`` of point (x, y) on a reference line of
    lines and arcs ``(s0, x0, y0, h0, length, curvature)``: s along it, t to its left."""
    best = None
    for s0, x0, y0, h0, length, k in geoms:
        dx, dy = x - x0, y - y0
        if abs(k) < 1e-12:
            u = math.cos(h0) * dx + math.sin(h0) * dy
            t = -math.sin(h0) * dx + math.cos(h0) * dy
        else:
            r = 1.0 / k  # signed: the centre lies at r to the left
            cx, cy = x0 - r * math.sin(h0), y0 + r * math.cos(h0)
            a0 = math.atan2(y0 - cy, x0 - cx)
            a = math.atan2(y - cy, x - cx)
            da = math.atan2(math.sin(a - a0), math.cos(a - a0))
            u = da * r
            t = r - math.copysign(math.hypot(x - cx, y - cy), r)
        out = max(-u, u - length, 0.0)
        cand = (s0 + min(max(u, 0.0), length), t, out)
        if best is None or (cand[2], abs(cand[1])) < (best[2], abs(best[1])):
            best = cand
    assert best is not None
    return best


def lane_position(rmap: RoadMap, lane_id: str, x: float, y: float) -> tuple[int, int, float, float] | None:
    """``(road id, OpenDRIVE lane id, s [m], offset [m])`` of point (x, y) on the world lane
    ``lane_id``, offset from the lane's centre along the road's t axis (left of the reference
    line positive); None when the lane was not written or the point is off its road's ends."""
    ref = rmap.lanes.get(str(lane_id))
    if ref is None:
        return rmap.locate(str(lane_id), x, y) if rmap.locate is not None else None
    rid, lid = ref
    if rid in rmap.refs and (rid, lid) in rmap.centre_t:
        s, t, out = _project(rmap.refs[rid], x, y)
        if out > 1e-6:
            return None
        return rid, lid, s, t - rmap.centre_t[(rid, lid)]
    return None


def world_xy(rmap: RoadMap, road_id: int, lane_id: int, s: float, offset: float) -> tuple[float, float]:
    """The world point (x, y) [m] of a ``LanePosition`` on a road :func:`road_xodr` wrote
    (the inverse of :func:`lane_position`)."""
    for s0, x0, y0, h0, length, k in rmap.refs[road_id]:
        if s <= s0 + length + 1e-9:
            break
    u = s - s0
    if abs(k) < 1e-12:
        x, y, h = x0 + u * math.cos(h0), y0 + u * math.sin(h0), h0
    else:
        h = h0 + k * u
        x = x0 + (math.sin(h) - math.sin(h0)) / k
        y = y0 - (math.cos(h) - math.cos(h0)) / k
    t = rmap.centre_t[(road_id, lane_id)] + offset
    return x - t * math.sin(h), y + t * math.cos(h)


# ------------------------------------------------------------------ a map-based world's road

_SECTIONS: dict[str, dict[tuple[str, int], tuple[float, float]]] = {}


def _sections(data: Any) -> dict[tuple[str, int], tuple[float, float]]:
    """``(road, section index) -> (s start, s end)`` of a map file, read once per file."""
    got = _SECTIONS.get(data.digest)
    if got is None:
        got = {}
        for _, road in ET.iterparse(data.path):
            if road.tag != "road":
                continue
            length = float(road.get("length"))
            starts = [float(sec.get("s")) for sec in road.findall("lanes/laneSection")]
            for k, s0 in enumerate(starts):
                got[(road.get("id"), k)] = (s0, min(starts[k + 1], length) if k + 1 < len(starts)
                                            else length)
            road.clear()
        _SECTIONS[data.digest] = got
    return got


def _lane_samples(data: Any, lane: Any) -> tuple[np.ndarray, np.ndarray]:
    """The road's s [m] at each of ``lane``'s centre samples, ascending, and the samples
    (N, 2) in that order."""
    s0, s1 = _sections(data)[(lane.road, lane.section)]
    ss = np.linspace(s0, s1, len(lane.s))
    xy = lane.xy if lane.forward else lane.xy[::-1]
    return ss, xy


def map_roadmap(road: Any) -> RoadMap:
    """The :class:`RoadMap` of a map-based world (``world.map(path)``): nothing is written,
    the export references the map file; ``locate`` places a world point by road, lane, s and
    offset on it."""
    data = road.data
    rmap = RoadMap(kind="map", map_path=str(data.path))

    def locate(lane_id: str, x: float, y: float) -> tuple[str, int, float, float] | None:
        lane = data.lanes.get(lane_id)
        if lane is None:
            return None
        ss, xy = _lane_samples(data, lane)
        ref = data.reference[lane.road]
        d = np.hypot(xy[:, 0] - x, xy[:, 1] - y)
        j = min(int(np.argmin(d)), len(ss) - 2)
        seg = xy[j + 1] - xy[j]
        f = float(np.clip(np.dot([x - xy[j, 0], y - xy[j, 1]], seg) / max(np.dot(seg, seg), 1e-12),
                          0.0, 1.0))
        s = float(ss[j] + f * (ss[j + 1] - ss[j]))
        for _ in range(4):  # onto the reference line's normal through the point
            rx, ry, rh = (float(v[0]) for v in ref(np.array([s])))
            s = float(np.clip(s + math.cos(rh) * (x - rx) + math.sin(rh) * (y - ry), ss[0], ss[-1]))
        rx, ry, rh = (float(v[0]) for v in ref(np.array([s])))
        t = -math.sin(rh) * (x - rx) + math.cos(rh) * (y - ry)
        cx, cy = np.interp(s, ss, xy[:, 0]), np.interp(s, ss, xy[:, 1])
        tc = -math.sin(rh) * (cx - rx) + math.cos(rh) * (cy - ry)
        return lane.road, lane.lane, s, t - tc

    rmap.locate = locate
    return rmap


def map_point(road: Any, road_id: str, lane_id: int, s: float, offset: float) -> tuple[str, float, float]:
    """The world lane id and point (x, y) [m] of a ``LanePosition`` on a map (the inverse of
    :func:`map_roadmap`'s ``locate``)."""
    data = road.data
    for (rid, k), (s0, s1) in _sections(data).items():
        if rid == str(road_id) and s0 - 1e-9 <= s <= s1 + 1e-9:
            lane = data.lanes.get(f"{rid}/{k}/{int(lane_id)}")
            if lane is not None:
                break
    else:
        raise LookupError(f"{data.path}: no lane {lane_id} of road {road_id} at s = {s:g} m")
    ss, xy = _lane_samples(data, lane)
    rx, ry, rh = (float(v[0]) for v in data.reference[lane.road](np.array([float(s)])))
    cx, cy = np.interp(s, ss, xy[:, 0]), np.interp(s, ss, xy[:, 1])
    tc = -math.sin(rh) * (cx - rx) + math.cos(rh) * (cy - ry)
    t = tc + offset
    return lane.id, rx - t * math.sin(rh), ry + t * math.cos(rh)

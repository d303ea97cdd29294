"""Lane tracking: every lane of a world's road, its neighbourhood and stop marks, and where
each agent is on it.

:class:`LaneIndex` replaces highway-env's ``get_closest_lane_index`` — a scan of every lane
of the network on every step of every vehicle — with tracking: an agent keeps its lane while
it stays inside it and otherwise checks only that lane's precomputed neighbours and
successors, falling back to a vectorized bounding-box query over all lanes only when it is
off every candidate (pedestrians on a sidewalk, a car off the road). It also answers the
routing questions agents ask while driving (the lanes straight on, the lane a lane change
aims at). The world owns one (``world.lane_index``); roads register their stop lines and
crosswalks in it.
"""

from __future__ import annotations

import math
from typing import Any, Iterable

import numpy as np

from .errors import SimError
from .geometry import wrap_to_pi
from .places import Lane

__all__ = ["LaneIndex"]


class LaneIndex:
    """All lanes of one road with their neighbourhoods, stop marks and a tracker for agents."""

    def __init__(self, lanes: Iterable[Lane]) -> None:
        self.lanes: dict[tuple, Lane] = {}
        for lane in lanes:
            self.lanes[lane.index] = lane
        self.order = list(self.lanes.values())
        self.code = {l.index: i for i, l in enumerate(self.order)}
        self.stop_marks: dict[tuple, list[tuple[float, str]]] = {}
        # Roads whose lanes continue across nodes they share with other lanes (a highway's
        # segments) name each lane's continuation here; :meth:`continue_route` follows it.
        self.straight_on: dict[tuple, Lane] = {}
        # Lanes that end with traffic still in them (a lane drop, an on-ramp's acceleration
        # lane): the side ("left"/"right") their traffic merges to.
        self.drops: dict[tuple, str] = {}
        boxes = []
        for lane in self.order:
            g = lane.geometry
            curved = (math.isfinite(getattr(g, "radius", math.inf))
                      or getattr(g, "amplitude", 0.0) != 0.0)
            ss = np.linspace(0.0, g.length, 17 if curved else 2)
            half = g.width_at(0.0) / 2 + 0.05
            pts = np.array([g.position(s, r) for s in ss for r in (-half, half)])
            boxes.append([pts[:, 0].min(), pts[:, 1].min(), pts[:, 0].max(), pts[:, 1].max()])
        self._box = np.asarray(boxes, dtype=float)
        self.boxes = self._box  # (lanes, 4): xmin, ymin, xmax, ymax [m] of each lane in `order`
        self.successors: dict[tuple, list[Lane]] = {}
        by_from: dict[str, list[Lane]] = {}
        by_to: dict[str, list[Lane]] = {}
        for lane in self.order:
            by_from.setdefault(lane.index[0], []).append(lane)
            by_to.setdefault(lane.index[1], []).append(lane)
        for lane in self.order:
            self.successors[lane.index] = list(by_from.get(lane.index[1], []))
        self.near: dict[tuple, tuple[Lane, ...]] = {}
        for i, lane in enumerate(self.order):
            near: list[Lane] = []
            for other in (self.successors[lane.index] + by_from[lane.index[0]]
                          + by_to[lane.index[1]] + self._parallel(i)):
                if other is not lane and other not in near:
                    near.append(other)
            self.near[lane.index] = tuple(near)

    def _parallel(self, i: int) -> list[Lane]:
        """Straight lanes beside lane ``i`` (same or opposite heading, overlapping boxes)."""
        me = self.order[i]
        if math.isfinite(getattr(me.geometry, "radius", math.inf)):
            return []
        b = self._box
        pad = 2.0 * me.width
        hit = ((b[:, 0] <= b[i, 2] + pad) & (b[:, 2] >= b[i, 0] - pad)
               & (b[:, 1] <= b[i, 3] + pad) & (b[:, 3] >= b[i, 1] - pad))
        out = []
        for j in np.flatnonzero(hit):
            o = self.order[j]
            if j == i or math.isfinite(getattr(o.geometry, "radius", math.inf)):
                continue
            if abs(math.sin(o.geometry.heading - me.geometry.heading)) < 0.05:
                out.append(o)
        return out

    def link(self, lane: Lane, nxt: Lane) -> None:
        """Declare ``nxt`` the lane that carries straight on from ``lane``."""
        self.straight_on[lane.index] = nxt

    def add_drop(self, lane: Lane, side: str = "left") -> None:
        """Declare that ``lane`` ends and its traffic merges to ``side``."""
        self.drops[lane.index] = side

    def add_stop(self, lane: Lane, s: float, kind: str) -> None:
        marks = self.stop_marks.setdefault(lane.index, [])
        marks.append((float(s), kind))
        marks.sort()

    # -- queries ---------------------------------------------------------------------------------
    def containing(self, x: float, y: float) -> list[tuple[Lane, float, float]]:
        """Lanes whose area contains the point, with its ``(s, r)`` on each."""
        b = self._box
        hit = np.flatnonzero((b[:, 0] <= x) & (x <= b[:, 2]) & (b[:, 1] <= y) & (y <= b[:, 3]))
        out = []
        for j in hit:
            lane = self.order[j]
            g = lane.geometry
            s, r = g.local_coordinates((x, y))
            if 0.0 <= s <= g.length and abs(r) <= g.width_at(s) / 2:
                out.append((lane, s, r))
        return out

    def on_road(self, x: float, y: float) -> bool:
        return bool(self.containing(x, y))

    def first_lane_middle(self, pts: list, cum: list) -> float:
        """Arc length [m] along a polyline at the middle of the first travel lane it crosses.

        -1 when it crosses none.
        """
        total = cum[-1]
        first = None
        for u in np.arange(0.0, total, 0.1):
            i = min(int(np.searchsorted(cum, u, side="right")) - 1, len(pts) - 2)
            seg = cum[i + 1] - cum[i]
            f = (u - cum[i]) / seg if seg > 0 else 0.0
            x = pts[i][0] + f * (pts[i + 1][0] - pts[i][0])
            y = pts[i][1] + f * (pts[i + 1][1] - pts[i][1])
            lanes = [l for l, _, _ in self.containing(x, y) if l.kind != "parking"]
            if first is None:
                if lanes:
                    first = (lanes[0], u)
            elif first[0] not in lanes:
                return (first[1] + u) / 2
        return (first[1] + total) / 2 if first is not None else -1.0

    # -- tracking --------------------------------------------------------------------------------
    def track(self, agent: Any) -> None:
        """Update ``agent``'s route progress and current lane after it moved."""
        self.progress(agent)
        self.current_lane(agent)

    def progress(self, agent: Any) -> None:
        """Advance ``route_index`` and set ``route_s``/``route_r`` [m] on the route lane."""
        route = agent.plan
        if not route:
            return
        pos = agent.position
        ri = agent.route_index
        g = route[ri].geometry
        s, r = g.local_coordinates(pos)
        while s > g.length and ri + 1 < len(route):
            ri += 1
            g = route[ri].geometry
            s, r = g.local_coordinates(pos)
        agent.route_index, agent.route_s, agent.route_r = ri, s, r
        # what was asked and answered, for whoever asks the same lane about this agent before
        # it moves again (another agent's leader(): a second projection per step on a map)
        agent.tracked = (float(pos[0]), float(pos[1]), g, s, r)

    def current_lane(self, agent: Any) -> None:
        """Set ``lane_index``, ``lane``, ``lane_r`` [m] and ``is_on_road`` (after :meth:`progress`)."""
        pos = agent.position
        x, y = float(pos[0]), float(pos[1])
        route = agent.plan
        ri = agent.route_index
        cur = agent.lane_index
        if cur is not None:
            if route and route[ri].index == cur:
                s, r = agent.route_s, agent.route_r
                g = route[ri].geometry
            else:
                g = self.lanes[cur].geometry
                s, r = g.local_coordinates(pos)
            if 0.0 <= s <= g.length and abs(r) <= g.width_at(s) / 2:
                agent.lane_r = r
                agent.is_on_road = True
                return
            candidates: tuple[Lane, ...] = (self.lanes[cur],) + self.near[cur]
        else:
            candidates = ()
        pedestrian = agent.kind == "pedestrian"
        on_route = {l.index for l in route[ri:ri + 2]} if route else set()
        heading = float(agent.heading)
        best = None
        for lane in candidates:
            g = lane.geometry
            s, r = g.local_coordinates(pos)
            inside = 0.0 <= s <= g.length and abs(r) <= g.width_at(s) / 2
            if not inside and lane.index != cur:
                continue
            score = self._score(lane, s, r, heading, pedestrian, on_route)
            if inside and (best is None or not best[3] or score < best[0]):
                best = (score, lane, r, True)
            elif best is None:
                best = (score, lane, r, False)
        if best is None or not best[3]:
            found = self.containing(x, y)
            if found:
                score, _, lane, r = min(
                    (self._score(l, s, r, heading, pedestrian, on_route), i, l, r)
                    for i, (l, s, r) in enumerate(found))
                best = (score, lane, r, True)
        if best is None:
            agent.lane_index = None if pedestrian else cur
            agent.lane_r = math.nan
            agent.is_on_road = False
            return
        _, lane, r, inside = best
        if pedestrian and not inside:
            agent.lane_index, agent.lane, agent.lane_r, agent.is_on_road = None, None, math.nan, False
            return
        agent.lane_index = lane.index
        agent.lane = lane.geometry
        agent.lane_r = r
        if inside:
            agent.is_on_road = True
        else:
            # Past a lane's end but still on its asphalt (highway-env's own on_lane margin).
            s, _ = lane.geometry.local_coordinates(pos)
            agent.is_on_road = bool(abs(r) <= lane.geometry.width_at(s) / 2
                                    and -2.5 <= s <= lane.geometry.length + 2.5)

    @staticmethod
    def _score(lane: Lane, s: float, r: float, heading: float, pedestrian: bool,
               on_route: set) -> float:
        g = lane.geometry
        d = abs(r) + max(s - g.length, 0.0) + max(-s, 0.0)
        if not pedestrian:
            d += abs(wrap_to_pi(heading - g.heading_at(s)))
        if lane.index in on_route:
            d -= 0.5
        return d

    # -- re-planning -------------------------------------------------------------------------------
    def continue_route(self, lane: Lane, limit: int = 32) -> list[Lane]:
        """``lane`` and the lanes that carry straight on from it (through intersections)."""
        route = [lane]
        on = {lane}  # (lanes compare by identity: a set answers "already on it" at once)
        while len(route) < limit:
            nxt = self.straight_on.get(route[-1].index)
            if nxt is not None:
                if nxt in on:
                    break
                route.append(nxt)
                on.add(nxt)
                continue
            g = route[-1].geometry
            h_end = g.heading_at(g.length)
            p_end = g.position(g.length, 0.0)
            nxt = None
            for cand in self.successors[route[-1].index]:
                cg = cand.geometry
                if abs(wrap_to_pi(cg.heading_at(cg.length) - h_end)) > 0.1:
                    continue
                if float(np.hypot(*(cg.position(0.0, 0.0) - p_end))) > 0.5:
                    continue
                nxt = cand
                break
            if nxt is None or nxt in on:
                break
            route.append(nxt)
            on.add(nxt)
        return route

    def resolve_lane_change(self, agent: Any, to: Any) -> Lane:
        """The lane a lane change ``to`` ("left", "right", "out", a number, a Lane) aims at."""
        if isinstance(to, Lane):
            return to
        here = agent.route_lane
        group = [l for l in self.order if l.group == here.group and here.group]
        if to == "out":
            g = here.geometry
            s = agent.route_s
            cands = [(abs(l.local(here.position(s))[1]), l) for l in self._parallel(self.order.index(here))
                     if l.kind == "travel" and abs(wrap_to_pi(l.geometry.heading - g.heading)) < 0.1]
            if not cands:
                raise SimError(f"no travel lane next to {here.id!r} to pull out into",
                               test=agent.world.name, agent=agent.name)
            return min(cands, key=lambda c: c[0])[1]
        if to == "left":
            number = here.number - 1
        elif to == "right":
            number = here.number + 1
        elif isinstance(to, (int, np.integer)):
            number = int(to)
        else:
            raise SimError(f"change_lane(to={to!r}): use 'left', 'right', a lane number or a Lane",
                           test=agent.world.name, agent=agent.name)
        for lane in group:
            if lane.number == number:
                return lane
        raise SimError(f"change_lane(to={to!r}) from {here.id!r}: no such lane "
                       f"(lanes {sorted(l.number for l in group)})",
                       test=agent.world.name, agent=agent.name)

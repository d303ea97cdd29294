"""A road network of several intersections joined by two-way link roads, in one world.

``world.road_network()`` hands out a :class:`Network`; a scenario places intersections on it
and connects arms that face each other, then routes agents across the whole network::

    net = world.road_network()
    a = net.intersection("A", at=(0, 0), approach_length=60, lane_width=5.5)
    b = net.intersection("B", at=(0, 200), approach_length=60, lane_width=5.5)
    net.connect(a, "north", b, "south")  # a 200 - 2 * (a.half + 60) m link, both directions
    world.ego(a.approach("south"), route=net.route(a.route("south"), b.route("south", "left")))

Each intersection is a full :class:`~.roads.Intersection` (stop lines, crosswalks, turns),
its lanes and crosswalks named with its name first (``"A.south.in[0]"``, ``"B.west"``). A link
continues the exit lanes of one arm into the approach lanes of the other (and back), so
agents, the autopilot and highway-env's own IDM driver drive from one intersection to the
next without a seam.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from .errors import SimError
from .places import Lane, Route
from .roads import _OPPOSITE, DIRECTIONS, Intersection, _Road

__all__ = ["Network", "Link"]


class Link(_Road):
    """The two-way road between arm ``arm_a`` of ``a`` and arm ``arm_b`` of ``b``.

    ``forward`` lanes carry traffic from ``a`` to ``b`` (lane ``i`` continues ``a.exit(arm_a,
    i)`` into ``b.approach(arm_b, i)``), ``backward`` lanes from ``b`` to ``a``.
    """

    kind = "link"

    def __init__(self, world: Any, net: Any, a: Intersection, arm_a: str, b: Intersection,
                 arm_b: str) -> None:
        from .engine import LineType, Straight

        super().__init__(world)
        self.a, self.arm_a, self.b, self.arm_b = a, arm_a, b, arm_b
        self.name = f"{a.name}.{arm_a}~{b.name}.{arm_b}"
        N, S, C = LineType.NONE, LineType.STRIPED, LineType.CONTINUOUS_LINE
        n = a.n_lanes
        self.forward: list[Lane] = []
        self.backward: list[Lane] = []
        for lanes, frm, to, fwd in ((self.forward, (a, arm_a), (b, arm_b), True),
                                    (self.backward, (b, arm_b), (a, arm_a), False)):
            (x, xa), (y, ya) = frm, to
            for i in range(n):
                out, into = x.exit(xa, i), y.approach(ya, i)
                outer = C if i == n - 1 else S
                inner = C if i == 0 and (fwd or x.median > 0) else N
                g = Straight(out.position(out.length), into.position(0.0), width=out.width,
                             line_types=(outer, inner),
                             speed_limit=float(out.geometry.speed_limit))
                lanes.append(self._lane(
                    net, out.index[1], into.index[0], g, f"{x.name}.{xa}~{y.name}.{ya}[{i}]",
                    "travel", "forward" if fwd else "backward",
                    f"{x.name}.{xa}~{y.name}.{ya}", i))

    @property
    def length(self) -> float:
        """Length [m] between the two arms' ends."""
        return self.forward[0].length

    def lane(self, i: int = 0, direction: str = "forward") -> Lane:
        """Lane ``i`` (0 next to the centre line) of ``direction`` ("forward": from a to b)."""
        return self._lane_of(i, direction, "link",
                             f"forward drives from {self.a.name!r} to {self.b.name!r}")

    def __repr__(self) -> str:
        return f"Link({self.name!r}, {self.length:g} m)"


class Network(_Road):
    """Intersections placed anywhere in the world frame and the links between their arms."""

    kind = "network"

    def __init__(self, world: Any, net: Any) -> None:
        super().__init__(world)
        self._net = net
        self.intersections: dict[str, Intersection] = {}
        self.links: list[Link] = []
        self._linked: dict[tuple[str, str], Link] = {}

    # -- building --------------------------------------------------------------------------------
    def _building(self, what: str) -> None:
        if self.world.agents:
            raise SimError(f"{what}: build the whole network before placing agents",
                           test=self.world.name)

    def intersection(self, name: str | None = None, at: Any = (0.0, 0.0), lanes: int = 1,
                     approach_length: float = 100.0, *, lane_width: float = 3.5,
                     speed_limit: float = 13.9, crosswalk_width: float = 3.0,
                     corner: float = 6.0, median: float = 0.0) -> Intersection:
        """A four-way intersection centred ``at`` (x, y) [m], called ``name`` (default "A",
        "B", … in order); other arguments as :meth:`World.intersection`."""
        if name is None:
            name = chr(ord("A") + len(self.intersections))
        name = str(name)
        self._building(f"intersection({name!r})")
        if not name or any(c in name for c in ".~[]>") or name in self.intersections:
            why = "is taken" if name in self.intersections else "must be non-empty without . ~ [ ] >"
            raise SimError(f"intersection(name={name!r}): the name {why}", test=self.world.name)
        from highway_env.road.road import RoadNetwork

        # Built on a scratch network first, so that a refused intersection leaves no lanes
        # behind in the world's network.
        inter = Intersection(self.world, RoadNetwork(), lanes, float(approach_length),
                             lane_width, speed_limit, crosswalk_width, corner, median, at=at,
                             name=name)
        for other in self.intersections.values():
            clash = self._overlap(inter, other)
            if clash:
                raise SimError(f"intersection({name!r}) at {_fmt(inter.origin)} overlaps "
                               f"{other.name!r} at {_fmt(other.origin)} ({clash}); move it or "
                               "shorten approach_length", test=self.world.name)
        for lane in inter.all_lanes:  # fresh node names: the same (from, to, i) indices
            self._net.add_lane(lane.index[0], lane.index[1], lane.geometry)
        self.intersections[name] = inter
        self._adopt(inter)
        return inter

    @staticmethod
    def _overlap(a: Intersection, b: Intersection) -> str:
        """Why the footprints (box plus arms, a plus sign) of ``a`` and ``b`` overlap, or ''."""
        def bars(x: Intersection) -> list[tuple[float, float, float, float]]:
            ox, oy = x.origin
            reach, wide = x.half + x.approach_length, x.half
            return [(ox - reach, oy - wide, ox + reach, oy + wide),
                    (ox - wide, oy - reach, ox + wide, oy + reach)]

        for p in bars(a):
            for q in bars(b):
                if p[0] < q[2] - 1e-6 and q[0] < p[2] - 1e-6 and p[1] < q[3] - 1e-6 \
                        and q[1] < p[3] - 1e-6:
                    return "their arms cross or run into each other"
        return ""

    def connect(self, a: Intersection, arm_a: str, b: Intersection, arm_b: str) -> Link:
        """A two-way link road from arm ``arm_a`` of ``a`` to arm ``arm_b`` of ``b``.

        The arms must face each other on one line (e.g. ``a``'s north arm and ``b``'s south
        arm with ``b`` due north of ``a``), with the same lanes, and leave a gap between their
        ends; the link fills the gap.
        """
        what = f"connect({getattr(a, 'name', a)!r}, {arm_a!r}, {getattr(b, 'name', b)!r}, {arm_b!r})"
        self._building(what)
        for x in (a, b):
            if not isinstance(x, Intersection) or self.intersections.get(x.name) is not x:
                raise SimError(f"{what}: {x!r} is not an intersection of this network",
                               test=self.world.name)
        if a is b:
            raise SimError(f"{what}: connect two different intersections", test=self.world.name)
        for x, arm in ((a, arm_a), (b, arm_b)):
            if arm not in DIRECTIONS:
                raise SimError(f"{what}: unknown arm {arm!r}; use one of {list(DIRECTIONS)}",
                               test=self.world.name)
            if (x.name, arm) in self._linked:
                raise SimError(f"{what}: the {arm} arm of {x.name!r} is already connected "
                               f"({self._linked[(x.name, arm)].name})", test=self.world.name)
        if arm_b != _OPPOSITE[arm_a]:
            raise SimError(f"{what}: the arms must face each other ({arm_a} to "
                           f"{_OPPOSITE[arm_a]}); bends between intersections are not supported",
                           test=self.world.name)
        if (a.n_lanes, a.lane_width, a.median) != (b.n_lanes, b.lane_width, b.median):
            raise SimError(f"{what}: the arms differ (lanes, lane_width, median: "
                           f"{(a.n_lanes, a.lane_width, a.median * 2)} vs "
                           f"{(b.n_lanes, b.lane_width, b.median * 2)})", test=self.world.name)
        end = a.exit(arm_a).position(a.exit(arm_a).length)
        start = b.approach(arm_b).position(0.0)
        h = a.exit(arm_a).heading_at(0.0)
        d = start - end
        along = d[0] * math.cos(h) + d[1] * math.sin(h)
        across = -d[0] * math.sin(h) + d[1] * math.cos(h)
        if abs(across) > 1e-6:
            raise SimError(f"{what}: the arms are not in line ({b.name!r}'s {arm_b} arm is "
                           f"{abs(across):.2f} m to the side of {a.name!r}'s {arm_a} arm)",
                           test=self.world.name)
        if along < 0.5:
            raise SimError(f"{what}: the arms' ends are {along:.2f} m apart; need at least 0.5 m "
                           "for the link (move the intersections apart or shorten "
                           "approach_length)", test=self.world.name)
        link = Link(self.world, self._net, a, arm_a, b, arm_b)
        self.links.append(link)
        self._linked[(a.name, arm_a)] = self._linked[(b.name, arm_b)] = link
        self._adopt(link)
        return link

    def _adopt(self, part: _Road) -> None:
        """Take ``part``'s lanes into the network and re-index (stop marks carry over)."""
        self.all_lanes.extend(part.all_lanes)
        self.world.reindex(self.all_lanes)
        if hasattr(part, "_after_index"):
            part._after_index()
        self.crosswalks.extend(part.crosswalks)
        self.stop_lines.extend(part.stop_lines)

    # -- places and routes ----------------------------------------------------------------------
    def __getitem__(self, name: str) -> Intersection:
        try:
            return self.intersections[name]
        except KeyError:
            raise SimError(f"no intersection {name!r}; the network has "
                           f"{list(self.intersections)}", test=self.world.name) from None

    def junction_of(self, lane: Lane) -> Intersection | None:
        """The intersection ``lane`` belongs to (approach, connector or exit), or None."""
        for inter in self.intersections.values():
            if inter.owns(lane):
                return inter
        return None

    def junction_ahead(self, agent: Any) -> Intersection | None:
        """The intersection ``agent`` is in or driving toward along its route (the one
        nearest it when it has no route, e.g. a pedestrian), or None."""
        plan = getattr(agent, "plan", None) or []
        ri = getattr(agent, "route_index", 0)
        for lane in plan[ri:]:
            inter = self.junction_of(lane)
            if inter is not None and (lane.kind == "connector" or inter.arm_of(lane)):
                return inter
        if not self.intersections:
            return None
        p = np.asarray(agent.position, dtype=float)
        return min(self.intersections.values(),
                   key=lambda x: float(np.hypot(*(x.origin - p))))

    def route(self, *parts: Any) -> Route:
        """One route through ``parts`` (lanes, routes such as ``a.route("south", "left")``,
        or lists of lanes), joined by the shortest way along the network between each part's
        last lane and the next one's first."""
        if not parts:
            raise SimError("network.route(): give at least one lane or route", test=self.world.name)
        lanes: list[Lane] = []
        for part in parts:
            seq = list(part.lanes) if isinstance(part, Route) else (
                [part] if isinstance(part, Lane) else list(part) if isinstance(part, (list, tuple))
                else None)
            if not seq or not all(isinstance(l, Lane) for l in seq):
                raise SimError(f"network.route(): {part!r} is not a lane, a route or a list of "
                               "lanes", test=self.world.name)
            for l in seq:
                if self.world.lane_index.lanes.get(l.index) is not l:
                    raise SimError(f"network.route(): lane {l.id!r} is not on this network",
                                   test=self.world.name)
            if lanes:
                if seq[0] is lanes[-1]:
                    seq = seq[1:]
                else:
                    lanes.extend(self._way(lanes[-1], seq[0]))
            lanes.extend(seq)
        return Route(tuple(lanes))

    def _way(self, frm: Lane, to: Lane) -> list[Lane]:
        """The lanes strictly between ``frm`` and ``to`` on the shortest way (fewest lanes)."""
        succ = self.world.lane_index.successors
        prev: dict[tuple, Lane | None] = {frm.index: None}
        queue = [frm]
        for lane in queue:
            if lane is to:
                break
            for nxt in succ[lane.index]:
                if nxt.index not in prev:
                    prev[nxt.index] = lane
                    queue.append(nxt)
        if to.index not in prev:
            raise SimError(f"network.route(): no way from {frm.id!r} to {to.id!r} (connect "
                           "the arms between them?)", test=self.world.name)
        way: list[Lane] = []
        lane = prev[to.index]
        while lane is not None and lane is not frm:
            way.append(lane)
            lane = prev[lane.index]
        return way[::-1]

    def default_route(self, lane: Lane) -> Route:
        """Straight on from ``lane``, through every intersection on the way."""
        return Route(tuple(self.world.lane_index.continue_route(lane, limit=64)))

    def __repr__(self) -> str:
        return (f"Network(intersections={list(self.intersections)}, "
                f"links={[l.name for l in self.links]})")


def _fmt(p: Any) -> str:
    return f"({float(p[0]):g}, {float(p[1]):g})"

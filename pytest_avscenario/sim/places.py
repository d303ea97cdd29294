"""The small vocabulary of places a scenario names: lanes, spots on them, lines, crosswalks, routes.

Roads hand these out (``road.lane(0)``, ``inter.approach("south")``, ``inter.stop_line("south")``,
``inter.crosswalk("north")``, ``inter.route("south", "left")``, ``inter.centre``) and the world
takes them back when agents are placed, so scenario code reads as the situation it describes::

    world.ego(inter.stop_line("south").before(case.d_ego), route=inter.route("south", "left"))
    world.pedestrian(inter.crosswalk("west"), behavior=b.cross(wait=2.0))

Everything here is plain frozen data over highway-env lane geometry (duck-typed: any object with
``position(s, r)``, ``local_coordinates(xy)``, ``heading_at(s)``, ``length``, ``width_at(s)``);
nothing imports highway-env. Lateral offsets ``r`` are positive to the left of the direction of
travel; lanes are numbered from the centre line (or the left edge) outward, lane 0 leftmost.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Sequence

import numpy as np

__all__ = ["Lane", "Spot", "Point", "Path", "StopLine", "Crosswalk", "Route", "distance"]


def _xy(p: Any) -> np.ndarray:
    """World position [m] of a place, an agent-like object or an (x, y) pair."""
    if hasattr(p, "position"):
        p = p.position
    return np.asarray(p, dtype=float).reshape(2)


def distance(a: Any, b: Any) -> float:
    """Euclidean distance [m] between two places, points or agents (their ``position``)."""
    d = _xy(a) - _xy(b)
    return float(math.hypot(d[0], d[1]))


@dataclass(frozen=True, eq=False)
class Lane:
    """One lane of a road, with its readable ``id`` (e.g. ``"road[0]"``, ``"south.in[1]"``).

    ``index`` is highway-env's ``(from_node, to_node, i)``; ``geometry`` the highway-env lane.
    ``direction`` is ``"forward"``/``"backward"`` on two-way roads, the arm (``"south"``…) on
    intersections, ``""`` otherwise. ``group`` names the carriageway (``"forward"``,
    ``"south.in"``…) and ``number`` the lane's place in it, 0 leftmost.
    """

    id: str
    index: tuple[str, str, int]
    geometry: Any = field(repr=False)
    kind: str = "travel"  # "travel", "parking", "connector"
    direction: str = ""
    group: str = ""  # lanes side by side in one carriageway share a group, numbered from 0
    number: int = 0

    @property
    def length(self) -> float:
        """Length along the centre line [m]."""
        return float(self.geometry.length)

    @property
    def width(self) -> float:
        """Width [m]."""
        return float(self.geometry.width_at(0.0))

    def at(self, s: float, r: float = 0.0) -> "Spot":
        """The spot ``s`` metres along this lane (``r`` metres left of its centre line)."""
        return Spot(self, float(s), float(r))

    @property
    def start(self) -> "Spot":
        return Spot(self, 0.0)

    @property
    def end(self) -> "Spot":
        return Spot(self, self.length)

    def position(self, s: float, r: float = 0.0) -> np.ndarray:
        """World position [m] of lane coordinates ``(s, r)`` [m]."""
        return np.asarray(self.geometry.position(float(s), float(r)), dtype=float)

    def heading_at(self, s: float) -> float:
        """Heading [rad] of the lane at ``s`` [m]."""
        return float(self.geometry.heading_at(float(s)))

    def local(self, xy: Any) -> tuple[float, float]:
        """Lane coordinates ``(s, r)`` [m] of a world position, place or agent."""
        s, r = self.geometry.local_coordinates(_xy(xy))
        return float(s), float(r)

    def __repr__(self) -> str:
        return f"Lane({self.id!r})"


@dataclass(frozen=True)
class Spot:
    """A place ``s`` metres along a lane, ``r`` metres left of its centre line."""

    lane: Lane
    s: float
    r: float = 0.0

    @property
    def position(self) -> np.ndarray:
        """World position [m]."""
        return self.lane.position(self.s, self.r)

    @property
    def heading(self) -> float:
        """Lane heading [rad] here."""
        return self.lane.heading_at(self.s)

    def before(self, d: float) -> "Spot":
        """The spot ``d`` metres upstream of this one on the same lane."""
        return Spot(self.lane, self.s - float(d), self.r)

    def after(self, d: float) -> "Spot":
        """The spot ``d`` metres downstream of this one on the same lane."""
        return Spot(self.lane, self.s + float(d), self.r)

    def distance_to(self, other: Any) -> float:
        """Euclidean distance [m] to another place, point or agent."""
        return distance(self, other)


@dataclass(frozen=True)
class Point:
    """A bare world position [m], e.g. the centre of an intersection."""

    x: float
    y: float

    @property
    def position(self) -> np.ndarray:
        return np.array([self.x, self.y])

    def distance_to(self, other: Any) -> float:
        """Euclidean distance [m] to another place, point or agent."""
        return distance(self, other)


@dataclass(frozen=True)
class Path:
    """A polyline a pedestrian walks, as ``(N, 2)`` world points [m] (N >= 2)."""

    points: tuple[tuple[float, float], ...]

    @classmethod
    def through(cls, points: Sequence[Sequence[float]]) -> "Path":
        pts = tuple((float(p[0]), float(p[1])) for p in points)
        if len(pts) < 2:
            raise ValueError(f"a path needs at least 2 points, got {len(pts)}")
        return cls(pts)

    @property
    def array(self) -> np.ndarray:
        return np.asarray(self.points, dtype=float)

    @property
    def length(self) -> float:
        """Total length [m]."""
        return float(np.sum(np.hypot(*np.diff(self.array, axis=0).T)))

    @property
    def position(self) -> np.ndarray:
        """Where the path starts [m]."""
        return self.array[0]

    def reversed(self) -> "Path":
        return Path(self.points[::-1])


@dataclass(frozen=True)
class StopLine:
    """A stop line across ``lane`` at ``s`` [m]; ``approach`` names the intersection arm."""

    lane: Lane
    s: float
    approach: str = ""

    @property
    def position(self) -> np.ndarray:
        return self.lane.position(self.s)

    def before(self, d: float) -> Spot:
        """The spot on the approach lane ``d`` metres before the line (the usual ego placement)."""
        return Spot(self.lane, self.s - float(d))

    def distance_to(self, other: Any) -> float:
        return distance(self, other)


@dataclass(frozen=True)
class Crosswalk:
    """A pedestrian crossing: a ``width``-metre band across some lanes.

    ``path`` runs kerb to kerb (from the ``start_side`` sidewalk across the road), ``crosses``
    lists ``(lane, s)`` — where the band's centre meets each lane it crosses. A pedestrian placed
    on a crosswalk walks ``path`` (``side=`` picks the end it starts from).
    """

    name: str
    path: Path
    width: float
    crosses: tuple[tuple[Lane, float], ...]
    sides: tuple[str, str] = ("a", "b")

    @property
    def position(self) -> np.ndarray:
        """Centre of the crossing [m]."""
        return self.path.array.mean(axis=0)

    def walk(self, side: str | None = None) -> Path:
        """The path walked when starting from ``side`` (one of ``sides``; default the first)."""
        if side is None or side == self.sides[0]:
            return self.path
        if side == self.sides[1]:
            return self.path.reversed()
        raise ValueError(f"crosswalk {self.name!r} has sides {self.sides}, not {side!r}")

    def distance_to(self, other: Any) -> float:
        return distance(self, other)


@dataclass(frozen=True)
class Route:
    """A planned sequence of lanes, e.g. an approach, a turn connector and an exit."""

    lanes: tuple[Lane, ...]
    turn: str = ""

    def __post_init__(self) -> None:
        if not self.lanes:
            raise ValueError("a route needs at least one lane")

    @property
    def start(self) -> Lane:
        return self.lanes[0]

    @property
    def end(self) -> Lane:
        return self.lanes[-1]

    @property
    def length(self) -> float:
        """Total length [m]."""
        return float(sum(l.length for l in self.lanes))

    def __iter__(self):
        return iter(self.lanes)

    def __len__(self) -> int:
        return len(self.lanes)

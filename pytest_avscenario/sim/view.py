"""A read-only view of the whole simulation, for drivers that need more than the Observation.

:meth:`World.view() <pytest_avscenario.sim.world.World.view>` returns a :class:`SceneView`:
every lane of the road network with its geometry and connections, and the state of every
agent on the road, in the world frame (x east, y north [m]; headings counter-clockwise from
+x [rad]; a lateral offset ``r`` is positive to the left of a lane's direction; the lanes of
a carriageway are numbered from 0 at the left). Everything in it is frozen or a copy: a
driver can keep it, but changing it changes nothing in the world.

A driver gets hold of the world through its per-case hook ``reset(world)`` (see
:mod:`pytest_avscenario.sim.drivers`) and may call ``world.view()`` from ``act``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Any, Mapping

import numpy as np

from .observation import AgentState

__all__ = ["LaneView", "SceneView", "StopMark"]

FRAME = ("world: x east, y north [m]; heading counter-clockwise from +x [rad]; lane offset r "
         "positive to the left; lanes of a carriageway numbered from 0 at the left")


@dataclass(frozen=True, eq=False)
class LaneView:
    """One lane: what it is, where it leads, and its geometry (methods as the lanes' own).

    ``index`` is highway-env's ``(from_node, to_node, i)`` of the lane; ``successors`` the ids
    of the lanes that start where it ends; ``centre_line`` an ``(n, 2)`` read-only array of
    centre-line points [m] (the two ends of a straight lane, about one point a metre on a
    curve).
    """

    id: str
    index: tuple[str, str, int]
    kind: str  # "travel", "parking", "connector", ...
    direction: str
    group: str  # lanes side by side in one carriageway share a group
    number: int  # place in the group, 0 leftmost
    length: float  # [m]
    width: float  # [m]
    speed_limit: float  # [m/s]
    successors: tuple[str, ...]
    centre_line: np.ndarray = field(repr=False)
    _geometry: Any = field(repr=False, compare=False)

    def position(self, s: float, r: float = 0.0) -> np.ndarray:
        """World position [m] of lane coordinates ``(s, r)`` [m]."""
        return np.array(self._geometry.position(float(s), float(r)), dtype=float)

    def heading_at(self, s: float) -> float:
        """Heading [rad] of the lane at ``s`` [m]."""
        return float(self._geometry.heading_at(float(s)))

    def local_coordinates(self, xy: Any) -> tuple[float, float]:
        """Lane coordinates ``(s, r)`` [m] of a world position ``(x, y)`` [m]."""
        s, r = self._geometry.local_coordinates(np.asarray(xy, dtype=float))
        return float(s), float(r)

    def width_at(self, s: float) -> float:
        """Width [m] at ``s`` [m]."""
        return float(self._geometry.width_at(float(s)))


@dataclass(frozen=True)
class StopMark:
    """A line where traffic on ``lane`` (an id) stops: ``kind`` "stop" or "crosswalk"."""

    lane: str
    s: float  # [m] along the lane
    kind: str


@dataclass(frozen=True)
class SceneView:
    """The simulation at time ``t`` [s], in the world frame (see :data:`FRAME`).

    ``agents`` are the agents on the road now, ego first (an agent that has not appeared
    yet, or has left, is not there); ``agent_lanes`` maps each of their names to the id of
    the lane it is on (None off every lane).
    """

    t: float  # [s]
    dt: float  # [s]
    ego: str  # the ego's name ("" before it is placed)
    lanes: tuple[LaneView, ...]
    agents: tuple[AgentState, ...]
    agent_lanes: Mapping[str, str | None]
    stop_marks: tuple[StopMark, ...]
    frame: str = FRAME

    def lane(self, lane_id: str) -> LaneView:
        """The lane called ``lane_id``."""
        for lane in self.lanes:
            if lane.id == lane_id:
                return lane
        raise KeyError(f"no lane {lane_id!r}; lanes: {[l.id for l in self.lanes]}")

    def agent(self, name: str) -> AgentState:
        """The state of the agent called ``name``."""
        for a in self.agents:
            if a.name == name:
                return a
        raise KeyError(f"no agent {name!r} on the road; agents: {[a.name for a in self.agents]}")


def lane_views(index: Any) -> tuple[LaneView, ...]:
    """The :class:`LaneView` of every lane of a :class:`~.lanes.LaneIndex`, in its order."""
    from highway_env.road.lane import SineLane, StraightLane  # loaded with the road

    out = []
    for lane in index.order:
        g = lane.geometry
        length = float(g.length)
        straight = isinstance(g, StraightLane) and not isinstance(g, SineLane)
        n = 2 if straight else max(2, int(math.ceil(length)) + 1)
        pts = np.array([g.position(s, 0.0) for s in np.linspace(0.0, length, n)], dtype=float)
        pts.setflags(write=False)
        out.append(LaneView(
            id=lane.id, index=tuple(lane.index), kind=lane.kind, direction=lane.direction,
            group=lane.group, number=int(lane.number), length=length,
            width=float(g.width_at(0.0)), speed_limit=float(getattr(g, "speed_limit", math.nan)),
            successors=tuple(l.id for l in index.successors.get(lane.index, ())),
            centre_line=pts, _geometry=g))
    return tuple(out)


def stop_marks(index: Any) -> tuple[StopMark, ...]:
    out = []
    for lane in index.order:
        for s, kind in index.stop_marks.get(lane.index, ()):
            out.append(StopMark(lane.id, float(s), kind))
    return tuple(out)


def agent_lanes(index: Any, agents: list[Any]) -> Mapping[str, str | None]:
    lanes = index.lanes
    return MappingProxyType({a.name: (lanes[a.lane_index].id if a.lane_index in lanes else None)
                             for a in agents})

"""What the AV under test sees each step, and what it answers.

A driver is handed one :class:`Observation` per step and returns ``(acceleration [m/s^2],
steering [rad])`` — the front-wheel angle of highway-env's kinematic bicycle model.
Drivers take any of three shapes (see :func:`pytest_avscenario.sim.drivers.resolve`): a
callable ``policy(observation)``, an object with ``act(observation)``, or an object with
``predict(observation)`` returning ``(action, state)`` — each gets this dataclass, not an
array: a model trained on highway-env drives through
:func:`~pytest_avscenario.sim.drivers.highway_env_agent`, which hands it highway-env's own
observations. Positions and headings are in the world frame (x east, y north [m], headings
counter-clockwise [rad]), which is highway-env's mirrored (y -> -y); ``r`` is positive to the
left. A driver that needs the whole scene gets the world in ``reset(world)`` and calls
``world.view()``.

Geometry is handed over as the simulator's lane objects, which all speak one small
vocabulary: ``position(s, r) -> (x, y)``, ``heading_at(s)``, ``local_coordinates((x, y)) ->
(s, r)``, ``length``, ``width_at(s)``.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

__all__ = ["AgentState", "Observation", "StopLine", "TrafficLight"]


@dataclass(frozen=True)
class AgentState:
    """One agent's state at the current step (world frame)."""

    name: str
    kind: str  # "ego", "car", "truck", "bus", "pedestrian", "parked"
    x: float  # [m]
    y: float  # [m]
    vx: float  # [m/s]
    vy: float  # [m/s]
    speed: float  # [m/s]
    heading: float  # [rad]
    length: float  # [m]
    width: float  # [m]
    flags: dict[str, Any] = field(default_factory=dict)  # e.g. {"stop_arm": True} on a bus

    @property
    def position(self) -> np.ndarray:
        return np.array([self.x, self.y])

    @property
    def velocity(self) -> np.ndarray:
        return np.array([self.vx, self.vy])


@dataclass(frozen=True)
class StopLine:
    """A line on the ego's route where it must stop before proceeding."""

    route_index: int  # index into Observation.route of the lane that carries it
    s: float  # [m] longitudinal position on that lane
    kind: str = "stop"  # "stop" (intersection), "crosswalk"


@dataclass(frozen=True)
class TrafficLight:
    """A traffic light on the ego's route ahead (within 150 m of the start of its lane)."""

    route_index: int  # index into Observation.route of the lane its stop position is on
    s: float  # [m] the stop position on that lane: stop the front bumper before it
    state: str  # "green", "amber" or "red" now
    signal: str = ""  # the map's signal id


@dataclass(frozen=True)
class Observation:
    """Everything a driver gets at one step.

    ``route`` is the ego's planned sequence of lanes (lane objects, see module doc);
    ``route_index`` the lane of it the ego is on now and ``s``/``r`` its longitudinal and
    signed lateral position in that lane's frame. ``agents`` are the other agents within
    ``sensor_range`` metres, nearest first. ``goal`` is a target pose for manoeuvres such as
    parking (``None`` otherwise). ``traffic_lights`` are the lights on the route ahead, each
    with where traffic stops for it and its state now (empty on a road without lights).
    """

    t: float  # [s]
    dt: float  # [s]
    ego: AgentState
    route: tuple[Any, ...]
    route_index: int
    s: float  # [m]
    r: float  # [m]
    agents: tuple[AgentState, ...]
    stop_lines: tuple[StopLine, ...] = ()
    speed_limit: float = 13.9  # [m/s]
    target_speed: float | None = None  # [m/s] what the scenario asked the ego to cruise at
    goal: dict[str, Any] | None = None  # e.g. {"kind": "park", "x":…, "y":…, "heading":…}
    sensor_range: float = 80.0  # [m]
    traffic_lights: tuple[TrafficLight, ...] = ()  # the lights on the route ahead, nearest first

"""One simulated scene per case: build a road, place agents, run, and keep the recording.

A test gets a fresh :class:`World` seeded from its case, builds one road on it, places the ego
(driven by the AV under test) and other agents, and calls :meth:`World.run`, which steps
highway-env and records a :class:`~pytest_avscenario.trajectory.Trajectory` into
preallocated arrays. All randomness comes from the case: the world's ``rng`` (the case's
``case.rng``) feeds behaviours, and highway-env's ``Road`` gets its own
``default_rng(seed)``. Same case, same bits, in any process and any test order.

highway-env (and with it pygame, matplotlib, pandas) is imported only when a road is built.
"""

from __future__ import annotations

import math
from typing import Any, Callable

import numpy as np

from .drivers import IDMDriver, declared_step, resolve
from .errors import DriverError, SimError
from .geometry import footprints_overlap
from .observation import AgentState, Observation, StopLine as ObsStopLine, TrafficLight
from .places import Crosswalk, Lane, Path, Route, Spot, StopLine, distance as _distance
from .recording import Recorder
from ..trajectory import Trajectory

__all__ = ["World"]



class World:
    """A fresh simulated world for one case.

    ``seed`` seeds highway-env's road rng; ``rng`` (default ``default_rng(seed)``) is what
    behaviours draw from during the run; ``driver`` is the ego's default driver (a name such
    as ``"autopilot"``/``"idm"`` or a policy object, see :func:`.drivers.resolve`); ``name``
    the pytest node id, quoted in every error. ``ego_driver``, when given, drives the ego
    whatever driver the scenario names (the plugin's avoidability check puts its reference
    driver there).

    ``dt`` [s] is the step of a :meth:`run` that gives none (the plugin's ``--avs-dt`` or
    ``@scenario(dt=...)``, ``dt_from`` saying which); None leaves it to the driver (see
    :meth:`run`). ``warn(warning, key)`` reports a :class:`~.errors.SimWarning` (default
    ``warnings.warn``); the plugin gives one that says each ``key`` once per test.
    """

    def __init__(self, seed: int, rng: np.random.Generator | None = None, driver: Any = None,
                 name: str = "", ego_driver: Any = None, *, dt: float | None = None,
                 dt_from: str = "", warn: Callable[[Warning, str], None] | None = None) -> None:
        try:
            self.seed = int(seed)
        except (TypeError, ValueError):
            raise SimError(f"World(seed={seed!r}): need an integer >= 0", test=str(name)) from None
        if self.seed < 0:
            raise SimError(f"World(seed={seed!r}): need an integer >= 0", test=str(name))
        self.rng = rng if rng is not None else np.random.default_rng(self.seed)
        if hasattr(self.rng, "clock"):  # the case's recording rng: log draws with the time
            self.rng.clock = lambda: self.t
        self.driver = driver
        self.ego_driver = ego_driver
        self.name = str(name)
        if dt is not None:
            try:
                ok = math.isfinite(float(dt)) and float(dt) > 0
            except (TypeError, ValueError):
                ok = False
            if not ok:
                raise SimError(f"World(dt={dt!r}) (from {dt_from or 'the caller'}): need a "
                               "finite number > 0 [s], or None for the driver's own step",
                               test=str(name))
        self.step_setting = None if dt is None else float(dt)  # [s] run()'s step when it gives none
        self.step_setting_from = dt_from or (f"World(dt={dt!r})" if dt is not None else "")
        self._warn = warn
        self.t = 0.0  # [s] simulation time of the state being acted on
        self.dt = 0.1  # [s]
        self.dt_from = "the default"  # where the last run's dt came from, for messages
        self._step_driver: Any = None  # the scenario's ego driver: its declared step, if any
        self.trajectory: Trajectory | None = None
        self.road: Any = None  # our road object (StraightRoad, TwoWayRoad, Intersection)
        self._road: Any = None  # the highway-env Road
        self._index: Any = None
        self._ego: Any = None
        self._others: list[Any] = []
        self._movers: list[Any] = []
        self._counts: dict[str, int] = {}
        self._route_geoms: tuple = ()
        self._stop_cache: dict[int, tuple] = {}
        self._allway: Any = None  # arrival order at all-way stops (right_of_way.AllWayStop)
        self._lights: Any = None  # the road's traffic lights (signals.TrafficLights), or False
        self.sensor_range = 80.0  # [m]

    def __repr__(self) -> str:
        return f"World(seed={self.seed}, name={self.name!r}, road={getattr(self.road, 'kind', None)})"

    # -- roads -------------------------------------------------------------------------------------
    def _new_network(self, what: str) -> Any:
        if self.road is not None:
            raise SimError(f"{what}: this world already has a {self.road.kind} road; "
                           "build one road per world", test=self.name)
        from ._hwenv import load_core

        load_core()
        from highway_env.road.road import RoadNetwork

        return RoadNetwork()

    def _finish_road(self, road: Any, net: Any) -> Any:
        from .engine import SimRoad

        self._road = SimRoad(network=net, vehicles=[], np_random=np.random.default_rng(self.seed),
                          record_history=False)
        self.reindex(road.all_lanes)
        self.road = road
        if hasattr(road, "_after_index"):
            road._after_index()
        return road

    def straight_road(self, lanes: int = 1, length: float = 400.0, *, lane_width: float = 3.5,
                      speed_limit: float = 13.9) -> Any:
        """A one-way road east from x = 0: ``lanes`` lanes (0 leftmost), ``length`` [m].

        ``speed_limit`` [m/s] is what IDM drivers cap their target speed at.
        """
        from .roads import StraightRoad

        net = self._new_network("straight_road")
        return self._finish_road(StraightRoad(self, net, lanes, float(length), lane_width,
                                              speed_limit), net)

    def highway(self, lanes: int = 3, segments: Any = None, *, lane_width: float = 3.75,
                speed_limit: float = 36.1) -> Any:
        """A one-way highway of ``segments`` (``straight(length)``, ``arc(radius, angle)``
        from :mod:`pytest_avscenario.sim.highway`; default one straight kilometre) starting at
        the origin heading east, ``lanes`` lanes (0 leftmost). A segment with fewer lanes
        drops the rightmost ones; ``road.on_ramp(at=...)`` adds an on-ramp. ``speed_limit``
        [m/s] (default 130 km/h) is what IDM drivers cap their target speed at."""
        from .highway import Highway

        net = self._new_network("highway")
        road = Highway(self, net, lanes, segments, lane_width, speed_limit)
        self._finish_road(road, net)
        # highway-env's own IDM (the "idm" ego) looks for its leader on the next segment too.
        self._road.neighbour_vehicles_connected_lanes = True
        return road

    def two_way_road(self, lanes: int = 1, length: float = 300.0, parking: bool = True, *,
                     lane_width: float = 3.5, parking_width: float = 2.5,
                     speed_limit: float = 13.9, median: float = 0.0) -> Any:
        """A two-way road along x: ``lanes`` lanes each way and, with ``parking``, a parking
        lane along each kerb. Forward traffic drives east. ``median`` [m] separates the two
        directions (0: one centre line)."""
        from .roads import TwoWayRoad

        net = self._new_network("two_way_road")
        return self._finish_road(TwoWayRoad(self, net, lanes, float(length), parking, lane_width,
                                            parking_width, speed_limit, median), net)

    def intersection(self, lanes: int = 1, approach_length: float = 100.0, *,
                     lane_width: float = 3.5, speed_limit: float = 13.9,
                     crosswalk_width: float = 3.0, corner: float = 6.0,
                     median: float = 0.0, control: str = "stop") -> Any:
        """A four-way intersection at the origin, ``lanes`` (1 or 2) lanes per approach.

        ``approach_length`` [m] per arm; ``corner`` [m] is the clearance between the outermost
        lane and the box edge (sets the turn radii); ``median`` [m] separates the two
        directions of every arm. ``control`` is ``"stop"`` (an all-way stop) or
        ``"signals"``: traffic lights, north-south and east-west taking turns
        (:meth:`signals` sets their plan). For several intersections use :meth:`road_network`.
        """
        from .roads import Intersection

        net = self._new_network("intersection")
        return self._finish_road(Intersection(self, net, lanes, float(approach_length),
                                              lane_width, speed_limit, crosswalk_width,
                                              corner, median, control=control), net)

    def road_network(self) -> Any:
        """An empty :class:`~.network.Network`: place intersections anywhere
        (``net.intersection("A", at=(0, 0))``), connect facing arms
        (``net.connect(a, "north", b, "south")``) and route across them
        (``net.route(a.route("south"), b.route("south", "left"))``). Build it whole before
        placing agents."""
        from .engine import SimRoad
        from .network import Network

        net = self._new_network("road_network")
        self._road = SimRoad(network=net, vehicles=[], np_random=np.random.default_rng(self.seed),
                             record_history=False)
        self.road = Network(self, net)
        return self.road

    def map(self, path: Any, *, speed_limit: float = 13.9, evaluator: str = "numpy") -> Any:
        """The drivable lanes of an OpenDRIVE map file as this world's road (a
        :class:`~.maps.MapRoad`): lanes by id (``road.lane("12/0/-1")``), routes through
        junctions (``road.route(a, b)``), the closest lane to a point. A relative ``path`` is
        looked up from the calling test module's folder, then the working directory; the
        file is read once per process. ``speed_limit`` [m/s] is for lanes the file gives
        none."""
        from .engine import SimRoad
        from .maps import MapRoad
        from .opendrive import _caller_dirs

        self._new_network("map")
        dirs = _caller_dirs()
        road = MapRoad(self, path, base=dirs[0] if dirs else None, speed_limit=speed_limit,
                       evaluator=evaluator)
        self._road = SimRoad(network=road.net, vehicles=[],
                             np_random=np.random.default_rng(self.seed), record_history=False)
        self._road.neighbour_vehicles_connected_lanes = True
        self._index = road.make_index()
        self.road = road
        self._map_stop_signs(road)
        return road

    def _map_stop_signs(self, road: Any) -> None:
        """The map's stop signs (``<signal type="206">``) and stop lines (``"294"``) as stop
        marks: drivers stop there and ``ran_stop`` judges them, as at a built all-way stop."""
        from .signals import STOP_LINE, STOP_SIGN, map_signals

        try:
            found = map_signals(road.data)
        except SimError as exc:
            raise SimError(str(exc), test=self.name) from None
        by_id = road._built.by_id
        marked = set()
        for sg in found.signals.values():
            if sg.kind not in (STOP_SIGN, STOP_LINE):
                continue
            for p in sg.stops:
                lane = by_id.get(p.lane)
                if lane is not None and (p.lane, round(p.s, 3)) not in marked:
                    marked.add((p.lane, round(p.s, 3)))
                    self._index.add_stop(lane, p.s, "stop")
                    road.stop_lines.append(StopLine(lane, p.s, sg.id))

    # -- the interface of the engine, roads and behaviours to the world ------------------------
    # Agents, roads and behaviours go through these few members, never through the world's
    # private attributes, so the world can change how it keeps its state.

    @property
    def lane_index(self) -> Any:
        """The :class:`~.lanes.LaneIndex` of the road: every lane, its neighbours and stop
        marks, and the tracker that keeps each agent's lane (None before a road is built)."""
        return self._index

    def reindex(self, lanes: Any) -> Any:
        """Index ``lanes`` afresh (a road network that grew), keeping the stop marks made so
        far; returns the new :attr:`lane_index`."""
        from .lanes import LaneIndex

        index = LaneIndex(lanes)
        if self._index is not None:
            for key, marks in self._index.stop_marks.items():
                index.stop_marks[key] = list(marks)
            index.straight_on.update(self._index.straight_on)
            index.drops.update(self._index.drops)
        self._index = index
        return index

    def agent_class(self, base: type) -> type:
        """A highway-env vehicle class ``base`` made an agent of this world (lane tracking,
        route progress), for drivers that bring their own vehicle model."""
        from .engine import agent_class

        return agent_class(base)

    @property
    def engine_road(self) -> Any:
        """highway-env's ``Road`` the agents live on (its ``network`` and ``vehicles``), for
        adapters that run highway-env code against the scene; read it, do not change it."""
        return self._road

    @property
    def movers(self) -> list[Any]:
        """The agents on the road this step (present ones, in stepping order). Read only."""
        return self._movers

    @property
    def all_way_stop(self) -> Any:
        """The arrival order at this world's all-way stops (a :class:`~.right_of_way.AllWayStop`),
        made on first use and remade when the road is re-indexed."""
        from .right_of_way import AllWayStop

        aw = self._allway
        if aw is None or aw.index is not self._index:
            aw = self._allway = AllWayStop(self)
        return aw

    # -- traffic lights ----------------------------------------------------------------------------
    @property
    def traffic_lights(self) -> Any:
        """The road's traffic lights (a :class:`~.signals.TrafficLights`, made on first use
        from the map file's signals), or None on a road without any."""
        got = self._lights
        if got is None:
            got = False
            road = self.road
            if getattr(road, "kind", "") == "map":
                from .signals import TrafficLights, map_signals

                try:
                    found = map_signals(road.data)
                except SimError as exc:
                    raise SimError(str(exc), test=self.name) from None
                lights = TrafficLights(found)
                got = lights if lights.stops else False
            elif getattr(road, "traffic_lights", None) is not None:
                got = road.traffic_lights
            self._lights = got
        return got or None

    def signals(self, *, green: float | None = None, amber: float | None = None,
                all_red: float | None = None, cycle: float | None = None,
                offset: Any = None, phase: float | None = None) -> Any:
        """The road's traffic lights with their fixed-time plan set: ``green``, ``amber``,
        ``all_red`` [s] per controller's turn (defaults 10, 3, 2 s, CARLA's), or ``cycle``
        [s] (a two-way junction's whole cycle), and ``offset`` [s] into every junction's cycle
        at t = 0 (or ``{junction id: s}``), or ``phase`` the same as a share (0..1) of each
        junction's cycle — sample it to vary the phase the ego arrives in.
        Returns the :class:`~.signals.TrafficLights` (``state(signal, t)``, ``stops``)."""
        if self.road is None:
            raise SimError("world.signals(): build a road first (world.map(...))", test=self.name)
        if self.trajectory is not None:
            raise SimError("world.signals(): the world has already run", test=self.name)
        lights = self.traffic_lights
        if lights is None:
            raise SimError(f"world.signals(): the {self.road.kind} road has no traffic lights "
                           "(a map file with <signal type=\"1000001\"> elements has)",
                           test=self.name)
        return lights.configure(green=green, amber=amber, all_red=all_red, cycle=cycle,
                                offset=offset, phase=phase, test=self.name)

    def lights_ahead(self, agent: Any, horizon: float = 150.0) -> list[tuple[float, str, str]]:
        """The traffic lights on ``agent``'s route ahead within ``horizon`` [m]: ``(distance
        [m] from its centre to the stop position (negative once passed, until it leaves that
        lane), state now, signal id)``, nearest first; [] on a road without lights."""
        lights, ahead = self.light_stops(agent, horizon)
        if not ahead:
            return []
        rs = float(agent.route_s)
        t = self.t
        state = lights.state
        return [(acc - rs, state(sid, t), sid) for _, _, acc, sid in ahead]

    def light_stops(self, agent: Any, horizon: float = 150.0) -> tuple[Any, list]:
        """(the road's :class:`~.signals.TrafficLights`, the stops ahead of ``agent`` as
        ``(route index, s, distance from the start of its lane [m], signal)``) — what
        :meth:`lights_ahead` reads, for a driver that asks a light's state only when it needs
        it; (None, []) on a road without lights."""
        lights = self._lights if self._lights is not None else self.traffic_lights
        if not lights:
            return None, []
        return lights, self._stops_ahead(lights, agent, horizon)

    @staticmethod
    def _stops_ahead(lights: Any, agent: Any, horizon: float) -> list:
        """``lights.ahead`` of ``agent``'s route from its lane on, kept until it moves to
        another lane or route: the stops ahead are looked up per lane, not per step."""
        plan, ri = agent.plan, agent.route_index
        if not plan:
            return []
        memo = agent.__dict__.get("_lights_memo")
        if memo is None or memo[0] is not plan or memo[1] != ri:
            memo = agent._lights_memo = (plan, ri, lights.ahead(plan, ri, horizon))
        return memo[2]

    # -- placing agents --------------------------------------------------------------------------
    def _need_road(self, what: str) -> None:
        if self.road is None or self._index is None:
            raise SimError(f"{what}: build a road first (world.straight_road(), "
                           "world.highway(), world.two_way_road(), world.intersection(), world.map() "
                           "or an intersection on world.road_network())", test=self.name)
        if self.trajectory is not None:
            raise SimError(f"{what}: the world has already run; a world runs once",
                           test=self.name)

    def _spot(self, place: Any, s: float, r: float, agent: str) -> Spot:
        if isinstance(place, Route):
            place = place.lanes[0]
        if isinstance(place, Lane):
            spot = Spot(place, float(s), float(r))
        elif isinstance(place, (Spot, StopLine)):
            spot = Spot(place.lane, float(place.s) + float(s), getattr(place, "r", 0.0) + float(r))
        else:
            raise SimError(f"cannot place a vehicle on {place!r}: give a lane "
                           "(road.lane(0), inter.approach('south')), a spot (lane.at(s)) "
                           "or a stop line", test=self.name, agent=agent)
        if self._index.lanes.get(spot.lane.index) is not spot.lane:
            raise SimError(f"lane {spot.lane.id!r} belongs to another world's road",
                           test=self.name, agent=agent)
        if not (math.isfinite(spot.s) and 0.0 <= spot.s <= spot.lane.length):
            raise SimError(f"placed off the road: s={spot.s!r} m is outside lane {spot.lane.id!r} "
                           f"(0..{spot.lane.length:g} m)", test=self.name, agent=agent)
        if not (math.isfinite(spot.r) and abs(spot.r) <= spot.lane.width / 2):
            raise SimError(f"placed off the road: r={spot.r!r} m is outside lane {spot.lane.id!r} "
                           f"(|r| <= {spot.lane.width / 2:g} m)", test=self.name, agent=agent)
        return spot

    def _name(self, kind: str, name: str | None) -> str:
        if name is None:
            k = self._counts.get(kind, 0) + 1
            self._counts[kind] = k
            name = f"{kind}{k}" if kind != "ego" else "ego"
        taken = [a.name for a in self._all()]
        if name in taken:
            raise SimError(f"duplicate agent name {name!r}", test=self.name, agent=name)
        return str(name)

    def _all(self) -> list[Any]:
        return ([self._ego] if self._ego is not None else []) + self._others

    def _check_speed(self, speed: float, agent: str) -> float:
        try:
            v = float(speed)
        except (TypeError, ValueError):
            raise SimError(f"speed={speed!r} is not a number [m/s]", test=self.name,
                           agent=agent) from None
        if not math.isfinite(v) or v < 0:
            raise SimError(f"speed={speed!r} m/s: need a finite speed >= 0", test=self.name,
                           agent=agent)
        return v

    def _overlapping(self, new: Any, others: list[Any]) -> Any:
        """The first of ``others`` whose footprint intersects ``new``'s, or None."""
        for other in others:
            if other is not new and footprints_overlap(new, other):
                return other
        return None

    def _check_overlap(self, new: Any) -> None:
        if new.appear is not None:
            return  # checked when it appears
        other = self._overlapping(new, [a for a in self._all() if a.appear is None])
        if other is not None:
            raise SimError(
                f"overlaps {other.name!r} at t=0 (centres {np.round(new.position, 2).tolist()} "
                f"and {np.round(other.position, 2).tolist()} m); move one of them",
                test=self.name, agent=new.name)

    def _when(self, value: Any, what: str, name: str) -> Any:
        if value is None or callable(value):
            return value
        try:
            t = float(value)
        except (TypeError, ValueError):
            t = math.nan
        if not (math.isfinite(t) and t >= 0):
            raise SimError(f"{what}={value!r}: give a time >= 0 [s] or a callable(world) -> bool",
                           test=self.name, agent=name)
        return t

    def _due(self, cond: Any) -> bool:
        if callable(cond):
            return bool(cond(self))
        return self.t >= cond - 1e-9

    def ego_within(self, place: Any, d: float) -> Callable[["World"], bool]:
        """A condition for ``appear=``/``disappear=``: the ego is within ``d`` [m] of ``place``."""
        return lambda w: w._ego is not None and _distance(w._ego, place) <= d

    def ego_past(self, place: Any, by: float = 0.0) -> Callable[["World"], bool]:
        """A condition: all of the ego (its rear) is ``by`` [m] past ``place`` along its route."""
        return lambda w: (w._ego is not None
                          and w._ego.distance_along_route(place) + w._ego.LENGTH / 2 < -by)

    def _bind(self, behavior: Any, kind: str, name: str) -> Any:
        from .behaviors import Behavior

        if behavior is None:
            return None
        if not isinstance(behavior, Behavior):
            raise SimError(f"behavior={behavior!r} is not a behaviour; use one from "
                           "pytest_avscenario.sim.behaviors", test=self.name, agent=name)
        if kind not in behavior.kinds:
            raise SimError(f"behaviour {behavior.name} cannot drive a {kind}", test=self.name,
                           agent=name)
        try:
            return behavior.bind(self.rng)
        except (TypeError, ValueError) as exc:
            raise SimError(f"behaviour {behavior.name}: {exc}", test=self.name, agent=name) from exc

    def _route_for(self, spot: Spot, route: Any, agent: str) -> tuple[list[Lane], int]:
        if route is None:
            lanes = list(self.road.default_route(spot.lane).lanes)
        elif isinstance(route, Route):
            lanes = list(route.lanes)
        elif isinstance(route, Lane):
            lanes = [route]
        else:
            lanes = list(route)
            if not lanes or not all(isinstance(l, Lane) for l in lanes):
                raise SimError(f"route={route!r}: give inter.route(...), a Lane or a list of "
                               "Lanes", test=self.name, agent=agent)
        if spot.lane not in lanes and not self._beside(spot.lane, lanes[0]):
            raise SimError(f"placed on {spot.lane.id!r}, which is not on its route "
                           f"{[l.id for l in lanes]} nor beside its first lane",
                           test=self.name, agent=agent)
        # (a map's lanes never change: a route of them found whole is not measured again)
        whole = getattr(self.road, "whole_routes", None)
        key = tuple(lanes) if whole is not None else None
        if key is None or key not in whole:
            for a, b in zip(lanes, lanes[1:]):
                gap = _joint_gap(a, b)
                if gap > 1.0:
                    raise SimError(f"route is broken: {b.id!r} starts {gap:.1f} m from the end "
                                   f"of {a.id!r}", test=self.name, agent=agent)
            if key is not None and len(whole) < 4096:
                whole.add(key)
        return lanes, lanes.index(spot.lane) if spot.lane in lanes else 0

    @staticmethod
    def _beside(lane: Lane, other: Lane) -> bool:
        """Whether ``lane`` runs beside ``other`` in the same carriageway (a lane change away)."""
        return bool(lane.group) and lane.group == other.group and lane is not other

    def _register(self, agent: Any, spot: Spot | None, lanes: list[Lane], k: int, kind: str,
                  name: str, behavior: Any, initial: float, appear: Any = None,
                  disappear: Any = None) -> Any:
        agent.road = self._road
        agent.appear = self._when(appear, "appear", name)
        agent.disappear = self._when(disappear, "disappear", name)
        agent._attach(self, name, kind, spot.lane if spot is not None else None, lanes, behavior,
                      initial, route_index=k)
        self._check_overlap(agent)
        if kind == "ego":
            self._ego = agent
        else:
            self._others.append(agent)
        return agent

    def _check_route_continues(self, lanes: list[Lane], drv: Any, name: str) -> None:
        """The built-in autopilot and careful driver follow their route's lanes and do not
        merge: a route ending in a lane that ends (a lane drop, an on-ramp's acceleration
        lane) would have them drive on past the road's edge unnoticed. Refused, naming the
        lane; highway-env's IDM (``driver="idm"``) merges and is allowed."""
        ends = getattr(self.road, "_drops", ())
        if not ends or not lanes or not any(lanes[-1] is lane for lane in ends):
            return
        from .drivers.autopilot import Autopilot
        from .drivers.reference import CarefulDriver

        target = getattr(drv, "target", drv)
        if isinstance(target, (Autopilot, CarefulDriver)):
            who = "autopilot" if isinstance(target, Autopilot) else "careful"
            raise SimError(
                f"the ego's route ends in {lanes[-1].id}, a lane that ends, and the "
                f"{who} driver follows its lanes without merging (it would drive "
                "off the road's edge); start the ego in a lane that continues, give it a route "
                "that does, or drive it with driver='idm'", test=self.name, agent=name)

    def ego(self, place: Any, s: float = 0.0, speed: float = 0.0, driver: Any = None,
            route: Any = None, target_speed: float | None = None, goal: dict | None = None, *,
            r: float = 0.0, allow_reverse: bool | None = None, name: str = "ego") -> Any:
        """Place the AV under test at ``place``: a lane (``s`` [m] along it), or a spot or stop
        line (``s`` [m] further along its lane, e.g. ``inter.stop_line("south").before(20)``).

        ``driver`` overrides the world's default driver (one with its own vehicle model, such
        as ``highway_env_agent(...)``, builds the ego itself); ``route`` (e.g.
        ``inter.route("south", "left")``) defaults to straight on. Placed on a lane beside the
        route's first lane (``inter.approach("south", 1)`` with a route from lane 0), the ego
        starts with a lane change onto its route: its driver merges. ``target_speed`` [m/s] is
        handed to the driver (and is the "idm" driver's desired speed; default ``speed`` or
        the speed limit); ``goal`` is passed through to the observation. Braking stops the
        ego at 0 m/s unless ``allow_reverse`` (default: only for a parking goal,
        ``goal={"kind": "park", ...}``) — so a driver that holds a stop by commanding a
        deceleration does not creep backwards.
        """
        self._need_road("world.ego()")
        if isinstance(place, Route) and route is None:
            route = place
        if self._ego is not None:
            raise SimError("the world already has an ego", test=self.name, agent=name)
        spot = self._spot(place, s, r, name)
        v = self._check_speed(speed, name)
        lanes, k = self._route_for(spot, route, name)
        drv = resolve(self.ego_driver if self.ego_driver is not None
                      else driver if driver is not None else self.driver)
        # the step follows the scenario's driver even when a reference replaces it, so a
        # replay with the reference sees the other agents move as in the case it judges
        self._step_driver = drv if self.ego_driver is None else _quietly_resolved(
            driver if driver is not None else self.driver)
        self._check_route_continues(lanes, drv, name)
        pos = spot.position
        heading = spot.heading
        from .engine import DriverEgo, IDMEgo

        if isinstance(drv, IDMDriver):
            v0 = target_speed if target_speed is not None else (v if v > 0 else None)
            if v0 is None:
                v0 = float(spot.lane.geometry.speed_limit)
            agent = IDMEgo(self._road, pos, heading, v, target_lane_index=lanes[k].index,
                           target_speed=float(v0), route=[l.index for l in lanes[k:]])
        elif callable(getattr(drv, "make_ego", None)):
            # a driver that brings its own vehicle model (highway_env_agent)
            agent = drv.make_ego(self, pos, heading, v, lane_index=lanes[k].index,
                                 route=[l.index for l in lanes[k:]], target_speed=target_speed,
                                 name=name)
        else:
            agent = DriverEgo(pos, heading, v)
        agent.driver = drv
        agent.goal = goal
        agent.target_speed_request = target_speed
        if allow_reverse is None:
            allow_reverse = isinstance(goal, dict) and goal.get("kind") == "park"
        agent.allow_reverse = bool(allow_reverse)
        self._counts["ego"] = 1
        return self._register(agent, spot, lanes, k, "ego", self._name_free(name), None, v)

    def _name_free(self, name: str) -> str:
        if name in [a.name for a in self._all()]:
            raise SimError(f"duplicate agent name {name!r}", test=self.name, agent=name)
        return name

    def _vehicle(self, cls: Any, kind: str, place: Any, s: float, speed: float, behavior: Any,
                 name: str | None, r: float, route: Any = None, appear: Any = None,
                 disappear: Any = None) -> Any:
        name = self._name(kind, name)
        spot = self._spot(place, s, r, name)
        v = self._check_speed(speed, name)
        lanes, k = self._route_for(spot, route, name)
        bound = self._bind(behavior, kind, name)
        agent = cls(spot.position, spot.heading, v)
        return self._register(agent, spot, lanes, k, kind, name, bound, v, appear, disappear)

    def car(self, lane: Any, s: float = 0.0, speed: float = 0.0, behavior: Any = None, *,
            name: str | None = None, r: float = 0.0, route: Any = None, appear: Any = None,
            disappear: Any = None) -> Any:
        """A 5 x 2 m car on ``lane`` (or a spot) at ``s`` [m], ``speed`` [m/s].

        Without a behaviour it keeps its lane at its initial speed (IDM behind others).
        ``appear``/``disappear`` (a time [s] or a ``callable(world) -> bool``, e.g.
        ``world.ego_within(inter.centre, 60)``, ``world.ego_past(spot, 20)``) spawn it later
        and remove it; absent, it is recorded with ``present`` False and NaN kinematics.
        It appears in its placed state once the condition holds and its spot is free.
        """
        from .behaviors import keep_lane
        from .engine import Actor

        self._need_road("world.car()")
        return self._vehicle(Actor, "car", lane, s, speed,
                             behavior if behavior is not None else keep_lane(), name, r, route,
                             appear, disappear)

    def bus(self, lane: Any, s: float = 0.0, speed: float = 0.0, behavior: Any = None, *,
            name: str | None = None, r: float = 0.0, route: Any = None, appear: Any = None,
            disappear: Any = None) -> Any:
        """A 12 x 2.55 m school bus; its ``stop_arm`` is recorded as signal ``"<name>.stop_arm"``.

        Other arguments as :meth:`car`.
        """
        from .behaviors import keep_lane
        from .engine import Bus

        self._need_road("world.bus()")
        return self._vehicle(Bus, "bus", lane, s, speed,
                             behavior if behavior is not None else keep_lane(), name, r, route,
                             appear, disappear)

    #: the kinds :meth:`vehicle` makes and their default size [m] (length, width): a car as
    #: :meth:`car`; a truck as the EU's largest rigid lorry (Directive 96/53/EC: 12 m, 2.55 m)
    VEHICLE_SIZES = {"car": (5.0, 2.0), "truck": (12.0, 2.55)}
    MAX_VEHICLE_LENGTH = 30.0  # [m] beyond a road train: a typo (millimetres), not a vehicle
    MAX_VEHICLE_WIDTH = 5.0  # [m] beyond any road vehicle's width

    def vehicle(self, lane: Any, s: float = 0.0, speed: float = 0.0, behavior: Any = None, *,
                kind: str = "car", length: float | None = None, width: float | None = None,
                name: str | None = None, r: float = 0.0, route: Any = None, appear: Any = None,
                disappear: Any = None) -> Any:
        """A vehicle of its own size: ``kind`` ``"car"`` (5 x 2 m) or ``"truck"`` (12 x 2.55 m),
        ``length`` and ``width`` [m] overriding the kind's size (a 16.5-m articulated lorry:
        ``world.vehicle(lane, kind="truck", length=16.5)``).

        A highway-env ``Vehicle`` with ``LENGTH``/``WIDTH`` of its own: its collisions, the
        gaps behaviours keep to it, the recording (and so every monitor's footprint), the
        pictures and the replay use that size; ``s`` is its centre, as for every vehicle. Its
        name is ``truck1``, ``truck2``… for trucks, and its ``kind`` in observations is
        ``kind``. Other arguments as :meth:`car`.
        """
        from .behaviors import keep_lane
        from .engine import Actor

        self._need_road("world.vehicle()")
        if kind not in self.VEHICLE_SIZES:
            raise SimError(f"vehicle kind={kind!r}: use one of {', '.join(map(repr, self.VEHICLE_SIZES))} "
                           "(world.bus() for a school bus, world.pedestrian() for a pedestrian)",
                           test=self.name, agent=name)
        default_length, default_width = self.VEHICLE_SIZES[kind]
        size = {"length": (length, default_length, self.MAX_VEHICLE_LENGTH),
                "width": (width, default_width, self.MAX_VEHICLE_WIDTH)}
        checked = {}
        for what, (given, default, most) in size.items():
            value = default if given is None else given
            try:
                number = float(value)
            except (TypeError, ValueError):
                number = math.nan
            if isinstance(value, bool) or not (math.isfinite(number) and 0.0 < number <= most):
                raise SimError(f"vehicle {what}={value!r}: must be a number of metres, "
                               f"0 < {what} <= {most:g}", test=self.name, agent=name)
            checked[what] = number

        def sized(position: Any, heading: float, speed_mps: float) -> Any:
            agent = Actor(position, heading, speed_mps)
            # instance constants shadow the class's: highway-env reads self.LENGTH / WIDTH for
            # the outline, the collision test and (through diagonal) its broad phase
            agent.LENGTH, agent.WIDTH = checked["length"], checked["width"]
            agent.diagonal = math.hypot(agent.LENGTH, agent.WIDTH)
            return agent

        return self._vehicle(sized, kind, lane, s, speed,
                             behavior if behavior is not None else keep_lane(), name, r, route,
                             appear, disappear)

    def parked_car(self, lane: Any, s: float = 0.0, behavior: Any = None, *,
                   name: str | None = None, appear: Any = None, disappear: Any = None) -> Any:
        """A standing 5 x 2 m car, usually on ``road.parking_lane``; ``b.pull_out`` moves it."""
        from .behaviors import stopped
        from .engine import Actor

        self._need_road("world.parked_car()")
        return self._vehicle(Actor, "parked", lane, s, 0.0,
                             behavior if behavior is not None else stopped(), name, 0.0,
                             None, appear, disappear)

    def pedestrian(self, path: Any, side: str | None = None, speed: float = 1.4,
                   behavior: Any = None, *, name: str | None = None, appear: Any = None,
                   disappear: Any = None) -> Any:
        """A pedestrian (0.6 m) walking ``path`` at ``speed`` [m/s].

        ``path`` is a crosswalk (walked from ``side``, default its first side), a
        :class:`~.places.Path` or a list of (x, y) points [m]. Without a behaviour it walks
        straight away; ``b.cross(wait=..., wait_in_road=...)`` adds the waits (times in
        behaviours count from the agent's appearance: ``agent.age``).
        ``appear``/``disappear`` as for :meth:`car`.
        """
        from .behaviors import walk
        from .engine import Pedestrian

        self._need_road("world.pedestrian()")
        name = self._name("pedestrian", name)
        if isinstance(path, Crosswalk):
            try:
                p = path.walk(side)
            except ValueError as exc:
                raise SimError(str(exc), test=self.name, agent=name) from None
        elif isinstance(path, Path):
            p = path
        else:
            try:
                p = Path.through(path)
            except (TypeError, ValueError, IndexError) as exc:
                raise SimError(f"path={path!r}: give a crosswalk, a Path or a list of (x, y) "
                               f"points ({exc})", test=self.name, agent=name) from None
        pts = p.array
        if not np.all(np.isfinite(pts)):
            raise SimError(f"path has non-finite points: {pts.tolist()}", test=self.name, agent=name)
        if p.length <= 0:
            raise SimError("path has zero length", test=self.name, agent=name)
        v = self._check_speed(speed, name)
        bound = self._bind(behavior if behavior is not None else walk(), "pedestrian", name)
        agent = Pedestrian(pts, v)
        agent.road = self._road
        agent.appear = self._when(appear, "appear", name)
        agent.disappear = self._when(disappear, "disappear", name)
        agent._attach(self, name, "pedestrian", None, [], bound, v)
        self._check_overlap(agent)
        self._others.append(agent)
        return agent

    # -- queries during a run -------------------------------------------------------------------------
    def agent(self, name: str) -> Any:
        """The agent called ``name`` (``"ego"``, ``"car1"``…)."""
        for a in self._all():
            if a.name == name:
                return a
        raise KeyError(f"no agent {name!r}; agents: {[a.name for a in self._all()]}")

    @property
    def agents(self) -> list[Any]:
        """All agents, ego first."""
        return self._all()

    def distance(self, a: Any, b: Any) -> float:
        """Euclidean distance [m] between two agents (or names) and/or places."""
        a = self.agent(a) if isinstance(a, str) else a
        b = self.agent(b) if isinstance(b, str) else b
        return _distance(a, b)

    def _junction(self, agent: Any) -> Any:
        """The intersection ``agent`` (default the ego) is at or driving toward, or None."""
        road = self.road
        kind = getattr(road, "kind", "")
        if kind == "intersection":
            return road
        who = agent if agent is not None else self._ego
        if kind == "network" and who is not None:
            return road.junction_ahead(who)
        return None

    def turn_route(self, agent: Any, direction: str) -> Route:
        """The agent's route from its current lane through the next intersection's turn."""
        road = self.road
        kind = getattr(road, "kind", "")
        if kind not in ("intersection", "network"):
            raise SimError(f"turn {direction!r} needs an intersection road, this is a "
                           f"{kind or None} road", test=self.name, agent=agent.name)
        ahead = agent.plan[agent.route_index:]
        # The next approach lane on the route (the current lane on a single intersection).
        k, inter, arm = 0, None, None
        for k, lane in enumerate(ahead if kind == "network" else ahead[:1]):
            inter = road.junction_of(lane) if kind == "network" else road
            arm = inter.arm_of(lane) if inter is not None else None
            if arm is not None:
                break
        if arm is None:
            lane = ahead[0]
            raise SimError(f"turn {direction!r}: place the agent on an approach lane "
                           f"(it is on {lane.id!r})", test=self.name, agent=agent.name)
        lane = ahead[k]
        try:
            turn = inter.route(arm, direction, lane.number)
        except SimError:
            turn = inter.route(arm, direction)
        return Route(tuple(ahead[:k]) + turn.lanes, turn=turn.turn)

    def ego_distance_to_centre(self, agent: Any = None) -> float:
        """Distance [m] from the ego to the centre of the intersection ``agent`` is at or
        driving toward (or to ``agent`` itself where there is none)."""
        if self._ego is None:
            return math.inf
        inter = self._junction(agent)
        return _distance(self._ego, inter.centre if inter is not None else agent)

    def ego_in_conflict(self, agent: Any) -> bool:
        """Whether the ego is inside the intersection ``agent`` is at (or driving toward), or
        approaching it within 30 m."""
        inter = self._junction(agent)
        if inter is None or self._ego is None:
            return False
        centre = inter.centre
        e = self._ego
        d = _distance(e, centre)
        if d < inter.half + 3.0:
            return True
        dx, dy = centre.x - float(e.position[0]), centre.y - float(e.position[1])
        approaching = math.cos(e.heading) * dx + math.sin(e.heading) * dy > 0 and e.speed > 0.1
        return approaching and d < 30.0

    # -- observation -------------------------------------------------------------------------------
    def _state(self, a: Any, kind: str | None = None) -> AgentState:
        h = float(a.heading)
        v = float(a.speed)
        p = a.position
        return _frozen(AgentState, {
            "name": a.name, "kind": kind or a.kind, "x": float(p[0]), "y": float(p[1]),
            "vx": v * math.cos(h), "vy": v * math.sin(h), "speed": v, "heading": h,
            "length": float(a.LENGTH), "width": float(a.WIDTH),
            "flags": {"stop_arm": bool(a.stop_arm)} if a.kind == "bus" else {}})

    def observe(self, ego: Any) -> Observation:
        """What the driver of ``ego`` sees now: the :class:`~.observation.Observation`."""
        x, y = float(ego.position[0]), float(ego.position[1])
        near = []
        rng2 = self.sensor_range ** 2
        for i, o in enumerate(self._movers):
            if o is ego:
                continue
            dx, dy = float(o.position[0]) - x, float(o.position[1]) - y
            d2 = dx * dx + dy * dy
            if d2 <= rng2:
                near.append((d2, i, o))
        near.sort(key=lambda t: (t[0], t[1]))
        ri = ego.route_index
        stops = self._stop_cache.get(ri)
        if stops is None:
            stops = tuple(ObsStopLine(j, s, kind) for j in range(ri, len(ego.plan))
                          for s, kind in self._index.stop_marks.get(ego.plan[j].index, ()))
            self._stop_cache[ri] = stops
        return _frozen(Observation, {
            "t": self.t, "dt": self.dt, "ego": self._state(ego, "ego"), "route": self._route_geoms,
            "route_index": ri, "s": float(ego.route_s), "r": float(ego.route_r),
            "agents": tuple(self._state(o) for _, _, o in near), "stop_lines": stops,
            "speed_limit": float(ego.plan[ri].geometry.speed_limit),
            "target_speed": ego.target_speed_request, "goal": ego.goal,
            "sensor_range": self.sensor_range, "traffic_lights": self._lights_seen(ego)})

    def _lights_seen(self, ego: Any) -> tuple:
        lights = self._lights if self._lights is not None else self.traffic_lights
        if not lights:
            return ()
        ahead = self._stops_ahead(lights, ego, 150.0)
        if not ahead:
            return ()
        t = self.t
        # the lights' states change every few seconds: the observation's tuple is made again
        # only when one changed or the stops ahead did (its items are frozen, so shared), and
        # the states are asked again only when one may have changed
        seen = ego.__dict__.get("_lights_seen")
        if seen is not None and seen[0] is ahead and seen[3] <= t < seen[4]:
            return seen[2]
        states, until = lights.states([sid for _, _, _, sid in ahead], t)
        if seen is not None and seen[0] is ahead and seen[1] == states:
            out = seen[2]
        else:
            out = tuple(_frozen(TrafficLight, {"route_index": j, "s": s, "state": st,
                                               "signal": sid})
                        for (j, s, _, sid), st in zip(ahead, states))
        ego._lights_seen = (ahead, states, out, t, until)
        return out

    def view(self) -> Any:
        """A read-only :class:`~.view.SceneView` of the simulation now: every lane of the road
        network with its geometry, and the state of every agent on the road (ego first), in
        the world frame. For drivers that need more than their observation (they get the
        world from their ``reset(world)`` hook); before a run, the agents placed to be there
        at t = 0."""
        from . import view as _view

        if self._index is None:
            raise SimError("world.view(): build a road first", test=self.name)
        cached = getattr(self, "_view_cache", None)
        if cached is None or cached[0] is not self._index:
            cached = (self._index, _view.lane_views(self._index), _view.stop_marks(self._index))
            self._view_cache = cached
        running = getattr(self, "_agents_in_order", None) is not None
        agents = list(self._movers) if running else [a for a in self._all() if a.appear is None]
        return _view.SceneView(
            t=float(self.t), dt=float(self.dt), ego=self._ego.name if self._ego is not None else "",
            lanes=cached[1],
            agents=tuple(self._state(a) for a in agents),
            agent_lanes=_view.agent_lanes(self._index, agents), stop_marks=cached[2])

    # -- running -----------------------------------------------------------------------------------
    def run(self, seconds: float, dt: float | None = None,
            until: Callable[["World"], bool] | None = None,
            stop_on_collision: bool = False) -> Trajectory:
        """Simulate ``seconds`` [s] in steps of ``dt`` [s] and record; returns the trajectory.

        ``dt`` given is the step, whatever the driver. Without it the step is the world's
        ``dt`` setting (the plugin's ``@scenario(dt=...)`` > ``--avs-dt`` > ini ``avs_dt``),
        else the step the ego's driver declares as its ``dt`` attribute (a highway-env
        agent: its environment's ``1 / simulation_frequency``), else 0.1 s.
        ``until(world)`` is asked after every step and ends the run early when true;
        ``stop_on_collision`` ends it at the step the ego first crashes. The recording has
        ``round(seconds / dt) + 1`` samples (fewer when stopped early), t = 0 first.
        """
        dt_from = None  # the test's own: said once dt is known to be a number
        if dt is None:
            dt, dt_from = self._default_step()
        for label, val in (("seconds", seconds), ("dt", dt)):
            try:
                ok = math.isfinite(float(val)) and float(val) > 0
            except (TypeError, ValueError):
                ok = False
            if not ok:
                raise SimError(f"run({label}={val!r}): need a finite number > 0 [s]", test=self.name)
        if until is not None and not callable(until):
            raise SimError(f"run(until={until!r}): need a callable(world) -> bool", test=self.name)
        self._need_road("world.run()")
        if self._ego is None:
            raise SimError("world.run(): place the ego first (world.ego(...))", test=self.name)
        seconds, dt = float(seconds), float(dt)
        n_steps = max(1, int(round(seconds / dt)))
        self.dt = dt
        self.dt_from = dt_from or f"world.run(dt={dt:g})"
        ego = self._ego
        agents = [ego] + self._others
        for a in agents:
            a.active = a.appear is None
            a.gone = False
            a.appeared_at = 0.0 if a.active else None  # [s] simulation time it appeared
        self._agents_in_order = agents
        self._sync_active()
        self._route_geoms = tuple(l.geometry for l in ego.plan)
        self._stop_cache = {}
        self.t = 0.0
        for a in agents:
            if a.behavior is not None:
                try:
                    a.behavior.start(a, self)
                except SimError:
                    raise
                except ValueError as exc:
                    raise SimError(f"behaviour {a.behavior.name}: {exc}", test=self.name,
                                   agent=a.name) from exc
        self._reset_driver(ego)
        rec = Recorder(self, agents, n_steps + 1)
        road = self._road
        reason = None
        k = 0
        # Arrivals and departures happen at sample times, so an agent's first recorded sample
        # is its placed state and its last one the state it left in.
        late = [a for a in agents if not a.active]
        leaving = [a for a in agents if a.disappear is not None]
        if late and self._arrivals(late):
            late = [a for a in late if not a.active]
        rec.write(0)
        for k in range(1, n_steps + 1):
            self.t = (k - 1) * dt
            road.act()
            road.step(dt)
            self.t = k * dt
            if leaving and self._departures(leaving):
                leaving = [a for a in leaving if not a.gone]
            if late and self._arrivals(late):
                late = [a for a in late if not a.active]
            rec.write(k)
            if stop_on_collision and ego.crashed:
                reason = "collision"
                break
            if until is not None and until(self):
                reason = "until"
                break
        self.trajectory = rec.finish(k + 1, seconds=seconds, stopped=reason)
        return self.trajectory

    def _default_step(self) -> tuple[Any, str]:
        """run()'s step when it gives none, and where it came from (see :meth:`run`)."""
        if self.step_setting is not None:
            return self.step_setting, self.step_setting_from
        declared = None if self._step_driver is None else declared_step(self._step_driver)
        if declared is None:
            return 0.1, "the default"
        try:
            ok = not isinstance(declared, bool) and math.isfinite(float(declared)) \
                and float(declared) > 0
        except (TypeError, ValueError):
            ok = False
        if not ok:
            raise SimError(f"driver {self._step_driver!r} declares dt={declared!r}: a driver's "
                           "dt is the step it was made for, a finite number > 0 [s] (or None)",
                           test=self.name, agent=self._ego.name)
        return float(declared), f"the driver's own step ({self._step_driver!r})"

    def warn(self, warning: Warning, key: str = "") -> None:
        """Report ``warning`` (a :class:`~.errors.SimWarning`); ``key`` names what it is about,
        so that the plugin says it once per test."""
        if self._warn is not None:
            self._warn(warning, key)
        else:
            import warnings

            warnings.warn(warning, stacklevel=3)

    def _reset_driver(self, ego: Any) -> None:
        """The driver's per-case hook: ``reset(world)`` once, before the first step."""
        reset = getattr(ego.driver, "reset", None)
        if not callable(reset):
            return
        try:
            reset(self)
        except SimError:
            raise
        except Exception as exc:  # the driver is user code: report, never swallow
            import traceback

            raise DriverError(
                f"driver {ego.driver!r}: reset(world) raised {type(exc).__name__}: {exc} "
                "(the per-case hook is reset(self, world), called before the run)",
                test=self.name, agent=ego.name, driver_traceback=traceback.format_exc()) from exc

    def _sync_active(self) -> None:
        active = [a for a in self._agents_in_order if a.active]
        self._movers = active
        self._road.vehicles = list(active)

    def _arrivals(self, late: list[Any]) -> bool:
        changed = False
        for a in late:
            if self._due(a.appear) and self._overlapping(a, self._movers) is None:
                a.active = True
                a.appeared_at = self.t
                self._sync_active()
                changed = True
        return changed

    def _departures(self, leaving: list[Any]) -> bool:
        changed = False
        for a in leaving:
            if a.active and self._due(a.disappear):
                a.active = False
                a.gone = True
                changed = True
        if changed:
            self._sync_active()
        return changed

    # -- rendering ---------------------------------------------------------------------------------
    def render_png(self, path: str, step: int | None = None, **kw: Any) -> str:
        """Write a PNG of the recorded run: one frame at ``step``, or a grid of 6 frames.

        Replays ``world.trajectory`` (call :meth:`run` first) offscreen; never opens a display.
        ``centre=`` (an (x, y) [m], a place or an agent name) and ``width=`` [m] fix the view
        (default: a window following the ego; the whole intersection). Returns the path.
        """
        from .render import render_png

        return render_png(self, path, step=step, **kw)

    def render_gif(self, path: str, every: int = 1, **kw: Any) -> str:
        """Write an animated GIF replaying every ``every``-th recorded step (view options as
        :meth:`render_png`). Returns the path."""
        from .render import render_gif

        return render_gif(self, path, every=every, **kw)


def _joint_gap(a: Lane, b: Lane) -> float:
    """[m] from the end of lane ``a`` to the start of lane ``b`` (a route's joint); kept with
    ``a``'s geometry when it offers a ``memo`` (a map's lanes never change)."""
    memo = getattr(a.geometry, "memo", None)
    key = ("gap to", b.geometry)
    got = memo.get(key) if memo is not None else None
    if got is None:
        got = float(np.hypot(*(a.end.position - b.start.position)))
        if memo is not None:
            memo[key] = got
    return got


def _quietly_resolved(driver: Any) -> Any:
    """The driver object for ``driver``, or None when it cannot be made (only its step is
    wanted: the driver that drives is another)."""
    try:
        return resolve(driver)
    except Exception:
        return None


def _frozen(cls: Any, values: dict) -> Any:
    """An instance of the frozen dataclass ``cls`` with every field given in ``values``.

    The generated ``__init__`` of a frozen dataclass sets each field through
    ``object.__setattr__`` (~0.3 µs a field); observations are built every step of every case,
    so they are filled in one ``__dict__`` update instead. ``values`` must name every field.
    """
    obj = object.__new__(cls)
    obj.__dict__.update(values)
    return obj

"""Our highway-env subclasses: lanes, vehicles, pedestrians, the IDM ego, each with its own constants.

This is the only module that imports highway-env at import time; the world imports it when it
builds its first road, never at plugin load. Every class here sets the class constants it
relies on itself, so code elsewhere in the process that rewrites highway-env's constants (e.g.
``intersection-v0`` rewriting ``IDMVehicle.COMFORT_ACC_MAX``) cannot change a scenario's
outcome. Each agent keeps its lane by tracking (see :mod:`.lanes`) rather than
highway-env's scan of every lane per step.

Agents expose the few helpers behaviours drive with: ``age`` (seconds since the agent
appeared), ``follow()``, ``idm()``, ``distance_along_route()``, ``change_lane()``,
``take_turn()``, ``curve_speed_cap()``.
"""

from __future__ import annotations

import bisect
import math
import traceback
from typing import Any

import numpy as np
from ._hwenv import load_core

load_core()  # roads and vehicles without highway-env's gym environments (see _hwenv)

from highway_env.road.lane import CircularLane, LineType, SineLane, StraightLane  # noqa: E402
from highway_env.road.road import Road  # noqa: E402
from highway_env.vehicle.behavior import IDMVehicle  # noqa: E402
from highway_env.vehicle.kinematics import Vehicle  # noqa: E402

from . import control
from .drivers import action_pair
from .errors import DriverError, SimError
from .geometry import wrap_to_pi
from .signals import GREEN, must_stop

__all__ = ["Straight", "Arc", "Sine", "LineType", "SimRoad", "Actor", "Bus", "DriverEgo", "IDMEgo", "Pedestrian",
           "agent_class"]


# -- lanes ----------------------------------------------------------------------------------------


class Straight(StraightLane):
    """A straight lane with scalar-math coordinate transforms (highway-env's use numpy per call)."""

    DEFAULT_WIDTH = 3.5
    VEHICLE_LENGTH = 5.0

    def __init__(self, start, end, width: float = 3.5, line_types=None, speed_limit: float = 13.9,
                 forbidden: bool = False) -> None:
        super().__init__(start, end, width=width, line_types=line_types, speed_limit=speed_limit,
                         forbidden=forbidden)
        self._sx, self._sy = float(self.start[0]), float(self.start[1])
        self._dx, self._dy = float(self.direction[0]), float(self.direction[1])
        self.length = float(self.length)
        self.heading = float(self.heading)
        self.radius = math.inf

    def position(self, longitudinal: float, lateral: float) -> np.ndarray:
        return np.array([self._sx + longitudinal * self._dx - lateral * self._dy,
                         self._sy + longitudinal * self._dy + lateral * self._dx])

    def local_coordinates(self, position) -> tuple[float, float]:
        ex = position[0] - self._sx
        ey = position[1] - self._sy
        return float(ex * self._dx + ey * self._dy), float(ey * self._dx - ex * self._dy)


class Arc(CircularLane):
    """A circular-arc lane (turn connector) with scalar-math coordinate transforms."""

    DEFAULT_WIDTH = 3.5
    VEHICLE_LENGTH = 5.0

    def __init__(self, center, radius: float, start_phase: float, end_phase: float,
                 clockwise: bool = True, width: float = 3.5, line_types=None,
                 speed_limit: float = 13.9) -> None:
        super().__init__(center, radius, start_phase, end_phase, clockwise=clockwise, width=width,
                         line_types=line_types, speed_limit=speed_limit)
        self._cx, self._cy = float(self.center[0]), float(self.center[1])
        self.length = float(self.length)

    def local_coordinates(self, position) -> tuple[float, float]:
        dx = position[0] - self._cx
        dy = position[1] - self._cy
        phi = math.atan2(dy, dx)
        phi = self.start_phase + wrap_to_pi(phi - self.start_phase)
        r = math.hypot(dx, dy)
        return (float(self.direction * (phi - self.start_phase) * self.radius),
                float(self.direction * (self.radius - r)))


class Sine(SineLane):
    """highway-env's sinusoidal lane (an on-ramp's S-bend) with scalar-math transforms.

    The centre line is ``amplitude * sin(pulsation * s + phase)`` [m] left of the straight
    line from ``start`` to ``end``; ``s`` [m] is measured along that line (as highway-env's).
    """

    DEFAULT_WIDTH = 3.5
    VEHICLE_LENGTH = 5.0

    def __init__(self, start, end, amplitude: float, pulsation: float, phase: float,
                 width: float = 3.5, line_types=None, speed_limit: float = 13.9) -> None:
        super().__init__(start, end, amplitude, pulsation, phase, width=width,
                         line_types=line_types, speed_limit=speed_limit)
        self._sx, self._sy = float(self.start[0]), float(self.start[1])
        self._dx, self._dy = float(self.direction[0]), float(self.direction[1])
        self.length = float(self.length)
        self.heading = float(self.heading)
        self.radius = math.inf
        self.amplitude, self.pulsation, self.phase = (float(amplitude), float(pulsation),
                                                      float(phase))

    def _offset(self, s: float) -> float:
        return self.amplitude * math.sin(self.pulsation * s + self.phase)

    def position(self, longitudinal: float, lateral: float) -> np.ndarray:
        lat = lateral + self._offset(longitudinal)
        return np.array([self._sx + longitudinal * self._dx - lat * self._dy,
                         self._sy + longitudinal * self._dy + lat * self._dx])

    def heading_at(self, longitudinal: float) -> float:
        return self.heading + math.atan(self.amplitude * self.pulsation
                                        * math.cos(self.pulsation * longitudinal + self.phase))

    def local_coordinates(self, position) -> tuple[float, float]:
        ex = position[0] - self._sx
        ey = position[1] - self._sy
        s = float(ex * self._dx + ey * self._dy)
        return s, float(ey * self._dx - ex * self._dy) - self._offset(s)


# -- the road -------------------------------------------------------------------------------------


class SimRoad(Road):
    """highway-env's Road with a vectorized broad phase before its pairwise collision test.

    highway-env checks every pair of vehicles every step with numpy calls per pair; with many
    agents that dominates. Pairs that cannot touch this step (centres further apart than their
    half diagonals plus what both can travel in ``dt``) are skipped with one array operation;
    the remaining pairs go through highway-env's own ``handle_collisions`` in the same order,
    so results equal the plain loop's.
    """

    BROAD_PHASE_FROM = 5  # agents; below this the per-pair loop is cheaper

    def step(self, dt: float) -> None:
        vehicles = self.vehicles
        for v in vehicles:
            v.step(dt)
        n = len(vehicles)
        if n < self.BROAD_PHASE_FROM:
            for i, v in enumerate(vehicles):
                for other in vehicles[i + 1:]:
                    v.handle_collisions(other, dt)
        else:
            pos = np.array([v.position for v in vehicles])
            reach = np.array([v.diagonal / 2 + abs(v.speed) * dt for v in vehicles])
            d = np.hypot(pos[:, None, 0] - pos[None, :, 0], pos[:, None, 1] - pos[None, :, 1])
            close = np.triu(d <= reach[:, None] + reach[None, :], k=1)
            for i, j in zip(*np.nonzero(close)):
                vehicles[i].handle_collisions(vehicles[j], dt)
        for v in vehicles:
            for o in self.objects:
                v.handle_collisions(o, dt)


# -- vehicles -------------------------------------------------------------------------------------


class _Agent:
    """Mixin: identity, lane tracking, route progress and the helpers behaviours use.

    :meth:`_attach` sets ``world``, ``name``, ``kind`` and ``plan``: the route as our
    :class:`~.places.Lane` objects (not ``route``, which highway-env's controlled vehicles, the
    IDM ego among them, use for their own list of lane indices), with ``route_index`` the lane
    of it the agent is on and ``route_s``/``route_r`` [m] its coordinates there.
    """

    allow_reverse = False

    def _attach(self, world: Any, name: str, kind: str, lane: Any, route: list, behavior: Any,
                initial_speed: float, route_index: int = 0) -> None:
        self.world = world
        self.name = name
        self.kind = kind
        self.plan = list(route)
        self.route_index = route_index
        self.route_s = 0.0
        self.route_r = 0.0
        self.behavior = behavior
        self.initial_speed = float(initial_speed)
        self.lane_index = lane.index if lane is not None else None
        self.lane = lane.geometry if lane is not None else None
        self.lane_r = math.nan
        self.is_on_road = lane is not None
        self.stop_arm = False
        world.lane_index.track(self)

    def on_state_update(self) -> None:
        # Replaces highway-env's per-step scan of every lane of the network.
        if getattr(self, "world", None) is not None:
            self.world.lane_index.track(self)

    def step(self, dt: float) -> None:
        super().step(dt)
        if self.speed < 0.0 and not self.allow_reverse:
            # Brakes stop a car; they do not put it in reverse.
            self.speed = 0.0

    # -- helpers for behaviours -----------------------------------------------------------------
    @property
    def age(self) -> float:
        """[s] time since the agent appeared: ``world.t - appeared_at`` (the simulation time for
        an agent present from t = 0). Behaviours measure their times with it, so ``brake_at(t=2)``
        of an agent that appears late brakes 2 s after it appeared. 0 before a run starts."""
        t0 = getattr(self, "appeared_at", None)
        return float(self.world.t) - (t0 if t0 is not None else float(self.world.t))

    @property
    def cruise_speed(self) -> float:
        """[m/s] the initial speed, or the lane's speed limit for an agent placed standing."""
        if self.initial_speed > 0:
            return self.initial_speed
        return float(self.route_lane.geometry.speed_limit)

    @property
    def route_lane(self) -> Any:
        return self.plan[self.route_index]

    def _route_heading(self, ahead: float) -> float:
        """Heading [rad] of the route ``ahead`` metres beyond the agent's projection."""
        i, s = self.route_index, self.route_s + ahead
        while s > self.plan[i].length and i + 1 < len(self.plan):
            s -= self.plan[i].length
            i += 1
        return float(self.plan[i].geometry.heading_at(s))

    def follow(self, r: float = 0.0, settle: float | None = None) -> float:
        """Steering [rad] that keeps the agent ``r`` metres left of its route's centre line.

        ``settle`` [s] is roughly how long it takes to close a lateral error (a lane change's
        duration; default 1.8 s).
        """
        k_lat = 3.0 / settle if settle else 1 / 0.6
        v = float(self.speed)
        path_heading = self._route_heading(max(v, 0.0) * 0.1)
        return control.lane_steering(v, float(self.heading), self.route_r - r, path_heading,
                                     self.LENGTH, k_lateral=k_lat)

    def leader(self, horizon: float = 60.0) -> tuple[float, float] | None:
        """``(gap [m], speed along the route [m/s])`` of the nearest agent ahead in our path.

        Sees agents on the next two route lanes whose footprint overlaps our path and that
        drive roughly our way (within 60 degrees) or stand nearly still (pedestrians, parked or
        stopped cars); crossing traffic is not seen, as in highway-env's IDM.
        """
        px, py = float(self.position[0]), float(self.position[1])
        # Anything within the horizon along the route is within it as the crow flies too.
        reach = horizon + self.LENGTH + 12.0
        best: tuple[float, float] | None = None
        here = self.plan[self.route_index].geometry
        lanes = [(here, -self.route_s)]
        if self.route_index + 1 < len(self.plan):
            lanes.append((self.plan[self.route_index + 1].geometry, here.length - self.route_s))
        for o in self.world.movers:
            if o is self:
                continue
            pos = o.position
            if abs(pos[0] - px) > reach or abs(pos[1] - py) > reach:
                continue
            known = getattr(o, "tracked", None)
            if known is not None and (known[0] != pos[0] or known[1] != pos[1]):
                known = None  # it moved since
            for g, offset in lanes:
                if known is not None and known[2] is g:
                    s_o, r_o = known[3], known[4]
                else:
                    s_o, r_o = g.local_coordinates(pos)
                if abs(r_o) > (self.WIDTH + o.WIDTH) / 2 + 0.2:
                    continue
                if s_o < -o.LENGTH / 2 or s_o > g.length + o.LENGTH / 2:
                    continue
                ahead = s_o + offset
                if ahead <= 0.0:
                    break
                rel = math.cos(o.heading - g.heading_at(s_o))
                if rel < 0.5 and o.speed > 0.5 and o.kind != "pedestrian":
                    break
                gap = ahead - (self.LENGTH + o.LENGTH) / 2
                if gap <= horizon and (best is None or gap < best[0]):
                    best = (gap, o.speed * max(rel, 0.0))
                break
        return best

    def idm(self, target_speed: float, stop_in: float | None = None) -> float:
        """IDM acceleration [m/s^2] toward ``target_speed`` [m/s] behind the leader.

        ``stop_in`` [m] adds a virtual standing obstacle that far ahead (a stop line).
        """
        lead = self.leader()
        gap, v_lead = (lead if lead is not None else (None, 0.0))
        light = self.light_stop()
        if light is not None:
            stop_in = light if stop_in is None else min(stop_in, light)
        if stop_in is not None and (gap is None or stop_in < gap):
            # Treat the line as a standing car whose rear is at the line.
            gap, v_lead = stop_in + control.IDM.s0, 0.0
        return control.idm_acceleration(float(self.speed), float(target_speed), gap, v_lead)

    #: [m] the front bumper stops this far before a traffic light's stop position
    LIGHT_MARGIN = 1.0

    def light_stop(self, comfort_decel: float = control.IDM.b_comf) -> float | None:
        """Distance [m] from the front bumper to where the agent stops for the next traffic
        light on its route (negative within :data:`LIGHT_MARGIN` of the line), or None when
        no light stops it. It stops on red, and on amber when it can stop at
        ``comfort_decel`` [m/s^2] (see :func:`.signals.must_stop`); having gone on at amber
        (or too close to stop on red) it keeps going through that light."""
        world = self.world
        lights, ahead = world.light_stops(self)
        if not ahead:
            return None
        went = self.__dict__.get("_light_went")
        if went is None:
            went = self._light_went = set()
        v = max(float(self.speed), 0.0)
        rs, t = float(self.route_s), world.t
        for _, _, acc, sid in ahead:  # (world.lights_ahead's distances, states asked as needed)
            front = (acc - rs) - self.LENGTH / 2
            if front < 0.0:
                continue  # the front is past the line: it has gone
            state = lights.state(sid, t)
            if state == GREEN:
                went.discard(sid)
                continue
            if must_stop(state, front, v, comfort_decel, control.MAX_DECELERATION, sid in went):
                return front - self.LIGHT_MARGIN  # negative once within the margin
            went.add(sid)
        return None

    def distance_along_route(self, place: Any) -> float:
        """Signed distance [m] along the route from the agent's centre to ``place``.

        ``place`` is a spot or stop line (a lane and ``s``) or any object with a
        ``position``; positive when it lies ahead.
        """
        from .places import Lane

        # a place's lane (a spot, a stop line); an agent's ``lane`` is highway-env's own and
        # goes by its position like anything else
        lane = getattr(place, "lane", None)
        if isinstance(lane, Lane):
            idx = lane.index
            for j in range(self.route_index, len(self.plan)):
                if self.plan[j].index == idx:
                    return (sum(self.plan[k].length for k in range(self.route_index, j))
                            + float(place.s) - self.route_s)
            if self.lane_index == idx:
                return float(place.s) - lane.local(self.position)[0]
        # Anything else: distance projected on the heading.
        p = np.asarray(getattr(place, "position", place), dtype=float)
        d = p - self.position
        return float(d[0] * math.cos(self.heading) + d[1] * math.sin(self.heading))

    def distance_to_stop_line(self) -> float | None:
        """Distance [m] along the route to the next stop line (negative once passed), or None."""
        found = self.stop_line_ahead()
        return found[0] if found is not None else None

    def stop_line_ahead(self) -> tuple[float, int] | None:
        """``(distance [m] from the centre, index in plan of its lane)`` of the next stop line
        on the route (the distance is negative once passed, until the agent leaves that
        lane), or None."""
        marks = self.world.lane_index.stop_marks
        ahead = -self.route_s
        for j in range(self.route_index, len(self.plan)):
            lane = self.plan[j]
            for s, kind in marks.get(lane.index, ()):
                if kind == "stop":
                    return ahead + s, j
            ahead += lane.length
        return None

    def curve_speed_cap(self, lateral_acc: float = 2.5, decel: float = 2.0) -> float:
        """Highest speed [m/s] now so curves on the route ahead stay under ``lateral_acc``."""
        cap = math.inf
        ahead = -self.route_s
        for j in range(self.route_index, min(self.route_index + 3, len(self.plan))):
            g = self.plan[j].geometry
            radius = getattr(g, "radius", math.inf)
            if math.isfinite(radius):
                v_c = control.curve_speed(radius, lateral_acc)
                cap = min(cap, math.sqrt(v_c * v_c + 2.0 * decel * max(ahead, 0.0)))
            ahead += self.plan[j].length
        return cap

    def change_lane(self, to: Any) -> None:
        """Re-plan the route onto lane ``to``: "left", "right", "out" (from parking), a number
        or a Lane."""
        target = self.world.lane_index.resolve_lane_change(self, to)
        self.plan = self.world.lane_index.continue_route(target)
        self.route_index = 0
        s, r = target.geometry.local_coordinates(self.position)
        self.route_s, self.route_r = s, r

    def lane_end_ahead(self) -> tuple[float, str, bool] | None:
        """``(distance [m] from the centre, side, on_it)`` when the route ends in a lane that
        ends with traffic in it (a lane drop, an on-ramp's acceleration lane): how far its end
        is, the side ("left"/"right") to merge to, and whether the agent is on that lane
        already. None when the route runs on."""
        plan = self.plan
        side = self.world.lane_index.drops.get(plan[-1].index)
        if side is None:
            return None
        # the lanes' lengths from here to the route's end, summed once per lane reached (a
        # map's default route runs on for up to 64 lanes)
        ri = self.route_index
        memo = self.__dict__.get("_end_memo")
        if memo is None or memo[0] is not plan or memo[1] != ri:
            memo = self._end_memo = (plan, ri, sum(plan[j].length for j in range(ri, len(plan))))
        d = memo[2] - self.route_s
        return d, side, ri == len(plan) - 1

    def gap_is_safe(self, to: Any, decel: float = 3.0) -> bool:
        """Whether moving into lane ``to`` ("left", "right", a number or a Lane) now is safe:
        neither we behind the new leader nor the new follower behind us would have to brake
        harder than ``decel`` [m/s^2] by the IDM (MOBIL's safety criterion)."""
        target = self.world.lane_index.resolve_lane_change(self, to).geometry
        s_me, _ = target.local_coordinates(self.position)
        v = float(self.speed)
        half = target.width_at(0.0) / 2 + 0.5
        for o in self.world.movers:
            if o is self:
                continue
            s_o, r_o = target.local_coordinates(o.position)
            if abs(r_o) > half or abs(s_o - s_me) > 150.0:
                continue
            gap = abs(s_o - s_me) - (self.LENGTH + o.LENGTH) / 2
            if gap < 1.0:
                return False
            if s_o > s_me:
                acc = control.idm_acceleration(v, max(v, 0.1), gap, float(o.speed))
            else:
                vo = float(o.speed)
                acc = control.idm_acceleration(vo, max(vo, 0.1), gap, v)
            if acc < -decel:
                return False
        return True

    def take_turn(self, direction: str) -> None:
        """Route through the intersection ahead taking ``direction``."""
        route = self.world.turn_route(self, direction)
        self.plan = list(route.lanes)
        self.route_index = 0
        s, r = self.plan[0].geometry.local_coordinates(self.position)
        self.route_s, self.route_r = s, r


class Actor(_Agent, Vehicle):
    """A car driven by a behaviour (5 x 2 m)."""

    LENGTH = 5.0
    WIDTH = 2.0
    MAX_SPEED = 40.0
    MIN_SPEED = -10.0
    HISTORY_SIZE = 0

    def __init__(self, position, heading: float, speed: float) -> None:
        # road=None skips highway-env's lane scan at construction; the world attaches the road.
        super().__init__(None, position, heading, speed)

    def act(self, action: Any = None) -> None:
        if self.crashed or self.behavior is None:
            return
        try:
            a, d = self.behavior.control(self, self.world)
        except ValueError as exc:
            if isinstance(exc, SimError):
                raise
            raise SimError(f"behaviour {self.behavior.name} failed at t={self.world.t:.2f} s: {exc}",
                           test=self.world.name, agent=self.name) from exc
        a = min(max(float(a), -control.MAX_DECELERATION), control.MAX_ACCELERATION)
        d = min(max(float(d), -control.MAX_STEERING), control.MAX_STEERING)
        Vehicle.act(self, {"acceleration": a, "steering": d})


class Bus(Actor):
    """A school bus (12 x 2.55 m) with a stop arm that behaviours set and the world records."""

    LENGTH = 12.0
    WIDTH = 2.55


class DriverEgo(Actor):
    """The ego under test: each step its driver answers (acceleration, steering) to an observation."""

    def act(self, action: Any = None) -> None:
        if self.crashed:
            return
        w = self.world
        obs = w.observe(self)
        try:
            raw = self.driver.act(obs)
        except Exception as exc:  # the driver is user code: report, never swallow
            hint = ""
            if getattr(self.driver, "style", "") == "predict":
                hint = ("; predict() gets the plugin's Observation, not an array: for a model "
                        "trained on highway-env use driver=highway_env_agent(model, "
                        "env='highway-fast-v0') from pytest_avscenario.sim.drivers")
            raise DriverError(
                f"driver {self.driver!r} raised {type(exc).__name__}: {exc} at t={w.t:.2f} s{hint}",
                test=w.name, agent=self.name, driver_traceback=traceback.format_exc()) from exc
        try:
            a, d = action_pair(raw)
        except ValueError as exc:
            raise SimError(f"driver {self.driver!r} returned a bad action at t={w.t:.2f} s: {exc}",
                           test=w.name, agent=self.name) from None
        a = min(max(a, -control.MAX_DECELERATION), control.MAX_ACCELERATION)
        d = min(max(d, -control.MAX_STEERING), control.MAX_STEERING)
        Vehicle.act(self, {"acceleration": a, "steering": d})


class IDMEgo(_Agent, IDMVehicle):
    """highway-env's IDM vehicle as the ego ("idm" driver), with its own copy of every constant.

    Values are highway-env 1.12.1's defaults, frozen here so ``intersection-v0`` (which
    rewrites ``IDMVehicle.COMFORT_ACC_MAX`` etc. process-wide) cannot change our runs. Lane
    changes are off: the ego follows its route.
    """

    LENGTH = 5.0
    WIDTH = 2.0
    MAX_SPEED = 40.0
    MIN_SPEED = -40.0
    HISTORY_SIZE = 0
    TAU_ACC = 0.6
    TAU_HEADING = 0.2
    TAU_LATERAL = 0.6
    TAU_PURSUIT = 0.5 * TAU_HEADING
    KP_A = 1 / TAU_ACC
    KP_HEADING = 1 / TAU_HEADING
    KP_LATERAL = 1 / TAU_LATERAL
    MAX_STEERING_ANGLE = np.pi / 3
    DELTA_SPEED = 5
    ACC_MAX = 6.0
    COMFORT_ACC_MAX = 3.0
    COMFORT_ACC_MIN = -5.0
    DISTANCE_WANTED = 5.0 + 5.0
    TIME_WANTED = 1.5
    DELTA = 4.0
    DELTA_RANGE = [3.5, 4.5]
    POLITENESS = 0.0
    LANE_CHANGE_MIN_ACC_GAIN = 0.2
    LANE_CHANGE_MAX_BRAKING_IMPOSED = 2.0
    LANE_CHANGE_DELAY = 1.0

    def acceleration(self, ego_vehicle, front_vehicle=None, rear_vehicle=None) -> float:
        """highway-env's IDM, and for the ego itself a traffic light that stops it acting
        as a standing car whose IDM standstill gap ends at the stop position."""
        acc = IDMVehicle.acceleration(self, ego_vehicle, front_vehicle, rear_vehicle)
        if ego_vehicle is not self or getattr(self, "world", None) is None:
            return acc
        stop = self.light_stop(comfort_decel=-self.COMFORT_ACC_MIN)
        if stop is None:
            return acc
        v = max(float(self.speed), 0.0)
        v0 = abs(float(self.target_speed)) or 1e-3
        s_star = self.DISTANCE_WANTED + v * self.TIME_WANTED + v * v / (
            2.0 * math.sqrt(-self.COMFORT_ACC_MAX * self.COMFORT_ACC_MIN))
        d = max(stop + self.DISTANCE_WANTED, 0.1)
        a_stop = self.COMFORT_ACC_MAX * (1.0 - (v / v0) ** self.DELTA - (s_star / d) ** 2)
        return min(acc, a_stop)

    def __init__(self, road, position, heading: float, speed: float, target_lane_index,
                 target_speed: float, route: list) -> None:
        IDMVehicle.__init__(self, None, position, heading, speed,
                            target_lane_index=target_lane_index, target_speed=target_speed,
                            route=route, enable_lane_change=False, timer=0.0)
        self.road = road
        self.driver = None


_AGENT_CLASSES: dict[type, type] = {}


def agent_class(base: type) -> type:
    """``base`` (a highway-env vehicle class) with the agent mixin — lane tracking, route
    progress, the helpers — and its class constants frozen at first use, so code that
    rewrites highway-env's constants later (``intersection-v0``) cannot change a case."""
    cls = _AGENT_CLASSES.get(base)
    if cls is None:
        consts = {k: getattr(base, k) for k in dir(base)
                  if k.isupper() and not callable(getattr(base, k))}
        cls = type(f"World{base.__name__}", (_Agent, base), consts)
        _AGENT_CLASSES[base] = cls
    return cls


class Pedestrian(_Agent, Vehicle):
    """A pedestrian (0.6 x 0.6 m) walking a polyline at the speed its behaviour asks for.

    It lives in ``road.vehicles`` (highway-env never steps ``road.objects``), so it moves and
    collides like a vehicle; it turns on the spot instead of following the bicycle model.
    """

    LENGTH = 0.6
    WIDTH = 0.6
    MAX_SPEED = 5.0
    MIN_SPEED = 0.0
    HISTORY_SIZE = 0
    MAX_WALK = 3.0  # [m/s] a run

    def __init__(self, path: np.ndarray, speed: float) -> None:
        self._pts = [(float(x), float(y)) for x, y in path]
        seg = np.hypot(*np.diff(np.asarray(path, dtype=float), axis=0).T)
        self._cum = [0.0] + np.cumsum(seg).tolist()
        self._seg_heading = [math.atan2(b[1] - a[1], b[0] - a[0])
                             for a, b in zip(self._pts, self._pts[1:])]
        self.path_length = self._cum[-1]
        self.walked = 0.0
        self._pause: float | None = None
        super().__init__(None, self._pts[0], self._seg_heading[0], 0.0)
        self.walk_speed = 0.0
        self.initial_walk = float(speed)

    def _place(self, u: float) -> None:
        u = min(max(u, 0.0), self.path_length)
        i = min(max(bisect.bisect_right(self._cum, u) - 1, 0), len(self._seg_heading) - 1)
        seg = self._cum[i + 1] - self._cum[i]
        f = (u - self._cum[i]) / seg if seg > 0 else 0.0
        (x0, y0), (x1, y1) = self._pts[i], self._pts[i + 1]
        self.position = np.array([x0 + f * (x1 - x0), y0 + f * (y1 - y0)])
        self.heading = self._seg_heading[i]

    def act(self, action: Any = None) -> None:
        if self.crashed or self.behavior is None:
            self.walk_speed = 0.0
            return
        v = float(self.behavior.control(self, self.world))
        if not math.isfinite(v):
            raise SimError(f"behaviour {self.behavior.name} asked for walking speed {v!r}",
                           test=self.world.name, agent=self.name)
        self.walk_speed = min(max(v, 0.0), self.MAX_WALK)

    def step(self, dt: float) -> None:
        if self.crashed:
            self.speed = 0.0
            self.impact = None
        else:
            v = self.walk_speed if self.walked < self.path_length else 0.0
            self.walked = min(self.walked + v * dt, self.path_length)
            self._place(self.walked)
            self.speed = v
            if self.impact is not None:
                self.position = self.position + self.impact
                self.crashed = True
                self.impact = None
        self.on_state_update()

    def road_pause_at(self) -> float | None:
        """Path length [m] at the middle of the first travel lane the path crosses, or None."""
        if self._pause is None:
            self._pause = self.world.lane_index.first_lane_middle(self._pts, self._cum)
        return self._pause if self._pause >= 0 else None

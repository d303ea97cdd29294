"""Reusable sub-scenarios for the example suite, and the few behaviours and monitors they need.

A sub-scenario is a plain function that adds its agents and their behaviours to a world and
returns them: ``crossing_traffic(world, inter, ...)``, ``pedestrian_crossing(world,
crosswalk, ...)``, ``parked_car_pulling_out(world, road, ...)``, ``oncoming_encroacher(world,
lane, ...)``, ``school_bus_stop(world, road, ...)``. The scenario modules use them one at a
time (1, 4, 5, 6, 8, 9, 10); ``test_11_composed_route.py`` composes three along one route.

Opportunistic composition: ``trigger=(place, within_m)`` makes a sub-scenario's agents
appear (``appear=world.ego_within(place, within_m)``) when the ego comes within ``within_m``
metres of ``place`` and disappear once the ego is 15 m past each of them
(:func:`ego_passed`); the times of their behaviours count from their appearance (as every
behaviour's do: ``agent.age``). While absent they are recorded with ``present`` False, so the
monitors judge each sub-scenario only while it applies.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from pytest_avscenario.monitors import as_monitor
from pytest_avscenario.sim import behaviors as b
from pytest_avscenario.sim.behaviors import Behavior

__all__ = [
    "slow_down", "throttle_encroach", "wobble", "ego_passed",
    "crossing_traffic", "pedestrian_crossing", "parked_car_pulling_out",
    "oncoming_encroacher", "school_bus_stop",
    "passes_stopped_school_bus", "parks",
]


# -- behaviours the library does not have (kept small; see README "needs") ---------------------


@dataclass(frozen=True)
class SlowDown(Behavior):
    """Cruise at the initial speed, brake at ``decel`` from ``t`` [s] after the agent appeared
    down to ``to_speed``."""

    t: float = 0.0
    decel: float = 4.0
    to_speed: float = 0.0

    def control(self, agent, world):
        due = agent.age >= self.t - 1e-9
        if due and agent.speed > self.to_speed + 0.05:
            return -float(self.decel), agent.follow()
        v = self.to_speed if due else agent.initial_speed
        return agent.idm(v), agent.follow()


def slow_down(t: float, decel: float, to_speed: float) -> SlowDown:
    """Brake at ``decel`` [m/s^2] from ``t`` [s] after the agent appeared until ``to_speed``
    [m/s], then hold it."""
    return SlowDown(t=t, decel=decel, to_speed=to_speed)


@dataclass(frozen=True)
class ThrottleEncroach(Behavior):
    """Accelerate with ``throttle`` x 3 m/s^2 up to ``max_speed``, drifting ``offset`` m left."""

    throttle: float = 0.5
    offset: float = 1.5
    max_speed: float = 15.0
    at: float = 0.0
    duration: float | None = None

    def control(self, agent, world):
        accel = 3.0 * self.throttle if agent.speed < self.max_speed else 0.0
        lead = agent.leader()
        if lead is not None and lead[0] < 8.0:
            accel = min(accel, agent.idm(self.max_speed))
        age = agent.age
        active = age >= self.at - 1e-9 and (self.duration is None or age < self.at + self.duration)
        r = float(self.offset) if active else 0.0
        return accel, agent.follow(r=r, settle=2.0)


def throttle_encroach(throttle: float, offset: float, max_speed: float = 15.0,
                      at: float = 0.0, duration: float | None = None) -> ThrottleEncroach:
    """An adversary that pulls away with ``throttle`` (0..1 of 3 m/s^2) up to ``max_speed``
    [m/s] and drives ``offset`` [m] left of its lane centre from ``at`` [s] after it appeared
    for ``duration`` [s] (None: to the end)."""
    return ThrottleEncroach(throttle=throttle, offset=offset, max_speed=max_speed, at=at,
                            duration=duration)


@dataclass(frozen=True)
class _Wrapping(Behavior):
    """A behaviour that changes what another one (``inner``) does: binds and starts it too."""

    inner: Any = None

    kinds = b.VEHICLES + b.PEDESTRIANS

    def bind(self, rng):
        out = super().bind(rng)
        return dataclasses.replace(out, inner=self.inner.bind(rng), state={})

    def start(self, agent, world):
        self.inner.start(agent, world)


@dataclass(frozen=True)
class Wobble(_Wrapping):
    """``inner`` with human imprecision drawn *during the run* from the world's rng (the case's
    ``case.rng``): every ``every`` seconds a new offset ~ N(0, ``sd``) is drawn and added to the
    commanded acceleration [m/s^2] of a vehicle, or to a pedestrian's walking speed as a
    fraction (0.1: +-10 %). Same case, same draws, in any process."""

    sd: float = 0.3
    every: float = 1.0

    def control(self, agent, world):
        st = self.state
        age = agent.age
        if age >= st.get("next", 0.0) - 1e-9:
            st["offset"] = float(world.rng.normal(0.0, self.sd))
            st["next"] = age + self.every
        out = self.inner.control(agent, world)
        if agent.kind == "pedestrian":
            return max(0.0, float(out) * (1.0 + st["offset"]))
        accel, steer = out
        if agent.speed <= 0.05 and accel <= 0.0:
            return accel, steer  # standing still stays standing
        return accel + st["offset"], steer


def wobble(inner: Behavior, sd: float = 0.3, every: float = 1.0) -> Wobble:
    """``inner`` with noise N(0, ``sd``) redrawn every ``every`` [s] from ``case.rng``."""
    return Wobble(inner=inner, sd=sd, every=every)


def ego_passed(name: str, by: float = 15.0):
    """A ``disappear=`` condition: the ego's rear is ``by`` [m] past the agent ``name``
    (measured along the ego's heading); :meth:`World.ego_past` on the agent, looked up by
    name because the condition is made before the agent exists."""
    return lambda world: world.ego_past(world.agent(name), by)(world)


def _spawn(world: Any, behavior: Behavior, trigger: Any, name: str) -> dict[str, Any]:
    """Keyword arguments that make an agent opportunistic: it appears when the ego comes
    within ``trigger = (place, within_m)`` and disappears once the ego has passed it."""
    if trigger is None:
        return {"behavior": behavior, "name": name}
    place, within = trigger
    return {"behavior": behavior, "name": name,
            "appear": world.ego_within(place, within), "disappear": ego_passed(name)}


# -- sub-scenarios -------------------------------------------------------------------------------


def crossing_traffic(world: Any, inter: Any, approach: str, *, first_s: float, speed: float,
                     count: int = 1, spacing: float = 20.0, turn: str = "straight",
                     lane: int = 0, start_at: float = 0.0, stops: bool = False,
                     jitter: float = 0.0, trigger: Any = None, name: str = "cross") -> list[Any]:
    """``count`` cars on ``approach`` of ``inter``, the first ``first_s`` m along the lane
    (i.e. ``approach_length - first_s`` from the box), ``spacing`` m apart, at ``speed`` [m/s].

    They drive ``turn`` through the box without stopping (``stops=False``: the ego's road has
    the stop sign) and react only to what is ahead of them in their own path; ``jitter``
    [m/s^2] adds acceleration noise drawn during the run from ``case.rng``.
    """
    lane_obj = inter.approach(approach, lane)
    cars = []
    for k in range(count):
        s = first_s - k * spacing
        if s < 0:
            break
        if stops:
            beh: Behavior = b.turn(turn, speed=speed)
        elif turn == "straight" and start_at <= 0:
            beh = b.keep_lane(speed)
        else:
            beh = b.cut_across(speed, direction=turn, start_at=start_at)
        if jitter:
            beh = wobble(beh, sd=jitter, every=1.0)
        cars.append(world.car(lane_obj, s=s, speed=speed if start_at <= 0 else 0.0,
                              **_spawn(world, beh, trigger, f"{name}{k + 1}")))
    return cars


def pedestrian_crossing(world: Any, crosswalk: Any, *, side: str | None = None,
                        wait: float = 0.0, wait_in_road: float = 0.0, speed: float = 1.4,
                        approach: float = 3.0, jitter: float = 0.0, trigger: Any = None,
                        name: str = "pedestrian") -> Any:
    """A pedestrian using ``crosswalk`` from ``side``: waits ``wait`` [s] ``approach`` m back
    from the crosswalk's kerb end, walks at ``speed`` [m/s] to it and across, stands
    ``wait_in_road`` [s] in the first lane it enters, and walks ``approach`` m on beyond;
    ``jitter`` (a fraction) varies its pace during the run, drawn from ``case.rng``.

    The ``approach`` keeps a waiting pedestrian out of the 5-m circle of the paper's distance
    metric for a car merely driving by in the kerb lane (the crosswalk path itself starts 2 m
    from the kerb, 3.75 m from the centre of a 3.5 m lane).
    """
    from pytest_avscenario.sim.places import Path

    pts = crosswalk.walk(side).array
    u = (pts[-1] - pts[0]) / np.linalg.norm(pts[-1] - pts[0])
    path = Path.through([pts[0] - approach * u, *pts, pts[-1] + approach * u])
    beh: Behavior = b.cross(wait=wait, wait_in_road=wait_in_road, speed=speed)
    if jitter:
        beh = wobble(beh, sd=jitter, every=1.0)
    return world.pedestrian(path, speed=speed, **_spawn(world, beh, trigger, name))


def parked_car_pulling_out(world: Any, road: Any, *, s: float, at: float, speed: float = 8.0,
                           trigger: Any = None, name: str = "pulling_out") -> Any:
    """A car parked ``s`` m along the forward parking lane that pulls out at ``at`` [s]."""
    return world.parked_car(road.parking_lane, s=s,
                            **_spawn(world, b.pull_out(at=at, speed=speed), trigger, name))


def oncoming_encroacher(world: Any, lane: Any, *, s: float, throttle: float, offset: float,
                        speed: float = 0.0, max_speed: float = 15.0, at: float = 0.0,
                        duration: float | None = None, trigger: Any = None,
                        name: str = "oncoming") -> Any:
    """An oncoming car ``s`` m along ``lane`` (the lane against the ego's direction, e.g.
    ``road.lane(0, "backward")``) that pulls away with ``throttle`` and, from ``at`` [s] for
    ``duration`` [s], drives ``offset`` m left of its lane centre, toward the ego's lane."""
    beh = throttle_encroach(throttle, offset, max_speed=max_speed, at=at, duration=duration)
    return world.car(lane, s=s, speed=speed, **_spawn(world, beh, trigger, name))


def school_bus_stop(world: Any, road: Any, *, direction: str, s: float, speed: float,
                    stop_at: float, duration: float, decel: float = 3.0,
                    trigger: Any = None) -> Any:
    """A school bus ``s`` m along lane 0 of ``direction`` at ``speed`` [m/s] that brakes at
    ``decel`` [m/s^2] from ``stop_at`` [s] and shows its stop arm for ``duration`` [s]."""
    beh = b.bus_stop(t=stop_at, duration=duration, decel=decel)
    return world.bus(road.lane(0, direction), s=s, speed=speed,
                     **_spawn(world, beh, trigger, "bus"))


# -- monitors the situation needs ---------------------------------------------------------------


def passes_stopped_school_bus(bus: str = "bus", margin: float = 2.0, decel: float = 6.0,
                              reaction: float = 0.5):
    """The ego never drives past a school bus while its stop arm is out.

    rho [m] = min over the steps with the arm out of how far the ego's front bumper stays
    behind the bus's near end minus ``margin``, measured along the road (x); the ego's own
    heading decides which end is near. When the arm came out too late for the ego to stop
    before the bus after a ``reaction`` time at a firm ``decel`` (the ego's front was already
    closer than v reaction + v^2 / (2 decel), or past the bus), the requirement does not apply
    (rho = +inf).
    """

    def stops_for_school_bus(tr) -> float:
        arm = np.asarray(tr.signals[f"{bus}.stop_arm"]) > 0.5
        if not arm.any():
            return math.inf
        e, k = tr.names.index("ego"), tr.names.index(bus)
        sign = 1.0 if math.cos(tr.heading[e, 0]) >= 0 else -1.0
        gap = sign * (tr.x[k] - tr.x[e]) - (tr.length[k] + tr.length[e]) / 2
        first = int(np.flatnonzero(arm)[0])
        v = tr.speed[e, first]
        if gap[first] < v * reaction + v * v / (2 * decel):
            return math.inf  # too late to stop when the arm came out
        return float(np.min(gap[arm]) - margin)

    return as_monitor(stops_for_school_bus, name="school_bus")


def parks(spot_xy: tuple[float, float], heading: float = 0.0, tol_m: float = 0.5,
          tol_rad: float = 0.15):
    """The ego ends the run parked in the slot: rho [m] = min(``tol_m`` - final distance of
    its centre from the slot centre, 10 m/rad x (``tol_rad`` - |final heading error|))."""

    def parked(tr) -> float:
        e = tr.names.index("ego")
        d = math.hypot(tr.x[e, -1] - spot_xy[0], tr.y[e, -1] - spot_xy[1])
        dh = abs((tr.heading[e, -1] - heading + math.pi) % (2 * math.pi) - math.pi)
        return float(min(tol_m - d, (tol_rad - dh) * 10.0))

    return as_monitor(parked, name="parked")

"""What the non-ego agents do: small, parameterized behaviours built from case values.

A test writes ``world.car(lane, s=20, speed=10, behavior=b.brake_at(case.brake_at, decel=6))``.
Each factory here returns a frozen description; when the agent enters a world the description
is *bound*: any parameter given as a callable ``f(rng)`` is drawn from the world's generator
(the case's ``case.rng``), so behaviours can be sampled dynamically and still replay exactly —
``b.brake_at(b.uniform(1, 5))`` draws the braking time per case. Binding happens in the
order agents are added, which is part of the scenario, so draws never depend on test order.

A behaviour of your own subclasses :class:`Behavior` the same way; it may also draw from
``world.rng`` inside ``control`` (agents act in a fixed order each step, so such draws replay
exactly too).

Times in behaviours (``brake_at(t)``, ``change_lane(at)``, ``encroach(at)``, ``pull_out(at)``,
``bus_stop(t)``, ``cut_across(start_at=)``, ``cross(wait=)``...) are seconds after the agent
appeared (``agent.age``): the simulation time for an agent present from the start, so a
sub-scenario whose agents appear late (``appear=world.ego_within(place, 40)``) keeps its
timing wherever it is composed. A behaviour of your own should measure time with
``agent.age`` too.

Every step the engine calls ``control(agent, world)``; vehicle behaviours return
``(acceleration [m/s^2], steering [rad])``, pedestrian behaviours a walking speed [m/s]. They
drive with the laws in :mod:`.control` through a few agent helpers (``agent.follow()``,
``agent.idm(v)``, ``agent.distance_along_route(place)``), never with highway-env's
``IDMVehicle`` (whose class constants other code in the process may rewrite).

Importing this module imports neither highway-env nor pygame.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import Any, Callable

from . import control, right_of_way

__all__ = [
    "Behavior", "keep_lane", "stopped", "brake_at", "change_lane", "turn", "turn_across",
    "cut_across", "encroach", "pull_out", "bus_stop", "cross", "walk", "uniform", "choice",
]

VEHICLES = ("ego", "car", "bus", "parked")
PEDESTRIANS = ("pedestrian",)


def uniform(low: float, high: float) -> Callable[[Any], float]:
    """A parameter drawn from U[low, high] with the world's rng when the agent is added."""
    return lambda rng: float(rng.uniform(low, high))


def choice(options: list[Any]) -> Callable[[Any], Any]:
    """A parameter drawn uniformly from ``options`` with the world's rng when the agent is added."""
    opts = list(options)
    return lambda rng: opts[int(rng.integers(len(opts)))]


@dataclass(frozen=True)
class Behavior:
    """Base class. Subclasses are frozen dataclasses of their parameters."""

    kinds = VEHICLES  # which agent kinds it can drive
    state: dict = field(default_factory=dict, compare=False, repr=False, kw_only=True)

    def bind(self, rng: Any) -> "Behavior":
        """A copy with callable parameters drawn from ``rng`` and fresh per-agent state."""
        values = {}
        for f in dataclasses.fields(self):
            if f.name == "state":
                continue
            v = getattr(self, f.name)
            values[f.name] = v(rng) if callable(v) and not isinstance(v, type) else v
        return dataclasses.replace(self, **values, state={})

    def start(self, agent: Any, world: Any) -> None:
        """Called once when the run starts (after every agent is placed)."""

    def control(self, agent: Any, world: Any) -> Any:  # pragma: no cover - abstract
        raise NotImplementedError

    @property
    def name(self) -> str:
        return type(self).__name__


# -- vehicles ----------------------------------------------------------------------------------


@dataclass(frozen=True)
class KeepLane(Behavior):
    """Follow the lane (and route) at ``speed`` [m/s] with IDM car following."""

    speed: float | None = None

    def control(self, agent, world):
        v = self.speed if self.speed is not None else agent.initial_speed
        return agent.idm(v), agent.follow()


def keep_lane(speed: float | None = None) -> KeepLane:
    """Keep the lane at ``speed`` [m/s] (default: the agent's initial speed), IDM behind others."""
    return KeepLane(speed)


@dataclass(frozen=True)
class Stopped(Behavior):
    """Stand still (brake to a stop if moving)."""

    def control(self, agent, world):
        # The engine never lets braking reverse a vehicle, so this settles at 0 m/s.
        return (-min(agent.speed / 0.3, 6.0) if agent.speed > 0 else 0.0), 0.0


def stopped() -> Stopped:
    """Stand still where placed (a parked car, a broken-down vehicle)."""
    return Stopped()


@dataclass(frozen=True)
class BrakeAt(Behavior):
    """Cruise like ``keep_lane(speed)``, then brake at ``decel`` from ``t`` [s] after the agent
    appeared or at place ``at``."""

    t: float | None = None
    decel: float = 6.0
    at: Any = None
    speed: float | None = None

    def start(self, agent, world):
        if self.t is None and self.at is None:
            raise ValueError("brake_at needs a time t [s] or a place at=")
        if not self.decel > 0:
            raise ValueError(f"brake_at decel must be > 0 m/s^2, got {self.decel!r}")

    def control(self, agent, world):
        st = self.state
        if not st.get("braking"):
            if self.t is not None and agent.age >= self.t - 1e-9:
                st["braking"] = True
            elif self.at is not None and agent.distance_along_route(self.at) <= 0.0:
                st["braking"] = True
        if st.get("braking"):
            return -float(self.decel), agent.follow()
        v = self.speed if self.speed is not None else agent.initial_speed
        return agent.idm(v), agent.follow()


def brake_at(t: float | None = None, decel: float = 6.0, *, at: Any = None,
             speed: float | None = None) -> BrakeAt:
    """Drive at ``speed`` [m/s] (default initial), then brake at ``decel`` [m/s^2] to a stop.

    Braking starts ``t`` [s] after the agent appeared or when it reaches the place ``at`` (a
    spot or stop line on its route), whichever is given.
    """
    return BrakeAt(t=t, decel=decel, at=at, speed=speed)


@dataclass(frozen=True)
class ChangeLane(Behavior):
    """Keep lane, then ``at`` [s] after the agent appeared move to lane ``to`` over about
    ``duration`` seconds."""

    to: Any = "left"
    at: float = 0.0
    duration: float = 3.0
    speed: float | None = None

    def control(self, agent, world):
        st = self.state
        if not st.get("done") and agent.age >= self.at - 1e-9:
            agent.change_lane(self.to)
            st["done"] = True
        v = self.speed if self.speed is not None else agent.initial_speed
        return agent.idm(v), agent.follow(settle=self.duration if st.get("done") else None)


def change_lane(to: Any = "left", at: float = 0.0, duration: float = 3.0,
                speed: float | None = None) -> ChangeLane:
    """Change to lane ``to`` ("left", "right", a lane number or a Lane) ``at`` [s] after the
    agent appeared.

    The manoeuvre takes roughly ``duration`` [s]; the agent keeps ``speed`` [m/s] (default
    initial) with IDM car following in its new lane.
    """
    return ChangeLane(to=to, at=at, duration=duration, speed=speed)


@dataclass(frozen=True)
class Turn(Behavior):
    """At an intersection, take ``direction``; stop at the line first when ``stop`` and go in
    arrival order (the world's :class:`~.right_of_way.AllWayStop`)."""

    direction: str = "straight"
    stop: bool = True
    stop_time: float = 1.0
    speed: float | None = None
    yield_to_ego: bool = False
    go_when_ego_within: float | None = None

    def start(self, agent, world):
        if self.direction not in ("left", "right", "straight"):
            raise ValueError(f"turn direction must be 'left', 'right' or 'straight', got {self.direction!r}")
        agent.take_turn(self.direction)

    PATIENCE = 10.0  # [s] beyond stop_time after which arrival order is no longer waited for

    def control(self, agent, world):
        st = self.state
        v = self.speed if self.speed is not None else agent.cruise_speed
        v = min(v, agent.curve_speed_cap())
        hold = None
        allway = None
        if self.stop:
            allway = world.all_way_stop
            allway.update()  # every step: arrival times of everyone, before we stop too
        if (self.stop or self.go_when_ego_within is not None) and not st.get("released"):
            d = agent.distance_to_stop_line()
            if d is not None:
                d -= agent.LENGTH / 2  # from the front bumper
            if d is None or right_of_way.has_entered(d, 0.0):
                st["released"] = True
            else:
                stopped = agent.speed < right_of_way.STANDING and d < 3.0
                if stopped:
                    st["stopped_for"] = st.get("stopped_for", 0.0) + world.dt
                waited = st.get("stopped_for", 0.0) >= (self.stop_time if self.stop else 0.0)
                ego_ok = True
                if self.go_when_ego_within is not None:
                    ego_ok = world.ego_distance_to_centre(agent) <= self.go_when_ego_within
                if self.yield_to_ego and world.ego_in_conflict(agent):
                    ego_ok = False
                if ego_ok and allway is not None and waited and stopped:
                    patient = st["stopped_for"] < self.stop_time + self.PATIENCE
                    ego_ok = allway.may_go(agent, patient)
                if (waited or not self.stop) and ego_ok and (stopped or not self.stop):
                    st["released"] = True
                else:
                    hold = max(d - 0.5, 0.0)
        return agent.idm(v, stop_in=hold), agent.follow()


def turn(direction: str, *, stop: bool = True, stop_time: float = 1.0,
         speed: float | None = None, yield_to_ego: bool = False) -> Turn:
    """Drive through the intersection turning ``direction`` ("left", "right", "straight").

    With ``stop`` it halts at the stop line for ``stop_time`` [s] and then takes its turn at the
    all-way stop: first to stop, first to go. It waits while a vehicle (the ego included) that
    came to a stop at another stop line of the intersection more than 0.2 s before it has not
    gone in, on a tie while the one on its right has not, and while a vehicle inside the box
    is on a path crossing or merging with its own; after 10 s more it stops waiting for the
    arrival order (a car that stopped first may never go) but never for the box. With
    ``yield_to_ego`` it also waits while the ego is inside the intersection or driving toward
    it within 30 m of its centre. ``speed`` [m/s] defaults to the initial speed (the speed limit for a car
    placed standing) and is capped in the turn for 2.5 m/s^2 lateral acceleration.
    """
    return Turn(direction=direction, stop=stop, stop_time=stop_time, speed=speed,
                yield_to_ego=yield_to_ego)


def turn_across(direction: str = "left", *, speed: float | None = None,
                go_when_ego_within: float | None = None) -> Turn:
    """Turn ``direction`` across the ego's path without yielding.

    Without ``go_when_ego_within`` it does not even stop; with it, it waits at the stop line
    until the ego is within that many metres [m] of the intersection centre, then goes.
    """
    return Turn(direction=direction, stop=False, stop_time=0.0, speed=speed,
                go_when_ego_within=go_when_ego_within)


@dataclass(frozen=True)
class CutAcross(Behavior):
    """Drive straight across the intersection at a constant speed, ignoring the stop line."""

    speed: float | None = None
    direction: str = "straight"
    start_at: float = 0.0

    def start(self, agent, world):
        agent.take_turn(self.direction)

    def control(self, agent, world):
        if agent.age < self.start_at - 1e-9:
            return control.track_speed(agent.speed, 0.0), agent.follow()
        v = self.speed if self.speed is not None else agent.cruise_speed
        v = min(v, agent.curve_speed_cap()) if self.direction != "straight" else v
        return control.track_speed(agent.speed, v), agent.follow()


def cut_across(speed: float | None = None, *, direction: str = "straight",
               start_at: float = 0.0) -> CutAcross:
    """Cross the intersection at ``speed`` [m/s] without stopping or yielding (a red-light runner).

    The agent stands still until ``start_at`` [s] after it appeared; ``direction`` may also be
    "left"/"right".
    ``speed`` defaults to the initial speed (the speed limit for a car placed standing).
    """
    return CutAcross(speed=speed, direction=direction, start_at=start_at)


@dataclass(frozen=True)
class Encroach(Behavior):
    """Drift ``offset`` metres to the left (into the oncoming lane) from ``at`` [s] after the agent
    appeared, for ``duration`` [s]."""

    offset: float = 1.5
    at: float = 0.0
    duration: float | None = None
    speed: float | None = None

    def control(self, agent, world):
        age = agent.age
        active = age >= self.at - 1e-9 and (self.duration is None or age < self.at + self.duration)
        v = self.speed if self.speed is not None else agent.initial_speed
        return agent.idm(v), agent.follow(r=float(self.offset) if active else 0.0, settle=2.0)


def encroach(offset: float, at: float = 0.0, duration: float | None = None,
             speed: float | None = None) -> Encroach:
    """Drive ``offset`` [m] left of the lane centre (over the centre line) from ``at`` [s] after
    the agent appeared.

    For ``duration`` [s] (None: to the end), at ``speed`` [m/s] (default initial).
    """
    return Encroach(offset=offset, at=at, duration=duration, speed=speed)


@dataclass(frozen=True)
class PullOut(Behavior):
    """Leave a parking spot ``at`` [s] after the agent appeared into the adjacent travel lane and
    drive on."""

    at: float = 0.0
    speed: float = 8.0
    to: Any = None

    def control(self, agent, world):
        st = self.state
        if agent.age < self.at - 1e-9:
            return (-agent.speed / 0.3 if agent.speed > 0 else 0.0), 0.0
        if not st.get("out"):
            agent.change_lane(self.to if self.to is not None else "out")
            st["out"] = True
        return agent.idm(self.speed), agent.follow(settle=3.0)


def pull_out(at: float = 0.0, speed: float = 8.0, to: Any = None) -> PullOut:
    """Pull out of the parking lane ``at`` [s] after the agent appeared and drive on at ``speed``
    [m/s].

    ``to`` is the lane to join (default: the travel lane next to the parking lane).
    """
    return PullOut(at=at, speed=speed, to=to)


@dataclass(frozen=True)
class BusStop(Behavior):
    """Drive, stop from ``t`` [s] after the agent appeared or at place ``at``, show the stop arm
    for ``duration`` [s] standing still, drive on."""

    t: float | None = None
    duration: float = 10.0
    at: Any = None
    decel: float = 2.5
    speed: float | None = None

    def control(self, agent, world):
        st = self.state
        v = self.speed if self.speed is not None else agent.initial_speed
        phase = st.get("phase", "drive")
        if phase == "drive":
            trig = (self.t is not None and agent.age >= self.t - 1e-9) or (
                self.at is not None and agent.distance_along_route(self.at) <= 0.5)
            if self.at is not None and self.t is None and not trig:
                d = agent.distance_along_route(self.at)
                # Brake early enough to stop at the place at ``decel``.
                if agent.speed ** 2 / (2 * max(d, 0.1)) >= self.decel:
                    trig = True
            if trig:
                phase = "stopping"
        if phase == "stopping":
            if agent.speed < 0.05:
                phase = "arm"
                st["since"] = agent.age
                agent.stop_arm = True
            else:
                st["phase"] = phase
                return -float(self.decel), agent.follow()
        if phase == "arm":
            if agent.age - st["since"] >= self.duration:
                agent.stop_arm = False
                phase = "leave"
            else:
                st["phase"] = phase
                # Stand still: cancel what is left of the speed (< 0.05 m/s) in one step.
                return -min(agent.speed / world.dt, float(self.decel)), agent.follow()
        st["phase"] = phase
        return agent.idm(v), agent.follow()


def bus_stop(t: float | None = None, duration: float = 10.0, *, at: Any = None,
             decel: float = 2.5, speed: float | None = None) -> BusStop:
    """School-bus stop: brake ``t`` [s] after the bus appeared or for place ``at``, then stand
    with the stop arm out for ``duration`` [s].

    The bus brakes at ``decel`` [m/s^2]; below 0.05 m/s it stops dead and shows its stop arm
    (recorded as the signal ``"<bus name>.stop_arm"``) while standing at exactly 0 m/s, then
    drives on at ``speed`` [m/s].
    """
    return BusStop(t=t, duration=duration, at=at, decel=decel, speed=speed)


# -- pedestrians -------------------------------------------------------------------------------


@dataclass(frozen=True)
class Cross(Behavior):
    """Wait until ``wait`` [s] after the pedestrian appeared on the kerb, walk, wait
    ``wait_in_road`` [s] once in the road, walk on."""

    kinds = PEDESTRIANS
    wait: float = 0.0
    wait_in_road: float = 0.0
    speed: float | None = None
    pause_at: float | None = None

    def control(self, agent, world):
        st = self.state
        v = self.speed if self.speed is not None else agent.initial_speed
        if agent.age < self.wait - 1e-9:
            return 0.0
        if self.wait_in_road > 0 and not st.get("paused_done"):
            pause = self.pause_at if self.pause_at is not None else agent.road_pause_at()
            if pause is not None and agent.walked >= pause:
                st.setdefault("since", agent.age)
                if agent.age - st["since"] < self.wait_in_road - 1e-9:
                    return 0.0
                st["paused_done"] = True
            elif pause is not None and agent.walked + v * world.dt > pause:
                # Stop exactly at the pause point rather than overshooting it.
                return (pause - agent.walked) / world.dt
        return v


def cross(wait: float = 0.0, wait_in_road: float = 0.0, speed: float | None = None,
          pause_at: float | None = None) -> Cross:
    """Cross the road on foot: wait on the kerb until ``wait`` [s] after the pedestrian
    appeared, then walk at ``speed`` [m/s].

    Once in the road (by default the middle of the first lane crossed; or ``pause_at`` metres
    along the path) it stands for ``wait_in_road`` [s], then walks on to the far kerb.
    """
    return Cross(wait=wait, wait_in_road=wait_in_road, speed=speed, pause_at=pause_at)


def walk(speed: float | None = None) -> Cross:
    """Walk the path at ``speed`` [m/s] without waiting."""
    return Cross(speed=speed)

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

Triggers start a manoeuvre on a condition rather than at a time: ``gap_below(m)`` and
``time_gap_below(s)`` (to the ego or another agent), ``condition(fn)`` for your own; pass one
as ``when=`` to ``change_lane``, ``brake_at``, ``cut_in``, ``cut_out``. ``speed_profile``
follows a list of (time, speed) or (distance, speed) points. On a lane that ends (a lane
drop, an on-ramp's acceleration lane) ``keep_lane`` and the behaviours built on it merge
when the gap is safe and otherwise wait at the lane's end.

Every step the engine calls ``control(agent, world)``; vehicle behaviours return
``(acceleration [m/s^2], steering [rad])``, pedestrian behaviours a walking speed [m/s]. They
drive with the laws in :mod:`.control` through a few agent helpers (``agent.follow()``,
``agent.idm(v)``, ``agent.distance_along_route(place)``), never with highway-env's
``IDMVehicle`` (whose class constants other code in the process may rewrite).

Importing this module imports neither highway-env nor pygame.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from typing import Any, Callable

from . import control, right_of_way

__all__ = [
    "Behavior", "keep_lane", "stopped", "brake_at", "change_lane", "turn", "turn_across",
    "cut_across", "encroach", "pull_out", "bus_stop", "cross", "walk", "uniform", "choice",
    "Trigger", "gap_below", "time_gap_below", "condition", "cut_in", "cut_out", "speed_profile",
]

VEHICLES = ("ego", "car", "truck", "bus", "parked")
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
            values[f.name] = (v(rng) if callable(v) and not isinstance(v, (type, Trigger))
                              else v)
        bound = dataclasses.replace(self, **values, state={})
        bound.check()
        return bound

    def check(self) -> None:
        """Raise ValueError naming the parameter when a (drawn) value cannot work; the world
        reports it with the test and the agent when the agent is added."""

    def start(self, agent: Any, world: Any) -> None:
        """Called once when the run starts (after every agent is placed)."""

    def control(self, agent: Any, world: Any) -> Any:  # pragma: no cover - abstract
        raise NotImplementedError

    @property
    def name(self) -> str:
        return type(self).__name__


# -- triggers ----------------------------------------------------------------------------------


def _finite(value: Any, what: str, low: float = 0.0, strict: bool = False) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError):
        v = math.nan
    if not math.isfinite(v) or v < low or (strict and v == low):
        raise ValueError(f"{what}={value!r}: need a finite number {'>' if strict else '>='} {low:g}")
    return v


@dataclass(frozen=True)
class Trigger:
    """A condition a behaviour waits for, asked every step with ``fired(agent, world)``.

    Subclass it (a frozen dataclass) for your own, or wrap a function with :func:`condition`.
    """

    def fired(self, agent: Any, world: Any) -> bool:  # pragma: no cover - abstract
        raise NotImplementedError

    def check(self) -> None:
        """Raise ValueError naming the bad parameter."""


def _other(agent: Any, world: Any, name: str) -> Any:
    for a in world.movers:
        if a.name == name:
            return a
    return None


def _gap_and_follower_speed(agent: Any, other: Any) -> tuple[float, float]:
    """Bumper-to-bumper gap [m] between two agents along ``agent``'s heading, and the speed
    [m/s] of the one behind. Negative gap: they overlap lengthwise (side by side)."""
    dx = float(other.position[0] - agent.position[0])
    dy = float(other.position[1] - agent.position[1])
    along = dx * math.cos(agent.heading) + dy * math.sin(agent.heading)
    gap = abs(along) - (agent.LENGTH + other.LENGTH) / 2
    behind = other if along < 0 else agent
    return gap, float(behind.speed)


@dataclass(frozen=True)
class GapBelow(Trigger):
    """Fires once the gap between the agent and ``other`` is below ``metres``."""

    metres: float = 0.0
    other: str = "ego"

    def check(self) -> None:
        _finite(self.metres, "gap_below(metres)")

    def fired(self, agent, world):
        o = _other(agent, world, self.other)
        return o is not None and _gap_and_follower_speed(agent, o)[0] < self.metres


@dataclass(frozen=True)
class TimeGapBelow(Trigger):
    """Fires once the time gap between the agent and ``other`` is below ``seconds``."""

    seconds: float = 0.0
    other: str = "ego"

    def check(self) -> None:
        _finite(self.seconds, "time_gap_below(seconds)")

    def fired(self, agent, world):
        o = _other(agent, world, self.other)
        if o is None:
            return False
        gap, v = _gap_and_follower_speed(agent, o)
        return gap < self.seconds * v


@dataclass(frozen=True)
class Condition(Trigger):
    """Fires once ``fn(agent, world)`` is true."""

    fn: Any = None

    def check(self) -> None:
        if not callable(self.fn):
            raise ValueError(f"condition(fn={self.fn!r}): need a callable(agent, world) -> bool")

    def fired(self, agent, world):
        return bool(self.fn(agent, world))


def gap_below(metres: float, other: str = "ego") -> GapBelow:
    """A trigger: the bumper-to-bumper gap [m] between the agent and ``other`` (an agent's
    name, default the ego), measured along the agent's heading in any lane, is below
    ``metres``. Side by side counts as a gap below zero."""
    return GapBelow(metres=metres, other=other)


def time_gap_below(seconds: float, other: str = "ego") -> TimeGapBelow:
    """A trigger: the time gap [s] — the gap of :func:`gap_below` divided by the speed of
    whichever of the two is behind — is below ``seconds``. A cut-in "when the ego is within
    1.5 s": ``time_gap_below(1.5)``."""
    return TimeGapBelow(seconds=seconds, other=other)


def condition(fn: Callable[[Any, Any], bool]) -> Condition:
    """A trigger from your own ``fn(agent, world) -> bool``."""
    return Condition(fn=fn)


def _check_when(when: Any, what: str) -> None:
    if when is not None and not isinstance(when, Trigger):
        raise ValueError(f"{what}(when={when!r}): need a trigger (gap_below(...), "
                         "time_gap_below(...), condition(fn)) or None")


def _drive(st: dict, agent: Any, v: float, settle: float | None = None) -> tuple[float, float]:
    """IDM along the route at ``v`` [m/s]; on a lane that ends, merge when the gap is safe
    and otherwise wait at its end."""
    if settle is None and st.get("merged"):
        settle = 3.0  # finish a merge as a lane change, not a swerve
    end = agent.lane_end_ahead()
    if end is None:
        return agent.idm(v), agent.follow(settle=settle)
    d, side, on_it = end
    if on_it and agent.gap_is_safe(side):
        agent.change_lane(side)
        st["merged"] = True
        return agent.idm(v), agent.follow(settle=3.0)
    return agent.idm(v, stop_in=max(d - agent.LENGTH / 2 - 1.0, 0.0)), agent.follow(settle=settle)


# -- vehicles ----------------------------------------------------------------------------------


@dataclass(frozen=True)
class KeepLane(Behavior):
    """Follow the lane (and route) at ``speed`` [m/s] with IDM car following."""

    speed: float | None = None

    def control(self, agent, world):
        v = self.speed if self.speed is not None else agent.initial_speed
        return _drive(self.state, agent, v)


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
    when: Any = None

    def check(self):
        _check_when(self.when, "brake_at")
        if self.when is not None:
            self.when.check()

    def start(self, agent, world):
        if self.t is None and self.at is None and self.when is None:
            raise ValueError("brake_at needs a time t [s], a place at= or a trigger when=")
        if not self.decel > 0:
            raise ValueError(f"brake_at decel must be > 0 m/s^2, got {self.decel!r}")

    def control(self, agent, world):
        st = self.state
        if not st.get("braking"):
            if self.t is not None and agent.age >= self.t - 1e-9:
                st["braking"] = True
            elif self.at is not None and agent.distance_along_route(self.at) <= 0.0:
                st["braking"] = True
            elif self.when is not None and self.when.fired(agent, world):
                st["braking"] = True
        if st.get("braking"):
            return -float(self.decel), agent.follow()
        v = self.speed if self.speed is not None else agent.initial_speed
        return agent.idm(v), agent.follow()


def brake_at(t: float | None = None, decel: float = 6.0, *, at: Any = None,
             speed: float | None = None, when: Trigger | None = None) -> BrakeAt:
    """Drive at ``speed`` [m/s] (default initial), then brake at ``decel`` [m/s^2] to a stop.

    Braking starts ``t`` [s] after the agent appeared, when it reaches the place ``at`` (a
    spot or stop line on its route) or when the trigger ``when`` fires (``gap_below(20)``),
    whichever is given first.
    """
    return BrakeAt(t=t, decel=decel, at=at, speed=speed, when=when)


@dataclass(frozen=True)
class ChangeLane(Behavior):
    """Keep lane, then ``at`` [s] after the agent appeared move to lane ``to`` over about
    ``duration`` seconds."""

    to: Any = "left"
    at: float = 0.0
    duration: float = 3.0
    speed: float | None = None
    when: Any = None
    lateral_speed: float | None = None

    def check(self):
        what = type(self).__name__
        _check_when(self.when, what)
        if self.when is not None:
            self.when.check()
        _finite(self.at, f"{what}(at)")
        _finite(self.duration, f"{what}(duration)", strict=True)
        if self.lateral_speed is not None:
            _finite(self.lateral_speed, f"{what}(lateral_speed)", strict=True)

    def _target(self, agent, world):
        return self.to

    def control(self, agent, world):
        st = self.state
        if (not st.get("done") and agent.age >= self.at - 1e-9
                and (self.when is None or self.when.fired(agent, world))):
            agent.change_lane(self._target(agent, world))
            st["done"] = True
            st["r0"], st["t0"] = float(agent.route_r), agent.age
        v = self.speed if self.speed is not None else agent.initial_speed
        if not st.get("done"):
            return _drive(st, agent, v)
        if self.lateral_speed is not None:
            # Move across at the given lateral speed: the reference offset from the new
            # lane's centre shrinks linearly; the lane-keeping law tracks it.
            r0 = st["r0"]
            left = max(abs(r0) - self.lateral_speed * (agent.age - st["t0"]), 0.0)
            return _drive(st, agent, v)[0], agent.follow(r=math.copysign(left, r0))
        acc, _ = _drive(st, agent, v)
        return acc, agent.follow(settle=self.duration)


def change_lane(to: Any = "left", at: float = 0.0, duration: float = 3.0,
                speed: float | None = None, *, when: Trigger | None = None,
                lateral_speed: float | None = None) -> ChangeLane:
    """Change to lane ``to`` ("left", "right", a lane number or a Lane) ``at`` [s] after the
    agent appeared, or (not before ``at``) when the trigger ``when`` fires.

    The manoeuvre takes roughly ``duration`` [s], or moves across at ``lateral_speed``
    [m/s] when that is given; the agent keeps ``speed`` [m/s] (default initial) with IDM
    car following in its new lane.
    """
    return ChangeLane(to=to, at=at, duration=duration, speed=speed, when=when,
                      lateral_speed=lateral_speed)


@dataclass(frozen=True)
class CutIn(ChangeLane):
    """A lane change into the ego's lane (``to="ego"``) on a trigger."""

    def _target(self, agent, world):
        if self.to != "ego":
            return self.to
        ego = next((a for a in world.movers if a.kind == "ego"), None)
        if ego is None:
            raise ValueError("cut_in(to='ego'): there is no ego on the road")
        return ego.route_lane.number


def cut_in(time_gap: float | None = None, *, gap: float | None = None, to: Any = "ego",
           lateral_speed: float = 1.0, speed: float | None = None, at: float = 0.0,
           other: str = "ego") -> CutIn:
    """Cut into lane ``to`` (default: the ego's lane) when the ego (or ``other``) comes
    within ``time_gap`` [s] or ``gap`` [m] (give one), moving across at ``lateral_speed``
    [m/s], at ``speed`` [m/s] (default initial) — UN R157's cut-in."""
    if (time_gap is None) == (gap is None):
        when = _Missing("cut_in needs exactly one of time_gap= [s] or gap= [m]")
    else:
        when = time_gap_below(time_gap, other) if time_gap is not None else gap_below(gap, other)
    return CutIn(to=to, at=at, speed=speed, when=when, lateral_speed=lateral_speed)


def cut_out(gap: float | None = None, *, time_gap: float | None = None,
            ahead: str | None = None, to: Any = "left", lateral_speed: float = 1.0,
            speed: float | None = None, at: float = 0.0) -> ChangeLane:
    """Leave the lane to ``to`` ("left"/"right") when the agent comes within ``gap`` [m] or
    ``time_gap`` [s] (give one) of the agent named ``ahead`` — the lead of UN R157's
    cut-out, swerving round a stopped or slower vehicle it reveals to the ego behind."""
    if (time_gap is None) == (gap is None) or ahead is None:
        when = _Missing("cut_out needs ahead= (the name of the vehicle it swerves round) and "
                        "exactly one of gap= [m] or time_gap= [s]")
    else:
        when = time_gap_below(time_gap, ahead) if time_gap is not None else gap_below(gap, ahead)
    return ChangeLane(to=to, at=at, speed=speed, when=when, lateral_speed=lateral_speed)


@dataclass(frozen=True)
class _Missing(Trigger):
    """A trigger that could not be made: its ``check`` reports why, when the agent is added."""

    message: str = ""

    def check(self) -> None:
        raise ValueError(self.message)

    def fired(self, agent, world):  # pragma: no cover - never runs: check() refuses it
        return False


@dataclass(frozen=True)
class SpeedProfile(Behavior):
    """Follow piecewise-linear speed ``points`` [(time [s] or distance [m], speed [m/s])]."""

    points: Any = ()
    by: str = "time"
    max_accel: float = 3.0
    max_decel: float = 8.0

    def check(self):
        if self.by not in ("time", "distance"):
            raise ValueError(f"speed_profile(by={self.by!r}): use 'time' or 'distance'")
        unit = "s" if self.by == "time" else "m"
        try:
            pts = [(float(x), float(v)) for x, v in self.points]
        except (TypeError, ValueError):
            raise ValueError(f"speed_profile(points={self.points!r}): give a list of "
                             f"({self.by} [{unit}], speed [m/s]) pairs") from None
        if not pts:
            raise ValueError(f"speed_profile(points={self.points!r}): need at least one "
                             f"({self.by} [{unit}], speed [m/s]) point")
        for x, v in pts:
            if not (math.isfinite(x) and x >= 0 and math.isfinite(v) and v >= 0):
                raise ValueError(f"speed_profile(points=...): point ({x!r}, {v!r}) needs a "
                                 f"{self.by} >= 0 [{unit}] and a speed >= 0 [m/s]")
        xs = [x for x, _ in pts]
        if any(b <= a for a, b in zip(xs, xs[1:])):
            raise ValueError(f"speed_profile(points=...): the {self.by}s {xs} must increase "
                             "strictly")
        _finite(self.max_accel, "speed_profile(max_accel)", strict=True)
        _finite(self.max_decel, "speed_profile(max_decel)", strict=True)

    TAU = 0.5  # [s] speed error closed in this time, and the look-ahead into the profile

    def target(self, x: float) -> float:
        """Profile speed [m/s] at ``x`` (time [s] or distance [m]); flat beyond its ends."""
        pts = self.points
        if x <= pts[0][0]:
            return float(pts[0][1])
        for (x0, v0), (x1, v1) in zip(pts, pts[1:]):
            if x <= x1:
                return float(v0 + (v1 - v0) * (x - x0) / (x1 - x0))
        return float(pts[-1][1])

    def control(self, agent, world):
        st = self.state
        v = float(agent.speed)
        if self.by == "time":
            x, ahead = agent.age, self.TAU
        else:
            x, ahead = st.get("odometer", 0.0), max(v, 0.5) * self.TAU
            st["odometer"] = x + v * world.dt
        a = (self.target(x + ahead) - v) / self.TAU
        a = min(max(a, -float(self.max_decel)), float(self.max_accel))
        lead = agent.leader()
        if lead is not None:  # never into the car ahead: IDM's interaction term caps it
            a = min(a, control.idm_acceleration(v, 1e3, lead[0], lead[1]))
        return a, agent.follow()


def speed_profile(points: Any, by: str = "time", *, max_accel: float = 3.0,
                  max_decel: float = 8.0) -> SpeedProfile:
    """Follow a speed profile: ``points`` is a list of ``(time [s], speed [m/s])`` after the
    agent appeared, or with ``by="distance"`` of ``(distance travelled [m], speed [m/s])``;
    speeds are interpolated linearly between points and held beyond the ends. The agent
    accelerates at most ``max_accel`` and brakes at most ``max_decel`` [m/s^2], looks 0.5 s
    into the profile, keeps its lane and never drives into the car ahead."""
    return SpeedProfile(points=tuple(tuple(p) if isinstance(p, (list, tuple)) else p
                                     for p in points) if _iterable(points) else points,
                        by=by, max_accel=max_accel, max_decel=max_decel)


def _iterable(x: Any) -> bool:
    try:
        iter(x)
    except TypeError:
        return False
    return not isinstance(x, (str, bytes))


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

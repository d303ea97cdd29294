"""The built-in autopilot: the default "AV under test" that the example suite falsifies.

It is meant to be a credible but imperfect driver, the kind of baseline stack an AV team
would start from, so that falsification finds real corners rather than a strawman's or an
oracle's. Per step it (1) follows its route with pure pursuit on the route's centre line,
(2) controls speed with the Intelligent Driver Model toward the cruise speed, capped on
curves by a lateral-acceleration limit, behind the nearest agent found on its path, (3) stops
at stop lines (full stop, then at an all-way stop goes in arrival order, first to stop first
to go, the one on the right first on a tie, once nothing moves in the box and no conflict
is predicted), at red traffic lights (and at amber ones when it can stop comfortably)
and for a school bus with its stop arm out, (4) predicts every other agent at constant velocity over a finite horizon
against its own path and yields when it could not clear a predicted conflict zone with a time
margin, and (5) parallel parks (two reverse arcs, or several moves in a tight slot) when its
observation carries a parking goal. Its weaknesses are deliberate and realistic: perception
reports agents with a latency (and a new agent only once that latency has passed), braking
builds up at a finite jerk, prediction is constant-velocity and blind beyond its horizon and
sensor range, a conflict it can no longer stop for is driven through, and the arrival order
at a stop is inferred from what it sees (other arms' stop lines are assumed as far from the
box as its own; a vehicle standing there that never goes is waited for ``allway_patience``
seconds).
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import asdict, dataclass, fields
from typing import Any

import numpy as np

from pytest_avscenario.sim.drivers.junction import Junction
from pytest_avscenario.sim.drivers.parking import Parker
from pytest_avscenario.sim.drivers.perception import EMPTY, Perceived
from pytest_avscenario.sim.drivers.route_path import RoutePath, pursuit_steering
from pytest_avscenario.sim.right_of_way import waiting_at_line
from pytest_avscenario.sim.signals import GREEN, must_stop

__all__ = ["Autopilot", "AutopilotOptions"]

@dataclass(frozen=True)
class AutopilotOptions:
    """Tuning of the autopilot; every field can be passed to ``Autopilot(**options)``."""

    cruise_speed: float | None = None  # [m/s] overrides observation.target_speed / speed_limit
    max_accel: float = 2.0  # [m/s^2] IDM comfortable acceleration
    comfort_decel: float = 3.5  # [m/s^2] IDM comfortable deceleration, stop-line approach
    max_decel: float = 8.0  # [m/s^2] emergency braking limit
    brake_jerk: float = 25.0  # [m/s^3] rate at which braking can build up (actuator lag)
    time_headway: float = 1.5  # [s] IDM desired time gap
    min_gap: float = 2.0  # [m] IDM bumper-to-bumper standstill gap
    idm_delta: float = 4.0  # IDM acceleration exponent
    lateral_accel: float = 2.5  # [m/s^2] curve speed limit
    lookahead_time: float = 0.5  # [s] pure-pursuit look-ahead per unit of speed
    min_lookahead: float = 4.0  # [m] pure-pursuit look-ahead at low speed
    max_steering: float = 0.6  # [rad] front-wheel angle limit
    horizon: float = 4.0  # [s] constant-velocity prediction horizon
    sensor_range: float = 60.0  # [m] agents further away are not seen
    latency: float = 0.2  # [s] perception latency: agents are seen as they were this long ago
    gap_time: float = 1.0  # [s] time margin to go before / after a predicted crossing agent
    lateral_margin: float = 0.4  # [m] clearance to vehicles in conflict prediction
    pedestrian_margin: float = 1.0  # [m] clearance to pedestrians in conflict prediction
    stop_margin: float = 1.0  # [m] front bumper stops this far before a line or conflict zone
    stop_dwell: float = 0.5  # [s] standstill at a stop line before it may go
    allway_patience: float = 8.0  # [s] waiting at a stop line after which arrival order is ignored
    bus_distance: float = 6.0  # [m] stop this far from a school bus with its stop arm out
    bus_caution_speed: float = 4.0  # [m/s] speed to be down to when reaching a slow school bus
    evasive_offset: float = 1.0  # [m] how far it shifts right in its lane for an oncoming car
    parking_speed: float = 1.0  # [m/s] speed of the parking manoeuvre
    parking_clearance: float = 0.4  # [m] kept to the car behind the slot when reversing in
    parking_side_clearance: float = 0.4  # [m] kept to the parked cars when driving past them

    def __post_init__(self) -> None:
        for f in fields(self):
            value = getattr(self, f.name)
            if value is None:
                continue
            if not isinstance(value, (int, float)) or isinstance(value, bool):
                raise TypeError(f"Autopilot option {f.name}={value!r}: expected a number")
            if value < 0:
                raise ValueError(f"Autopilot option {f.name}={value!r}: must be >= 0")
        for name in ("max_accel", "comfort_decel", "max_decel", "brake_jerk", "max_steering"):
            if getattr(self, name) <= 0:
                raise ValueError(f"Autopilot option {name} must be > 0")


class Autopilot:
    """Route-following, IDM-based driver with conflict prediction and parallel parking.

    ``Autopilot(**options)`` takes the fields of :class:`AutopilotOptions`;
    ``act(observation) -> (acceleration [m/s^2], steering [rad])``. One instance drives one
    case: it keeps internal state between steps (perception buffer, stop-line progress,
    parking phase) and is deterministic (no randomness, no clock).

    What it reads from the observation: ``route``/``route_index``/``s`` (where it is on its
    path; a route that steps to a parallel lane is driven as a lane change), ``agents``
    (``kind`` "pedestrian" gets a wider margin, "bus" with ``flags["stop_arm"]`` is stopped
    for, in either direction), ``stop_lines`` (kind "stop": full stop for ``stop_dwell``, then
    go when no conflict is predicted and, with a connector after the line, when vehicles that
    came to rest at the intersection's other stop lines before it have gone and nothing
    moves in the box; kind "crosswalk": where it waits for pedestrians),
    ``target_speed`` (else ``speed_limit``), ``dt``, and ``goal``. A parking goal is
    ``{"kind": "park", "x": [m], "y": [m], "heading": [rad], "length": [m] (optional)}``:
    the pose of the car's centre once parked and, optionally, the free kerb length of the
    slot centred there (otherwise it measures the slot from the parked cars it sees). It
    drives its route until near the slot, reverses in (the world must let it reverse), and
    gives the slot up and drives on if no plan keeps 0.2 m from the parked cars (about
    L + 1.3 m of kerb is the least it manages). ``last_reason`` names what decided the last
    command ("cruise", "follow", "stop line", "right of way", "yield", "school bus",
    "park:reverse", ...).
    """

    def __init__(self, **options: Any) -> None:
        try:
            self.options = AutopilotOptions(**options)
        except TypeError as exc:
            known = ", ".join(f.name for f in fields(AutopilotOptions))
            raise TypeError(f"{exc}. Known Autopilot options: {known}") from None
        self._path: RoutePath | None = None
        self._route: tuple = ()
        self._history: deque = deque()
        self._accel = 0.0  # last commanded acceleration [m/s^2]
        self._stop_state: dict[tuple[int, float], list] = {}
        self._yielding: set[str] = set()
        self._light_went: set[str] = set()  # lights it went on through at amber
        self._evade = 0.0  # [m] wanted shift to the right for oncoming traffic
        self._offset = 0.0  # [m] lateral offset from the centre line it steers for (left +)
        self._parker: Parker | None = None
        self._goal_key: Any = None
        # Read by tests and debugging: why the last command was chosen.
        self.last_reason = "cruise"

    def __repr__(self) -> str:
        changed = {k: v for k, v in asdict(self.options).items()
                   if v != getattr(AutopilotOptions, k)}
        return f"Autopilot({', '.join(f'{k}={v!r}' for k, v in changed.items())})"

    # -- perception -----------------------------------------------------------------------
    def _perceive(self, obs: Any) -> Perceived:
        """The agents as seen ``latency`` seconds ago; nothing until a track is that old."""
        delay = int(round(self.options.latency / obs.dt)) if obs.dt > 0 else 0
        self._history.append(Perceived(obs.agents) if obs.agents else EMPTY)
        while len(self._history) > delay + 1:
            self._history.popleft()
        if len(self._history) < delay + 1:
            return EMPTY
        return self._history[0]

    def _route_path(self, route: tuple, obs: Any) -> RoutePath | None:
        if not route:
            return None
        if route is not self._route and route != self._route:
            self._path = RoutePath(route, start=(obs.route_index, obs.s))
            self._route = route
            self._stop_state.clear()
        return self._path

    # -- the step -------------------------------------------------------------------------
    def act(self, obs: Any) -> tuple[float, float]:
        """Acceleration [m/s^2] and front-wheel angle [rad] for one observation."""
        o = self.options
        ego = obs.ego
        dt = obs.dt if obs.dt > 0 else 0.1
        seen = self._perceive(obs)
        if obs.goal is not None and obs.goal.get("kind") == "park":
            key = (obs.goal.get("x"), obs.goal.get("y"), obs.goal.get("heading"))
            if self._parker is None or key != self._goal_key:
                self._parker = Parker(obs.goal, o, ego, seen)
                self._goal_key = key
            if self._parker.phase == "approach":
                self._parker.plan(ego, seen)
            elif self._parker.phase != "abandoned":
                if self._parker.phase != "done" and any(
                        math.hypot(a.vx, a.vy) > 0.3
                        and math.hypot(a.x - ego.x, a.y - ego.y) < 0.5 * ego.length + 4.0
                        for a in seen.agents):
                    # Someone moving close by (a pedestrian behind, a car squeezing past):
                    # pause the manoeuvre where it is.
                    self.last_reason = "park:pause"
                    accel = max(-3.0, min(3.0, -ego.speed / dt))
                    self._accel = accel
                    return accel, 0.0
                accel, steer = self._parker.act(ego, dt)
                self._accel = accel
                self.last_reason = "park:" + self._parker.phase
                return accel, steer

        path = self._route_path(obs.route, obs)
        v = ego.speed
        if path is None:  # no route: hold the heading and stop
            self.last_reason = "no route"
            return self._finish(-o.comfort_decel, 0.0, v, dt)
        L, W = ego.length, ego.width
        off = path.offset(obs.route_index)
        if off is not None:
            s_ego = off + obs.s
        else:
            s_ego = path.project(ego.x, ego.y)[0]

        # Cruise speed, capped by the curvature ahead so the ego can brake into a curve.
        v0 = o.cruise_speed if o.cruise_speed is not None else (
            obs.target_speed if obs.target_speed is not None else obs.speed_limit)
        # (only on a path with some |curvature| over 1e-3 [1/m]; the path is built as the ego
        # goes, so that is asked of the whole path only when the window's bound cannot tell)
        known = path.known_max_abs_curvature
        if known is None or known > 1e-3:
            b = 0.7 * o.comfort_decel
            # Every point's allowed speed is at least sqrt(lateral_accel / |k|max): when that
            # is no cap on v0, the points need not be looked at (the same v0 either way).
            w, bound = path.curve_window(s_ego, s_ego + v * v / (2 * b) + 20.0)
            if math.sqrt(o.lateral_accel / max(bound, 1e-6)) < v0 and (
                    bound > 1e-3 or path.max_abs_curvature > 1e-3):
                v0 = min(v0, path.curve_speed_min(w, s_ego, o.lateral_accel, b))
        accel = o.max_accel * (1.0 - (v / v0) ** o.idm_delta) if v0 > 0.1 else -o.comfort_decel
        reason = "cruise"

        stops: list[tuple[float, str]] = []  # (front-bumper distance to stop [m], why)
        crosswalks = []
        for line in obs.stop_lines:
            off = path.offset(line.route_index)
            if off is None:
                continue
            s_line = off + line.s
            if line.kind == "crosswalk":
                crosswalks.append(s_line)
        if seen.n:
            a_lead, agent_stops, clear = self._agents(seen, path, ego, s_ego, v, v0, crosswalks)
            if a_lead < accel:
                accel, reason = a_lead, "follow"
            stops.extend(agent_stops)
        else:
            clear = True
            self._evade = 0.0
        # Lateral offset from the centre line: right for an encroaching oncoming car, toward
        # the kerb before a parking manoeuvre; reached at 0.5 m/s (a nudge, not a swerve).
        want = -self._evade
        if self._parker is not None:
            want += self._parker.approach_offset(path, s_ego, W)
        self._offset += max(-0.5 * dt, min(0.5 * dt, want - self._offset))
        stops.extend(self._stop_lines(obs, path, s_ego, L, v, dt, clear, seen))
        stops.extend(self._lights(obs, path, s_ego, L, v))
        if self._parker is not None:  # approaching the parking start point
            d = self._parker.approach_distance(ego)
            if d is not None:
                stops.append((d, "park:approach"))
        for d, why in stops:
            a_stop = self._stop_accel(d, v, dt)
            if a_stop < accel:
                accel, reason = a_stop, why
        if self._parker is not None:
            self._parker.maybe_start(ego)

        # Pure pursuit on the centre line, from the vehicle centre along its velocity.
        look = max(o.min_lookahead, o.lookahead_time * v)
        px, py = path.point(s_ego + look)
        if self._offset:
            tx, ty = path.tangent(s_ego + look)
            px, py = px - self._offset * ty, py + self._offset * tx
        dx, dy = px - ego.x, py - ego.y
        steer = pursuit_steering(dx, dy, ego.heading, L, o.max_steering)
        self.last_reason = reason
        return self._finish(accel, steer, v, dt)

    def _finish(self, accel: float, steer: float, v: float, dt: float) -> tuple[float, float]:
        """Actuator realism and limits: braking ramps at ``brake_jerk``, never reverses."""
        o = self.options
        if accel < self._accel:
            floor = min(self._accel, 0.0) - o.brake_jerk * dt
            accel = max(accel, floor)
        accel = max(-o.max_decel, min(o.max_accel, accel))
        if v >= 0.0:
            # highway-env integrates speed without a floor: braking at standstill would
            # drive backwards.
            accel = max(accel, -v / dt)
        self._accel = accel
        return accel, steer

    # -- longitudinal pieces ----------------------------------------------------------------
    def _idm_interaction(self, v: float, v_lead: float, gap: float) -> float:
        """IDM's braking term [m/s^2] behind a lead at bumper gap ``gap`` [m]."""
        o = self.options
        brake_scale = 2.0 * math.sqrt(o.max_accel * o.comfort_decel)
        s_star = o.min_gap + max(0.0, v * o.time_headway + v * (v - v_lead) / brake_scale)
        return -o.max_accel * (s_star / max(gap, 0.1)) ** 2

    def _stop_accel(self, d: float, v: float, dt: float) -> float:
        """Acceleration [m/s^2] to stop the front bumper ``d`` metres ahead.

        Tracks the speed profile of a constant comfortable deceleration, which stops
        crisply (IDM would creep toward a standing obstacle for seconds).
        """
        o = self.options
        if d <= 0.0:
            return -o.max_decel if v > 0.3 else -v / dt
        if d < 0.3 and v < 0.5:
            return -v / dt
        v_des = math.sqrt(2.0 * 0.8 * o.comfort_decel * d)
        if v < v_des:
            return (v_des - v) / 0.4
        # On or above the profile: the constant deceleration that ends exactly at d, which
        # corrects itself each step (a lagging speed tracker would overrun the line).
        return -v * v / (2.0 * d)

    def _travel_time(self, d: float, v: float, v0: float) -> float:
        """Time [s] to cover ``d`` [m] accelerating at max_accel from ``v`` up to ``v0``."""
        if d <= 0.0:
            return 0.0
        a = self.options.max_accel
        vmax = max(v0, v, 0.5)
        d_acc = (vmax * vmax - v * v) / (2.0 * a)
        if d <= d_acc:
            return (-v + math.sqrt(v * v + 2.0 * a * d)) / a
        return (vmax - v) / a + (d - d_acc) / vmax

    def _stop_lines(self, obs, path, s_ego, L, v, dt, clear, seen) -> list[tuple[float, str]]:
        """Stop targets from the route's stop lines: full stop, then go when ``clear`` and it
        has the right of way (first to stop, first to go; see :class:`Junction`)."""
        o = self.options
        out = []
        nearest = True
        for line in obs.stop_lines:
            if line.kind == "crosswalk":
                continue
            off = path.offset(line.route_index)
            if off is None:
                continue
            d = off + line.s - (s_ego + 0.5 * L)
            if d < -L:
                continue  # passed
            key = (line.route_index, round(line.s, 2))
            state = self._stop_state.get(key)
            if state is None:
                # A connector after the line: an intersection whose arrival order counts.
                junction = (Junction(obs.route, line)
                            if line.route_index + 1 < len(obs.route) else None)
                state = self._stop_state[key] = ["approach", 0.0, junction]
            if state[0] == "go":
                continue
            junction = state[2]
            if junction is not None and nearest:
                delay = int(round(o.latency / dt)) * dt if dt > 0 else 0.0
                junction.observe(seen, obs.t - delay)
                if junction.t_me is None and waiting_at_line(d, 0.0, v):
                    junction.t_me = obs.t
            nearest = False
            target = d - o.stop_margin
            if state[0] == "approach":
                if v < 0.1 and target < 1.5:
                    state[1] += dt
                    if state[1] >= o.stop_dwell:
                        state[0] = "waiting"
                else:
                    state[1] = 0.0
            why = "stop line"
            if state[0] == "waiting" and junction is not None:
                junction.waited += dt
            if state[0] == "waiting" and clear:
                if junction is None:
                    state[0] = "go"
                    continue
                if junction.first_to_go(seen, junction.waited < o.allway_patience):
                    state[0] = "go"
                    continue
                why = "right of way"
            out.append((target, why))
        return out

    def _lights(self, obs, path, s_ego, L, v) -> list[tuple[float, str]]:
        """Stop targets for the traffic lights ahead: red, and amber when it can stop at its
        comfortable deceleration; once it went on at amber it keeps going through that
        light (:func:`~pytest_avscenario.sim.signals.must_stop`)."""
        lights = getattr(obs, "traffic_lights", ())
        if not lights:
            return []
        o = self.options
        out = []
        for light in lights:
            off = path.offset(light.route_index)
            if off is None:
                continue
            front = off + light.s - (s_ego + 0.5 * L)
            if front < 0.0:
                continue
            if light.state == GREEN:
                self._light_went.discard(light.signal)
                continue
            if must_stop(light.state, front, v, o.comfort_decel, o.max_decel,
                         light.signal in self._light_went):
                out.append((max(front - o.stop_margin, 0.0), f"{light.state} light"))
                break
            self._light_went.add(light.signal)
        return out

    # -- other agents -------------------------------------------------------------------------
    def _agents(self, seen, path, ego, s_ego, v, v0, crosswalks):
        """Lead following, school buses and conflict yielding.

        Returns (IDM acceleration behind the lead [m/s^2] or +inf, stop targets, clear) where
        ``clear`` says no conflict is predicted (a stop line may be left). Each agent is first
        placed on the route (arc length, lateral offset, velocity along / across it); agents
        not simply travelling along the route in our direction then go through a constant-
        velocity prediction vectorized over (agents x route points).
        """
        o = self.options
        L, W = ego.length, ego.width
        rng2 = o.sensor_range * o.sensor_range
        etx, ety = path.tangent(s_ego)
        a_lead = math.inf
        lead_gap = math.inf
        lead_v = 0.0
        stops: list[tuple[float, str]] = []
        cand = []
        a_bus = math.inf
        shift = 0.0
        for a in seen.agents:
            dx, dy = a.x - ego.x, a.y - ego.y
            if dx * dx + dy * dy > rng2:
                continue  # beyond sensor range
            s_a, lat, tx, ty = path.project_near(a.x, a.y, s_ego + dx * etx + dy * ety)
            v_par = a.vx * tx + a.vy * ty
            v_perp = tx * a.vy - ty * a.vx
            cos_rel = abs(a.c * tx + a.s * ty)
            sin_rel = abs(a.s * tx - a.c * ty)
            ext_par = a.hl * cos_rel + a.hw * sin_rel
            ext_perp = a.hl * sin_rel + a.hw * cos_rel
            # Lead: the nearest agent ahead overlapping the ego's corridor, whatever its lane.
            in_corridor = abs(lat) < 0.5 * W + ext_perp + 0.3
            if in_corridor and s_a > s_ego:
                gap = s_a - s_ego - 0.5 * L - ext_par
                if gap < lead_gap:
                    lead_gap, lead_v = gap, max(v_par, 0.0)
            if a.bus and abs(lat) < 12.0 and s_a + ext_par > s_ego - 0.5 * L:
                d_bus = s_a - ext_par - (s_ego + 0.5 * L)
                if a.arm:
                    # Stop bus_distance short of it; if that point is already overrun, stop
                    # now, unless even an emergency stop would not end before the bus.
                    if d_bus > 0.0 and v * v / (2.0 * d_bus) <= o.max_decel:
                        stops.append((max(d_bus - o.bus_distance, 0.0), "school bus"))
                elif math.hypot(a.vx, a.vy) < o.bus_caution_speed and d_bus > 0.0:
                    # A school bus slowing or standing may put its arm out any moment: arrive
                    # slowly enough to stop for it.
                    # Reach that speed 4 m before the line it would stop at (latency and
                    # brake build-up eat ~1 m at that speed).
                    room = max(d_bus - o.bus_distance - 4.0, 0.0)
                    v_caution = math.sqrt(o.bus_caution_speed ** 2 + 1.4 * o.comfort_decel * room)
                    if v_caution < v0:
                        v0 = v_caution
                        a_caution = o.max_accel * (1.0 - (v / v0) ** o.idm_delta)
                        if a_caution < a_bus:
                            a_bus = a_caution
            if v_par < -1.0 and s_a > s_ego and lat > 0.0:
                # Oncoming and coming closer than its lane allows: make room on the right
                # when it would meet us within the horizon.
                need = 0.5 * W + ext_perp + o.lateral_margin - lat
                if need > 0.0 and (s_a - s_ego) < (v - v_par) * o.horizon:
                    shift = max(shift, min(need, o.evasive_offset))
            if a.ped and crosswalks and abs(lat) < 3.6 and not (
                    lat * v_perp > 0.0 and abs(lat) > 0.5 * W + 1.5):
                # A pedestrian on a crosswalk ahead, in the road and not yet walking clear of
                # our lane: wait at the crosswalk's line, whatever it is predicted to do.
                front = s_ego + 0.5 * L
                for c in crosswalks:
                    if -1.0 < s_a - c < 5.0 and c > front:
                        d = c - front - o.stop_margin
                        if v * v / (2.0 * max(d, 0.05)) <= o.max_decel:
                            stops.append((d, "crosswalk"))
            speed_a = math.hypot(a.vx, a.vy)
            if in_corridor and abs(v_perp) < max(0.5, 0.15 * speed_a) and v_par >= -0.1:
                continue  # ahead or behind on our path, going our way: the lead logic's job
            if speed_a < 0.1 and abs(lat) > 0.5 * W + 1.5 + a.hl + a.hw:
                continue  # standing clear of the path: no constant-velocity conflict
            cand.append((a, ext_par))
        if lead_gap < math.inf:
            a_lead = self._idm_interaction(v, lead_v, lead_gap)
            a_lead += o.max_accel * (1.0 - (v / v0) ** o.idm_delta) if v0 > 0.1 else 0.0
        a_lead = min(a_lead, a_bus)
        self._evade = shift
        clear = True
        yielding = set()
        if cand:
            clear = self._conflicts(cand, path, s_ego, L, W, v, v0, crosswalks, stops, yielding)
        self._yielding = yielding
        return a_lead, stops, clear

    def _conflicts(self, cand, path, s_ego, L, W, v, v0, crosswalks, stops, yielding) -> bool:
        """Constant-velocity conflict prediction; appends yield stops, returns ``clear``.

        For every (agent, route point ahead) pair, |d0 + v t| <= R is solved for t: the
        interval during which the agent covers that route point, R being the ego's half
        width plus the agent's half extent across the route there (for its heading) plus a
        margin. The route points covered within the horizon form the agent's conflict zone
        [s_in, s_out] and its occupancy window [ta_in, ta_out]; the ego yields unless it
        would leave the zone ``gap_time`` before the agent comes, or reach it ``gap_time``
        after the agent has gone (assuming it accelerates toward its cruise speed).
        """
        o = self.options
        reach = max(20.0, v * o.horizon + 0.5 * o.max_accel * o.horizon ** 2 + L)
        w = path.window(s_ego - 0.5 * L, s_ego + min(reach, o.sensor_range))
        qx, qy, qtx, qty, qs = path.x[w], path.y[w], path.tx[w], path.ty[w], path.S[w]
        if self._offset:
            qx, qy = qx - self._offset * qty, qy + self._offset * qtx
        rows = np.array([(a.x, a.y, a.vx, a.vy, a.c, a.s, a.hl, a.hw,
                          o.pedestrian_margin if a.ped else o.lateral_margin)
                         for a, _ in cand])
        ax, ay, avx, avy, ac, as_, hl, hw, margin = (rows[:, k:k + 1] for k in range(9))
        cx, cy = ax - qx, ay - qy
        cos_r = np.abs(ac * qtx + as_ * qty)
        sin_r = np.abs(as_ * qtx - ac * qty)
        radius = 0.5 * W + margin + hl * sin_r + hw * cos_r
        qa = avx * avx + avy * avy
        qb = 2.0 * (cx * avx + cy * avy)
        qc = cx * cx + cy * cy - radius * radius
        disc = qb * qb - 4.0 * qa * qc
        root = np.sqrt(np.maximum(disc, 0.0))
        qa2 = 2.0 * np.maximum(qa, 1e-9)
        t1 = (-qb - root) / qa2
        t2 = (-qb + root) / qa2
        hit = (disc >= 0.0) & (t2 >= 0.0) & (t1 <= o.horizon)
        clear = True
        front, rear = s_ego + 0.5 * L, s_ego - 0.5 * L
        for r in np.flatnonzero(hit.any(axis=1)):
            a, ep = cand[r]
            cols = np.flatnonzero(hit[r])
            s_in = float(qs[cols[0]]) - ep
            s_out = float(qs[cols[-1]]) + ep
            ta_in = max(0.0, float(t1[r, cols].min()))
            ta_out = float(t2[r, cols].max())
            d_in = s_in - front
            if d_in <= 0.0:
                continue  # already inside the zone: committed, drive through
            te_in = self._travel_time(d_in, v, v0)
            te_out = self._travel_time(s_out - rear, v, v0)
            gap = o.gap_time + (0.5 if a.ped else 0.0)
            # Hysteresis: once yielding to an agent, letting go needs twice the margin (else
            # slowing makes the conflict vanish, speeding up brings it back: stop-and-go).
            if a.name in self._yielding:
                gap *= 2.0
            if ta_out + gap <= te_in:
                continue  # it will be gone before we get there
            if te_out + gap <= ta_in:
                continue  # we clear the zone well before it arrives
            clear = False
            d_stop = d_in - o.stop_margin
            if a.ped:
                # Yield to pedestrians at the crosswalk line rather than at them.
                ahead = [c - front for c in crosswalks if front < c < s_in]
                if ahead:
                    d_stop = min(ahead) - o.stop_margin
            if v * v / (2.0 * max(d_stop, 0.05)) > o.max_decel:
                continue  # cannot stop before it any more: commit
            yielding.add(a.name)
            stops.append((d_stop, "yield"))
        return clear

"""The careful and competent (C&C) human driver of UN Regulation No. 157 as an ego driver.

It is the reference against which a failure of the AV under test is judged avoidable: put it
in the ego's seat of the same case (``world.ego(..., driver="careful")``, or an ``avs_driver``
fixture returning ``"careful"``) and see whether it, too, collides.

Source: UN Regulation No. 157 (Automated Lane Keeping Systems), original series
(ECE/TRANS/WP.29/2020/81, in force January 2021), Annex 4, Appendix 3 "Guidance on traffic
disturbance critical scenarios for ALKS", the performance model of a careful and competent
human driver (pages 43-45 of the consolidated text R157e.pdf). The facts carried over:

* **risk perception time** 0.4 s: from the moment a hazard becomes perceivable (a vehicle
  ahead that starts to brake hard, or that is revealed; a vehicle in the next lane that has
  left its lateral wandering zone toward the ego's lane) until the driver has perceived it;
* **reaction time** 0.75 s: from perceiving the risk until the brake starts to act (foot off
  the accelerator onto the brake);
* **braking**: the deceleration builds up linearly to its maximum of **0.774 g** in **0.6 s**
  (a jerk of 0.774 x 9.80665 / 0.6 = 12.65 m/s^3), then holds until the hazard is resolved;
* **lateral wandering distance** 0.375 m: how far a vehicle drifts from its lane centre in
  ordinary driving; a vehicle of the next lane further toward the ego's lane than that,
  moving toward it, is perceivable as cutting in;
* a perceived cut-in is **critical** when its time to collision is below 2 s; only then does
  the driver answer with the model's full response.

So from speed ``v`` with a standing obstacle appearing ahead, the C&C driver stands still
after (the closed form :func:`stopping_distance`; ``T`` = build-up time, ``a`` = maximum
deceleration, ``t_p + t_r`` = 1.15 s)::

    v (t_p + t_r)  +  v T / 2 - a T^2 / 24  +  v^2 / (2 a)

the middle term being the jerk-limited build-up (the distance covered during the 0.6 s ramp
less the speed it already takes off). For a cut-in at constant speed the same formula of the
closing speed gives the gap the driver needs (:func:`closing_distance`). Behind a lead that
brakes at ``d`` to a stop the two motions must be compared over time:
:func:`braking_lead_min_gap` is the smallest gap, from exact piecewise kinematics (the
lead's constant deceleration; the ego's held acceleration through the delay, the linear
build-up, the held maximum), negative where the careful driver collides — e.g. from 20 m/s
at a 1 s time gap behind a 6 m/s^2 stop (-1.9 m), not behind a 5.5 m/s^2 one (+1.1 m).

How the driver follows the model, step by step:

* **onset**: the moment a hazard becomes perceivable, taken from the observations as they
  come: a vehicle in its path (or cutting in) whose speed drops faster than
  ``critical_decel`` between two observations started braking at the first of them (or when
  it was first seen, if it came into view braking); a car of the next lane cuts in when it
  crosses the edge of its wandering zone, interpolated between the two observations around
  it; a car newly in the path (revealed by one cutting out, or at the edge of the sensor
  range) appears when first seen there; and, as a last resort, anything it closes in on
  within the critical TTC is a hazard from then on;
* **perception** ``t_p`` after the onset, judged on what it sees then (not dead-reckoned
  from stale speeds): is the hazard critical? A lead braking harder than ``critical_decel``
  is (R157 counts the risk perception time from the onset of the lead's deceleration and
  gives no threshold; see below). A car cutting in, revealed or closed in on is critical
  when its TTC is below ``critical_ttc`` (R157's criterion) or when ordinary braking — the
  comfortable deceleration after the reaction time — would not stop ``min_gap`` short of
  it (the model's own closed form says only its full response will do: a standing car
  revealed 2.5 s ahead at 20 m/s is critical, though its TTC is above 2 s);
* **reaction**: from the perception until ``t_p + t_r`` after the onset the driver keeps the
  command it gave at the onset (its foot on its way to the brake), or brakes more if
  ordinary driving asks for it;
* **response**: from ``t_p + t_r`` after the onset the brake builds up at the model's jerk
  from what it was doing to 0.774 g, held (integrated exactly over each step, so the speed
  follows the continuous profile at every sample) until the hazard is resolved: the ego
  closes in on nothing in its path and nothing there has braked hard for ``t_p + t_r``;
* a hazard that is not critical is left to ordinary driving.

What the regulation leaves open, and what this driver chose:

* **which lead deceleration is critical**: R157 times the risk perception from the start of
  the lead's deceleration and applies the 2 s TTC to cut-ins, where a TTC exists at the
  moment of perception; behind a lead at the same speed there is none. Here a lead braking
  harder than ``critical_decel`` = 1.5 m/s^2 — the comfortable deceleration ordinary
  following itself uses (IDM's b) — is a critical event and gets the full response at
  once; gentler deceleration is ordinary traffic that IDM follows. (esmini's R157 reference
  driver takes 5 m/s^2; with it, 2-4 m/s^2 stops would be followed by IDM alone and the
  closed form would not describe them.) R157 sets gentle lead decelerations apart from
  critical ones without a figure a simulation can use; this threshold is that line, an
  option, and the closed form describes everything above it;
* **what the driver does during the delay**: R157's figures hold the speed; here the driver
  keeps its command of the onset, which is the speed held when it was cruising. The closed
  form takes that acceleration as an argument;
* **ordinary driving** between hazards (keeping the lane, cruise speed, following) is the
  Intelligent Driver Model with the highway parameters of Treiber, Hennecke and Helbing
  (2000): a = 1.0 m/s^2, b = 1.5 m/s^2, T = 1.6 s, s0 = 2 m, delta = 4 — the regulation
  describes only the response to a critical event. It sees the other agents as they were
  ``t_p + t_r`` ago, dead-reckoned at their speed then (a driver following traffic
  anticipates it at its pace; hazards are not judged on that view), and its braking builds
  up at the model's jerk and stops at 0.774 g.

Simplifications (deliberate, documented so a reader can judge a verdict): no automatic
emergency braking, no evasive steering, no reaction to crossing traffic, pedestrians off its
lane or vehicles behind: the regulation's model is a lane-keeping motorway driver, and so is
this one (straight or gently curved lanes). It sees what the world's sensor range shows (80
m by default, centre to centre): a lead that brakes beyond it is a hazard from when it comes
into view.

Deterministic: no randomness, no clock; one instance drives one case.
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import asdict, dataclass, fields, replace
from typing import Any

from ..control import lane_steering

__all__ = ["CarefulDriver", "CarefulDriverOptions", "stopping_distance", "closing_distance",
           "braking_lead_min_gap", "STANDARD_GRAVITY"]

#: [m/s^2] the "g" of the regulation's 0.774 g (standard gravity, ISO 80000-3)
STANDARD_GRAVITY = 9.80665


@dataclass(frozen=True)
class CarefulDriverOptions:
    """Parameters of the C&C driver; every field can be passed to ``CarefulDriver(**options)``.

    The first six are the regulation's (R157 Annex 4 Appendix 3); the next six shape
    ordinary driving between critical events (IDM, Treiber et al. 2000); ``critical_decel``
    is where this driver draws the line the regulation leaves open between a lead's gentle
    and critical deceleration (see the module doc).
    """

    risk_perception_time: float = 0.4  # [s] R157: hazard perceivable -> risk perceived
    reaction_time: float = 0.75  # [s] R157: risk perceived -> brake acts
    max_decel_g: float = 0.774  # [g] R157: maximum deceleration
    brake_buildup_time: float = 0.6  # [s] R157: time to reach the maximum deceleration
    lateral_wandering: float = 0.375  # [m] R157: lateral wandering distance in the lane
    critical_ttc: float = 2.0  # [s] R157: a perceived hazard is critical below this TTC
    cruise_speed: float | None = None  # [m/s] overrides observation.target_speed / speed_limit
    max_accel: float = 1.0  # [m/s^2] IDM acceleration
    comfort_decel: float = 1.5  # [m/s^2] IDM comfortable deceleration
    time_headway: float = 1.6  # [s] IDM desired time gap
    min_gap: float = 2.0  # [m] IDM standstill gap, bumper to bumper
    idm_delta: float = 4.0  # IDM acceleration exponent
    critical_decel: float = 1.5  # [m/s^2] a lead braking harder than this is a critical event

    def __post_init__(self) -> None:
        for f in fields(self):
            value = getattr(self, f.name)
            if value is None:
                continue
            if not isinstance(value, (int, float)) or isinstance(value, bool) \
                    or not math.isfinite(value):
                raise TypeError(f"CarefulDriver option {f.name}={value!r}: expected a finite number")
            if value < 0:
                raise ValueError(f"CarefulDriver option {f.name}={value!r}: must be >= 0")
        for name in ("max_decel_g", "max_accel", "comfort_decel", "idm_delta"):
            if getattr(self, name) <= 0:
                raise ValueError(f"CarefulDriver option {name}={getattr(self, name)!r}: must be > 0")

    @property
    def delay(self) -> float:
        """[s] from a hazard becoming perceivable to the brake acting: perception + reaction."""
        return self.risk_perception_time + self.reaction_time

    @property
    def max_decel(self) -> float:
        """[m/s^2] the maximum deceleration, 0.774 g by default."""
        return self.max_decel_g * STANDARD_GRAVITY

    @property
    def brake_jerk(self) -> float:
        """[m/s^3] how fast braking builds up (infinite with a zero build-up time)."""
        if self.brake_buildup_time <= 0:
            return math.inf
        return self.max_decel / self.brake_buildup_time


def closing_distance(closing_speed: float, options: CarefulDriverOptions | None = None) -> float:
    """Distance [m] a gap shrinks from the moment a hazard that keeps its speed becomes
    perceivable until the C&C driver has matched that speed, closing at ``closing_speed``
    [m/s] and not accelerating before it reacts: delay, jerk-limited build-up, full braking.

    A standing hazard makes it the stopping distance (:func:`stopping_distance`). 0 when not
    closing.
    """
    o = options if options is not None else CarefulDriverOptions()
    v = float(closing_speed)
    if not v > 0:
        return 0.0
    a, T = o.max_decel, o.brake_buildup_time
    d = v * o.delay
    if T > 0 and v <= a * T / 2:
        # matched during the build-up: j t^2 / 2 = v
        j = a / T
        t = math.sqrt(2 * v / j)
        return d + v * t - j * t ** 3 / 6
    return d + v * T / 2 - a * T * T / 24 + v * v / (2 * a)


def stopping_distance(speed: float, options: CarefulDriverOptions | None = None) -> float:
    """Distance [m] the C&C driver travels from ``speed`` [m/s] between a standing obstacle
    becoming perceivable and standing still (see the module doc for the closed form)."""
    return closing_distance(speed, options)


def braking_lead_min_gap(gap: float, speed: float, lead_speed: float, lead_decel: float, *,
                         accel: float = 0.0,
                         options: CarefulDriverOptions | None = None) -> float:
    """Smallest bumper gap [m] between the C&C driver and a lead that brakes to a stop.

    Time 0 is the hazard's onset, when it becomes perceivable: the bumper gap is ``gap`` [m],
    the ego drives at ``speed`` [m/s] with acceleration ``accel`` [m/s^2] (0: R157's driver
    holds its speed until it reacts), the lead at ``lead_speed`` [m/s] brakes at
    ``lead_decel`` [m/s^2] until it stands (0: it keeps its speed, as a car cutting in; a
    standing obstacle has ``lead_speed`` 0). The C&C driver keeps ``accel`` through the
    delay ``t_p + t_r`` (1.15 s), then its brake builds up linearly from ``min(accel, 0)`` at
    the model's jerk to the maximum deceleration (0.774 g after 0.6 s from rest), held until
    it stands. Negative: the two would overlap by that much, i.e. they collide.

    Exact piecewise kinematics, not a simulation: both motions are polynomials of degree <= 3
    between the breakpoints (the end of the delay, of the build-up, each vehicle's stop), so
    the gap's minimum lies at a breakpoint or where the relative speed, a polynomial of degree
    <= 2 on each piece, vanishes; every candidate is evaluated. It reduces to ``gap -``
    :func:`closing_distance` for a lead keeping its speed and to ``gap -``
    :func:`stopping_distance` for a standing one.
    """
    o = options if options is not None else CarefulDriverOptions()
    for name, value in (("gap", gap), ("speed", speed), ("lead_speed", lead_speed),
                        ("lead_decel", lead_decel), ("accel", accel)):
        if not math.isfinite(value):
            raise ValueError(f"braking_lead_min_gap: {name}={value!r} must be finite")
    if speed < 0 or lead_speed < 0 or lead_decel < 0:
        raise ValueError("braking_lead_min_gap: speeds and the lead's deceleration must be >= 0")
    ego = _cc_response(float(speed), float(accel), o)
    lead = _braking(float(lead_speed), float(lead_decel))
    cuts = sorted({0.0, *(p[0] for p in ego), *(p[0] for p in lead)})
    best = math.inf
    for k, t0 in enumerate(cuts):
        t1 = cuts[k + 1] if k + 1 < len(cuts) else math.inf
        xe, ve, ae, je = _state(ego, t0)
        xl, vl, al, jl = _state(lead, t0)
        g0, dv, da, dj = gap + xl - xe, vl - ve, al - ae, jl - je
        taus = [0.0]
        if math.isfinite(t1):
            taus.append(t1 - t0)
        # where the relative speed dv + da u + dj u^2 / 2 vanishes inside the piece
        if dj != 0.0:
            disc = da * da - 2.0 * dj * dv
            if disc >= 0.0:
                r = math.sqrt(disc)
                taus += [(-da + r) / dj, (-da - r) / dj]
        elif da != 0.0:
            taus.append(-dv / da)
        for u in taus:
            if 0.0 <= u <= t1 - t0:
                best = min(best, g0 + dv * u + da * u * u / 2.0 + dj * u ** 3 / 6.0)
        if not math.isfinite(t1) and dv < 0.0 and da == 0.0 and dj == 0.0:
            return -math.inf  # never happens for a driver that brakes to a stop
    return best


# A motion is a list of pieces (t0 [s], x0 [m], v0 [m/s], a0 [m/s^2], jerk [m/s^3]), each
# valid from its t0 to the next piece's; the last one lasts forever.

def _braking(v: float, d: float) -> list:
    if d <= 0.0 or v <= 0.0:
        return [(0.0, 0.0, v, 0.0, 0.0)]
    t = v / d
    return [(0.0, 0.0, v, -d, 0.0), (t, v * t / 2.0, 0.0, 0.0, 0.0)]


def _cc_response(v: float, a: float, o: CarefulDriverOptions) -> list:
    """The C&C driver's motion from a hazard's onset (see :func:`braking_lead_min_gap`)."""
    pieces = []
    t, x = 0.0, 0.0
    # the delay: its acceleration held (stopping, if braking, where the speed reaches 0)
    td = o.delay
    if a < 0.0 and v + a * td <= 0.0:
        ts = v / -a
        return [(0.0, 0.0, v, a, 0.0), (ts, v * ts / 2.0, 0.0, 0.0, 0.0)]
    pieces.append((t, x, v, a, 0.0))
    x, v, t = x + v * td + a * td * td / 2.0, v + a * td, td
    a_max, jerk = o.max_decel, o.brake_jerk
    a0 = min(a, 0.0)
    if math.isfinite(jerk) and a0 > -a_max:
        ramp = (a0 + a_max) / jerk
        # speed during the build-up: v + a0 u - jerk u^2 / 2; stopped within it?
        u_stop = (a0 + math.sqrt(a0 * a0 + 2.0 * jerk * v)) / jerk
        u = min(ramp, u_stop)
        pieces.append((t, x, v, a0, -jerk))
        x += v * u + a0 * u * u / 2.0 - jerk * u ** 3 / 6.0
        v = max(v + a0 * u - jerk * u * u / 2.0, 0.0)
        t += u
        if u_stop <= ramp:
            pieces.append((t, x, 0.0, 0.0, 0.0))
            return pieces
    if v > 0.0:
        pieces.append((t, x, v, -a_max, 0.0))
        u = v / a_max
        x, t = x + v * u / 2.0, t + u
    pieces.append((t, x, 0.0, 0.0, 0.0))
    return pieces


def _state(motion: list, t: float) -> tuple[float, float, float, float]:
    """(x, v, a, jerk) of a piecewise motion at ``t`` (from the piece starting at or before)."""
    t0, x0, v0, a0, j = motion[0]
    for piece in motion:
        if piece[0] <= t + 1e-12:
            t0, x0, v0, a0, j = piece
    u = t - t0
    return (x0 + v0 * u + a0 * u * u / 2.0 + j * u ** 3 / 6.0, v0 + a0 * u + j * u * u / 2.0,
            a0 + j * u, j)


class _Hazard:
    """One hazard the driver tracks: what it is, when it became perceivable, and (once
    perceived) whether it was critical."""

    __slots__ = ("name", "kind", "onset", "state")

    def __init__(self, name: str, kind: str, onset: float) -> None:
        self.name = name
        self.kind = kind  # "braking", "cut-in", "revealed", "closing"
        self.onset = onset  # [s] when it became perceivable
        self.state = "pending"  # -> "critical" | "ordinary" once perceived


class CarefulDriver:
    """The careful and competent driver of UN R157 (see the module doc for the model).

    ``CarefulDriver(**options)`` takes the fields of :class:`CarefulDriverOptions`;
    ``act(observation) -> (acceleration [m/s^2], steering [rad])``. It keeps its lane (the
    route's current lane), cruises at ``cruise_speed`` (else the scenario's target speed, else
    the speed limit), follows what it has seen in its path with IDM, and answers a critical
    hazard with the regulation's response: its command held from the hazard's onset until
    ``t_p + t_r`` after it, then the ramp at 12.65 m/s^3 to 0.774 g, held until the hazard is
    resolved. ``last_reason`` names what decided the last command ("cruise", "follow",
    "reacting", "critical", "stopped").
    """

    name = "careful"

    def __init__(self, **options: Any) -> None:
        try:
            self.options = CarefulDriverOptions(**options)
        except TypeError as exc:
            known = ", ".join(f.name for f in fields(CarefulDriverOptions))
            raise TypeError(f"{exc}. Known CarefulDriver options: {known}") from None
        self._seen: deque = deque()  # (t [s], agents) observations, oldest first
        self._accel = 0.0  # [m/s^2] last command
        self._commands: deque = deque()  # (t [s], command [m/s^2]) for the last few seconds
        self._last: dict[str, tuple] = {}  # name -> (t, s, r, v_lon, in path) last seen
        self._braking_until: dict[str, float] = {}  # name -> last t [s] seen braking hard
        self._hazards: dict[str, _Hazard] = {}
        # (when the brake acts [s], the command held until then, the command the build-up
        # starts from: known once the brake acts)
        self._response: tuple[float, float, float | None] | None = None
        self.last_reason = "cruise"

    def __repr__(self) -> str:
        changed = {k: v for k, v in asdict(self.options).items()
                   if v != getattr(CarefulDriverOptions, k)}
        return f"CarefulDriver({', '.join(f'{k}={v!r}' for k, v in changed.items())})"

    # -- perception -------------------------------------------------------------------------
    def _view(self, obs: Any) -> tuple[float, tuple]:
        """The newest observation at least ``delay`` old: (its time, its agents); before one
        exists, nothing has been seen yet. Ordinary driving (IDM) uses it."""
        self._seen.append((obs.t, obs.agents))
        cutoff = obs.t - self.options.delay + 1e-9
        while len(self._seen) > 1 and self._seen[1][0] <= cutoff:
            self._seen.popleft()
        t0, agents = self._seen[0]
        return (t0, agents) if t0 <= cutoff else (obs.t, ())

    def _ahead(self, obs: Any, lane: Any, t_seen: float, agents: tuple) -> list:
        """What ordinary driving follows: agents in the ego's path ahead as seen ``delay``
        ago, (bumper gap now [m], speed along the lane [m/s], name), the gap dead-reckoned at
        the speed they had then — a driver following traffic anticipates it at its pace."""
        o = self.options
        ego = obs.ego
        hdg = lane.heading_at(obs.s)
        tx, ty = math.cos(hdg), math.sin(hdg)
        width = lane.width_at(obs.s) if hasattr(lane, "width_at") else 3.5
        age = obs.t - t_seen
        out = []
        for a in agents:
            s_a, r_a = lane.local_coordinates((a.x, a.y))
            v_lon = a.vx * tx + a.vy * ty
            v_lat = a.vy * tx - a.vx * ty  # + toward the left
            s_now = s_a + v_lon * age
            if s_now <= obs.s:
                continue  # behind the ego's centre: not its concern
            in_path = abs(r_a - obs.r) < 0.5 * (ego.width + a.width)
            cutting_in = (abs(r_a) < 1.5 * width and abs(r_a) < width - o.lateral_wandering
                          and r_a * v_lat < 0.0)
            if in_path or cutting_in:
                out.append((s_now - obs.s - 0.5 * (ego.length + a.length), v_lon, a.name))
        return out

    def _notice(self, obs: Any, lane: Any) -> list:
        """Register the hazards that became perceivable since the last observation, from the
        current one (the driver acts on them only ``t_p`` later, see :meth:`_perceive`).
        Returns what is in the ego's path ahead now: (gap [m], speed along the lane [m/s],
        deceleration [m/s^2], name)."""
        o = self.options
        ego = obs.ego
        hdg = lane.heading_at(obs.s)
        tx, ty = math.cos(hdg), math.sin(hdg)
        width = lane.width_at(obs.s) if hasattr(lane, "width_at") else 3.5
        edge = width - o.lateral_wandering  # |r| inside this: out of its wandering zone
        v = ego.speed
        now: dict[str, tuple] = {}
        in_path_now = []
        for a in obs.agents:
            s_a, r_a = lane.local_coordinates((a.x, a.y))
            v_lon = a.vx * tx + a.vy * ty
            v_lat = a.vy * tx - a.vx * ty
            in_path = abs(r_a - obs.r) < 0.5 * (ego.width + a.width)
            now[a.name] = (obs.t, s_a, r_a, v_lon, in_path)
            if s_a <= obs.s:
                continue
            gap = s_a - obs.s - 0.5 * (ego.length + a.length)
            prev = self._last.get(a.name)
            decel = 0.0
            if prev is not None and obs.t > prev[0]:
                decel = (prev[3] - v_lon) / (obs.t - prev[0])
            toward = r_a * v_lat < 0.0
            cutting_in = abs(r_a) < 1.5 * width and abs(r_a) < edge and toward
            if decel > o.critical_decel and (in_path or cutting_in):
                # braking since the previous sample at the latest: that is its onset
                self._braking_until[a.name] = obs.t
                self._register(a.name, "braking", prev[0])
            if cutting_in and not in_path:
                onset = obs.t
                if prev is not None and abs(prev[2]) >= edge and obs.t > prev[0]:
                    # it crossed the edge of its wandering zone between the two samples
                    f = (abs(prev[2]) - edge) / max(abs(prev[2]) - abs(r_a), 1e-9)
                    onset = prev[0] + min(max(f, 0.0), 1.0) * (obs.t - prev[0])
                self._register(a.name, "cut-in", onset)
            if in_path:
                if prev is None or not prev[4]:
                    # newly in the path: revealed (a car cutting out, the edge of the sensor
                    # range) unless it came in as a cut-in already registered
                    self._register(a.name, "revealed", obs.t)
                closing = v - v_lon
                if closing > 0.0 and gap < o.critical_ttc * closing:
                    self._register(a.name, "closing", obs.t)
                in_path_now.append((gap, v_lon, decel, a.name))
        self._last = now
        return in_path_now

    def _register(self, name: str, kind: str, onset: float) -> None:
        h = self._hazards.get(name)
        if (h is None or (h.state == "ordinary" and kind in ("braking", "closing"))
                or (h.state == "pending" and kind == "braking" and h.kind != kind)):
            # a braking lead is critical whatever else was noticed about it (a car revealed
            # already braking brakes from when it was first seen); one judged ordinary is a
            # hazard again when it brakes, or when ordinary following lets it within the
            # critical TTC
            self._hazards[name] = _Hazard(name, kind, onset)

    def _perceive(self, obs: Any, path: list) -> None:
        """Judge the hazards perceivable for ``t_p`` now, on what is seen now: a lead braking
        harder than ``critical_decel`` is critical; a car cutting in, revealed or closing in
        is critical when its time to collision is below ``critical_ttc``. A critical one
        starts the response (if none runs): the brake acts ``t_p + t_r`` after its onset."""
        o = self.options
        v = obs.ego.speed
        by_name = {p[3]: p for p in path}
        for h in self._hazards.values():
            if h.state != "pending" or obs.t + 1e-9 < h.onset + o.risk_perception_time:
                continue
            seen = by_name.get(h.name)
            if h.kind == "braking":
                critical = True
            else:
                if seen is None:  # a cut-in not yet in the path: its gap along the lane
                    seen = self._along(h.name, obs)
                critical = seen is not None and self._needs_response(v, seen[0], seen[1])
            h.state = "critical" if critical else "ordinary"
            if critical and self._response is None:
                self._response = (h.onset + o.delay, self._command_at(h.onset), None)

    def _needs_response(self, v: float, gap: float, v_other: float) -> bool:
        """Is closing in on something ``gap`` [m] ahead at ``v_other`` [m/s] critical? R157's
        criterion, a time to collision below ``critical_ttc``; or when ordinary braking (the
        comfortable deceleration, after the reaction time) would not stop the ego
        ``min_gap`` short of it — the model's own closed form says only its full response
        will do (a standing car revealed 2.5 s ahead is critical whatever its TTC)."""
        o = self.options
        closing = v - v_other
        if closing <= 0.0:
            return False
        if gap < o.critical_ttc * closing:
            return True
        ordinary = replace(o, risk_perception_time=0.0,
                           max_decel_g=o.comfort_decel / STANDARD_GRAVITY)
        # something coming toward us on our path (an oncoming car across a junction) is taken
        # as standing here: no less demanding than that, and its closing speed counts in
        # the time-to-collision test above
        return braking_lead_min_gap(max(gap, 0.0), v, max(v_other, 0.0), 0.0,
                                    options=ordinary) < o.min_gap

    def _along(self, name: str, obs: Any) -> tuple | None:
        rec = self._last.get(name)
        if rec is None:
            return None
        a = next((x for x in obs.agents if x.name == name), None)
        length = a.length if a is not None else obs.ego.length
        return (rec[1] - obs.s - 0.5 * (obs.ego.length + length), rec[3])

    def _command_at(self, t: float) -> float:
        """The command that was in force at ``t`` [s] (the last one given at or before)."""
        cmd = self._accel
        for t_c, a in reversed(self._commands):
            cmd = a
            if t_c <= t + 1e-9:
                break
        return cmd

    def _resolved(self, obs: Any, path: list) -> bool:
        """The hazard is over once the ego closes in on nothing in its path and nothing there
        has braked hard for ``t_p + t_r`` (so what ordinary driving sees is settled too)."""
        v = obs.ego.speed
        for gap, v_lon, _, name in path:
            if v > v_lon + 1e-6:
                return False
            if obs.t - self._braking_until.get(name, -math.inf) < self.options.delay:
                return False
        return True

    # -- the step -----------------------------------------------------------------------------
    def act(self, obs: Any) -> tuple[float, float]:
        """Acceleration [m/s^2] and front-wheel angle [rad] for one observation."""
        o = self.options
        ego = obs.ego
        dt = obs.dt if obs.dt > 0 else 0.1
        v = ego.speed
        t_seen, agents = self._view(obs)
        lane = obs.route[obs.route_index] if obs.route else None
        if lane is None:
            self.last_reason = "no route"
            return self._finish(obs.t, -o.comfort_decel, 0.0, v, dt)
        path = self._notice(obs, lane)
        self._perceive(obs, path)
        ahead = self._ahead(obs, lane, t_seen, agents) if agents else []

        v0 = o.cruise_speed if o.cruise_speed is not None else (
            obs.target_speed if obs.target_speed is not None else obs.speed_limit)
        accel = o.max_accel * (1.0 - (v / v0) ** o.idm_delta) if v0 > 0.1 else -o.comfort_decel
        reason = "cruise"
        if ahead:
            gap, v_lead, _ = min(ahead)
            s_star = o.min_gap + max(0.0, v * o.time_headway + v * (v - v_lead)
                                     / (2.0 * math.sqrt(o.max_accel * o.comfort_decel)))
            accel -= o.max_accel * (s_star / max(gap, 0.1)) ** 2
            reason = "follow"
        light = self._light(obs, v)
        if light is not None:
            # a red light (amber when it can stop comfortably): a standing car at its line
            s_star = o.min_gap + max(0.0, v * o.time_headway + v * v
                                     / (2.0 * math.sqrt(o.max_accel * o.comfort_decel)))
            free = 1.0 - (v / v0) ** o.idm_delta if v0 > 0.1 else 0.0
            a_light = o.max_accel * (free - (s_star / max(light + o.min_gap, 0.1)) ** 2)
            if a_light < accel:
                accel, reason = a_light, "light"
        # ordinary driving's braking builds up at the model's jerk as well
        if accel < self._accel:
            accel = max(accel, min(self._accel, 0.0) - o.brake_jerk * dt)
        if self._response is not None and obs.t >= self._response[0] and self._resolved(obs, path):
            self._response = None
            self._hazards = {k: h for k, h in self._hazards.items() if h.state == "pending"}
        if self._response is not None:
            t_b, held, a_pre = self._response
            if obs.t + dt <= t_b + 1e-9:  # (a step that ends where the brake acts)
                # reacting: the command of the onset held, or more braking if ordinary driving
                # asks for it (its own build-up at the model's jerk)
                accel = min(accel, held)
                reason = "reacting"
            else:
                if a_pre is None:
                    # the brake acts: it builds up from what the driver was doing then
                    self._response = (t_b, held, self._accel)
                accel = self._profile(obs.t, dt)
                reason = "critical"
        lookahead = max(v, 0.0) * 0.1
        steer = lane_steering(v, ego.heading, obs.r, lane.heading_at(obs.s + lookahead),
                              ego.length)
        self.last_reason = "stopped" if v <= 0.0 and accel <= 0.0 else reason
        return self._finish(obs.t, accel, steer, v, dt)

    def _light(self, obs: Any, v: float) -> float | None:
        """Distance [m] from the front bumper to where it stops for a traffic light ahead
        (1 m before the stop position), or None (as :func:`..signals.must_stop`, stopping
        on amber when 3 m/s^2 does — the amber-time formula's deceleration; its own IDM
        comfort, 1.5 m/s^2, would run many ambers into red — at most its maximum on red)."""
        from ..signals import AMBER_DECEL, GREEN, must_stop

        lights = getattr(obs, "traffic_lights", ())
        if not lights:
            return None
        o = self.options
        went = self.__dict__.setdefault("_light_went", set())
        for light in lights:
            ahead = sum(obs.route[j].length for j in range(obs.route_index, light.route_index))
            front = ahead + light.s - obs.s - 0.5 * obs.ego.length
            if front < 0.0:
                continue
            if light.state == GREEN:
                went.discard(light.signal)
                continue
            if must_stop(light.state, front, v, max(o.comfort_decel, AMBER_DECEL),
                         o.max_decel, light.signal in went):
                return max(front - 1.0, 0.0)
            went.add(light.signal)
        return None

    def _profile(self, t: float, dt: float) -> float:
        """The regulation's response averaged over the step [t, t + dt], so the speed follows
        the continuous profile exactly at every sample: the command of the reaction phase
        until the brake acts at ``t_b``, then from it (or 0, if it was accelerating) down at
        the model's jerk to the maximum deceleration, held."""
        o = self.options
        t_b, _, a_pre = self._response
        a_max, jerk = o.max_decel, o.brake_jerk
        a_on = min(a_pre, 0.0)

        def integral(u: float) -> float:  # of the profile from t_b to t_b + u (u may be < 0)
            if u <= 0.0:
                return a_pre * u
            if math.isinf(jerk):
                return -a_max * u
            t_full = max((a_on + a_max) / jerk, 0.0)  # when the ramp reaches -a_max
            if u <= t_full:
                return a_on * u - 0.5 * jerk * u * u
            return a_on * t_full - 0.5 * jerk * t_full * t_full - a_max * (u - t_full)

        return (integral(t + dt - t_b) - integral(t - t_b)) / dt

    def _finish(self, t: float, accel: float, steer: float, v: float,
                dt: float) -> tuple[float, float]:
        """Human limits: braking stops at the model's maximum and never reverses the car."""
        o = self.options
        accel = max(-o.max_decel, min(o.max_accel, accel))
        if v >= 0.0:
            accel = max(accel, -v / dt)
        self._accel = accel
        self._commands.append((t, accel))
        while len(self._commands) > 2 and self._commands[1][0] < t - 2.0 * o.delay:
            self._commands.popleft()
        return accel, steer

"""The stack's side of ``avs-osi/1`` for Python stacks: serve a driver in a few lines.

::

    from pytest_avscenario.stack import serve

    def policy(obs):                      # the Observation an in-process driver gets
        return 1.0, 0.0                   # (acceleration [m/s^2], steering [rad])

    serve(policy, "tcp://127.0.0.1:5555")

:func:`serve` binds a REP socket and answers the plugin: a ``Reset`` starts a case (a
driver given by name — ``"autopilot"``, ``"careful"``, ``"package.module:Name"`` — is made
afresh; an object's ``reset()`` hook is called), each ``SensorView`` is turned into the
:class:`~pytest_avscenario.sim.observation.Observation` the world would have built (the
ego's route from the Reset, its progress along it tracked here as the world tracks it, the
agents within sensor range nearest first), and the driver's (acceleration, steering) goes
back as a ``MotionRequest`` whose desired state is where that command takes the ego in one
step (:func:`~.frame.action_to_motion`), or, with ``answer="trajectory"``, whose desired
trajectory is where the command held takes it (:func:`~.frame.action_to_trajectory`). A driver that raises is answered with ``Error``
and its traceback, which the plugin shows as the case's error.

Lanes are rebuilt from the OSI centre lines: a straight lane exactly (two points), a curved
one as a polyline of its one-metre samples (a driver on a curve sees it to within
millimetres, not bit for bit). A lane's width along it (``width_at(s)``) is read from its
two boundaries, which the plugin places half the width at each centre-line point to either
side: on a map whose lanes widen and narrow, the driver sees the width where the ego is,
not the Reset's ``width`` (the width at s = 0).
"""

from __future__ import annotations

import bisect
import math
import os
import traceback
from typing import Any

import numpy as np

from . import frame, wire

__all__ = ["serve", "Session", "StraightLine", "Polyline"]


class _Widths:
    """A lane's width [m] along it from its widths at points ``ss`` [m] (ascending): linear
    between them, the end's beyond an end."""

    def __init__(self, ss: Any, widths: Any) -> None:
        self._s = [float(v) for v in ss]
        self._w = [float(v) for v in widths]

    def at(self, s: float) -> float:
        k = min(max(bisect.bisect_right(self._s, s) - 1, 0), len(self._s) - 2)
        s0, s1 = self._s[k], self._s[k + 1]
        f = min(max((s - s0) / (s1 - s0), 0.0), 1.0) if s1 > s0 else 0.0
        return self._w[k] + f * (self._w[k + 1] - self._w[k])


class StraightLine:
    """A straight lane from two centre-line points, with the lanes' small vocabulary
    (``position``, ``heading_at``, ``local_coordinates``, ``length``, ``width_at``) computed
    as the simulator's straight lanes compute it. ``width`` [m] is its width at its start;
    ``widths``, when given, its width at each of the two points (``width_at`` follows it)."""

    def __init__(self, start: Any, end: Any, width: float, speed_limit: float,
                 widths: Any = None) -> None:
        self.start = np.array(start[:2], dtype=float)
        self.end = np.array(end[:2], dtype=float)
        self.length = float(np.linalg.norm(self.end - self.start))
        self.direction = (self.end - self.start) / self.length
        self._sx, self._sy = float(self.start[0]), float(self.start[1])
        self._dx, self._dy = float(self.direction[0]), float(self.direction[1])
        self.heading = float(np.arctan2(self.direction[1], self.direction[0]))
        self.width = float(width)
        self.speed_limit = float(speed_limit)
        self.radius = math.inf
        self._widths = None if widths is None else _Widths((0.0, self.length), widths)

    def position(self, longitudinal: float, lateral: float) -> np.ndarray:
        return np.array([self._sx + longitudinal * self._dx - lateral * self._dy,
                         self._sy + longitudinal * self._dy + lateral * self._dx])

    def local_coordinates(self, position: Any) -> tuple[float, float]:
        ex = position[0] - self._sx
        ey = position[1] - self._sy
        return float(ex * self._dx + ey * self._dy), float(ey * self._dx - ex * self._dy)

    def heading_at(self, longitudinal: float) -> float:
        return self.heading

    def width_at(self, longitudinal: float) -> float:
        return self.width if self._widths is None else self._widths.at(longitudinal)


class Polyline:
    """A curved lane as the polyline of its centre-line samples (same vocabulary; ``widths``
    as :class:`StraightLine`'s, one a point)."""

    def __init__(self, points: Any, width: float, speed_limit: float, widths: Any = None) -> None:
        p = np.asarray(points, dtype=float)[:, :2]
        seg = np.diff(p, axis=0)
        seglen = np.hypot(seg[:, 0], seg[:, 1])
        self._widths = None if widths is None else \
            _Widths(np.concatenate([[0.0], np.cumsum(seglen)]), widths)
        keep = seglen > 1e-9
        self._p0, self._seg, self._len = p[:-1][keep], seg[keep], seglen[keep]
        self._cum = np.concatenate([[0.0], np.cumsum(self._len)])
        self._dir = self._seg / self._len[:, None]
        self._head = np.arctan2(self._dir[:, 1], self._dir[:, 0])
        self.length = float(self._cum[-1])
        self.width = float(width)
        self.speed_limit = float(speed_limit)

    def _segment(self, s: float) -> int:
        return min(max(bisect.bisect_right(self._cum, s) - 1, 0), len(self._len) - 1)

    def position(self, longitudinal: float, lateral: float) -> np.ndarray:
        i = self._segment(longitudinal)
        dx, dy = self._dir[i]
        u = longitudinal - self._cum[i]
        return np.array([self._p0[i, 0] + u * dx - lateral * dy, self._p0[i, 1] + u * dy + lateral * dx])

    def heading_at(self, longitudinal: float) -> float:
        return float(self._head[self._segment(longitudinal)])

    def local_coordinates(self, position: Any) -> tuple[float, float]:
        e = np.asarray(position[:2], dtype=float) - self._p0
        u = np.clip(np.einsum("ij,ij->i", e, self._dir), 0.0, self._len)
        near = self._p0 + u[:, None] * self._dir
        i = int(np.argmin(np.hypot(*(np.asarray(position[:2]) - near).T)))
        ex, ey = e[i]
        dx, dy = self._dir[i]
        return float(self._cum[i] + ex * dx + ey * dy), float(ey * dx - ex * dy)

    def width_at(self, longitudinal: float) -> float:
        return self.width if self._widths is None else self._widths.at(longitudinal)


def _widths(lane: Any, bounds: dict, n: int) -> list[float] | None:
    """A lane's width [m] at each of its ``n`` centre-line points, read from its boundaries
    (the plugin sends one boundary point a centre-line point, half the width at that point
    to each side), or None when it is one width all along (the Reset's ``width``, the width
    at s = 0) or the boundaries are not there."""
    cl = lane.classification
    if not cl.left_lane_boundary_id or not cl.right_lane_boundary_id:
        return None
    left = bounds.get(cl.left_lane_boundary_id[0].value)
    right = bounds.get(cl.right_lane_boundary_id[0].value)
    if left is None or right is None or not len(left.boundary_line) == len(right.boundary_line) == n:
        return None
    out = [math.hypot(a.position.x - b.position.x, a.position.y - b.position.y)
           for a, b in zip(left.boundary_line, right.boundary_line)]
    return out if max(out) - min(out) > 1e-6 else None


def _number(value: Any) -> float:
    """A JSON number as a float; ``null`` (sent for what is not finite) as NaN."""
    return math.nan if value is None else float(value)


class Session:
    """One case on the stack's side: the Reset's facts, the route, the driver."""

    def __init__(self, hello: dict, policy: Any, answer: str = "desired_state") -> None:
        from ..sim.drivers import resolve

        self.hello = hello
        self.answer_kind = answer
        self.dt = float(hello["dt"])
        self.dt_ns = wire.ns(self.dt)
        self.host = int(hello["host_vehicle_id"])
        self.agents = {int(a["id"]): a for a in hello["agents"]}
        self.lanes = {int(l["id"]): l for l in hello["lanes"]}
        ego = hello["ego"]
        self.route_ids = [int(i) for i in ego["route"]]
        self.route_index = int(ego["route_index"])
        self.target_speed = ego.get("target_speed")
        self.goal = ego.get("goal")
        self.sensor_range = float(ego.get("sensor_range", 80.0))
        self.route: tuple = ()
        self._motion: Any = None  # the MotionRequest answered with, kept for the case
        self._slots: tuple = ()  # its timestamp and desired state's sub-messages
        self.stop_lines: dict[int, tuple] = {}
        self._limits: dict[int, float] = {}  # route index -> speed limit [m/s]
        # traffic lights: stop positions by lane OSI id -> [(s, light OSI id, signal id)]
        self.light_stops: dict[int, list] = {}
        for light in hello.get("traffic_lights", ()):
            for lane, s in light["stops"]:
                self.light_stops.setdefault(int(lane), []).append(
                    (float(s), int(light["id"]), str(light["signal"])))
        # a name is made afresh for each case, as the world makes it; an object is reused and
        # its per-case hook called (with no world: the stack has only what the wire carries)
        self.driver = resolve(policy)
        if not callable(getattr(self.driver, "act", None)) or callable(getattr(self.driver, "make_ego", None)):
            raise ValueError(f"cannot serve {policy!r}: serve a driver that answers act(observation)")
        hook = getattr(self.driver, "reset", None)
        if callable(hook):
            hook(None)

    def _build_route(self, gt: Any) -> None:
        by_id = {lane.id.value: lane for lane in gt.lane}
        bounds = {b.id.value: b for b in gt.lane_boundary}
        route = []
        for lid in self.route_ids:
            lane = by_id[lid]
            pts = [(p.x, p.y) for p in lane.classification.centerline]
            info = self.lanes[lid]
            limit = _number(info.get("speed_limit"))
            widths = _widths(lane, bounds, len(pts))
            cls = StraightLine(pts[0], pts[1], info["width"], limit, widths) if len(pts) == 2 \
                else Polyline(pts, info["width"], limit, widths)
            route.append(cls)
        self.route = tuple(route)

    def _state(self, oid: int, mo: Any, kind: str | None = None, b: Any = None,
               p: Any = None) -> Any:
        """The AgentState of the ``osi3.MovingObject`` ``mo`` (OSI id ``oid``): what
        :func:`.frame.object_state` reads, each sub-message looked up once (every lookup of
        one through protobuf's Python wrappers costs as much as reading a number; ``b`` and
        ``p``: its ``base`` and ``base.position`` when the caller has them)."""
        if b is None:
            b = mo.base
            p = b.position
        v, d = b.velocity, b.dimension
        yaw = b.orientation.yaw
        vx, vy = v.x, v.y
        speed = math.hypot(vx, vy)
        if vx * math.cos(yaw) + vy * math.sin(yaw) < 0.0:
            speed = -speed
        info = self.agents.get(oid, _NO_INFO)
        k = kind or info.get("kind", "car")
        return _SIM["frozen"](_SIM["AgentState"], {
            "x": p.x, "y": p.y, "heading": yaw, "speed": speed, "vx": vx, "vy": vy,
            "length": d.length, "width": d.width, "name": info.get("name", str(oid)), "kind": k,
            "flags": frame.object_flags(mo) if k == "bus" else {}})

    def observation(self, sv: Any, t_ns: int | None = None) -> Any:
        """The Observation the world would have handed an in-process driver (``t_ns``: the
        SensorView's timestamp [ns], when the caller has read it already)."""
        sim = _sim()
        frozen = sim["frozen"]
        gt = sv.global_ground_truth
        if not self.route:
            self._build_route(gt)
        if t_ns is None:
            t_ns = wire.timestamp_ns(sv.timestamp)
        t = int(round(t_ns / self.dt_ns)) * self.dt  # the world's k * dt, bit for bit
        host = self.host
        ego_mo = None
        others = {}  # by OSI id: the last of a repeated id counts, in the order first seen
        for mo in gt.moving_object:
            oid = mo.id.value
            if oid == host:
                ego_mo = mo
            else:
                others[oid] = mo
        if ego_mo is None:
            raise ValueError(f"the SensorView has no host vehicle (id {self.host})")
        state = self._state
        ego = state(host, ego_mo, "ego")
        x, y = ego.x, ego.y
        # route progress, as the world's lane tracker advances it
        ri = self.route_index
        g = self.route[ri]
        s, r = g.local_coordinates((x, y))
        while s > g.length and ri + 1 < len(self.route):
            ri += 1
            g = self.route[ri]
            s, r = g.local_coordinates((x, y))
        self.route_index = ri
        near = []
        rng2 = self.sensor_range ** 2
        for oid, mo in others.items():
            b = mo.base
            p = b.position
            dx, dy = p.x - x, p.y - y
            d2 = dx * dx + dy * dy
            if d2 <= rng2:
                near.append((d2, oid, mo, b, p))
        near.sort(key=lambda q: (q[0], q[1]))

        stops = self.stop_lines.get(ri)
        if stops is None:
            StopLine = sim["StopLine"]
            stops = tuple(StopLine(j, float(sm), kind) for j in range(ri, len(self.route))
                          for sm, kind in self.lanes[self.route_ids[j]].get("stop_marks", ()))
            self.stop_lines[ri] = stops
        limit = self._limits.get(ri)
        if limit is None:
            limit = self._limits[ri] = _number(self.lanes[self.route_ids[ri]].get("speed_limit"))
        lights: tuple = ()
        if self.light_stops:
            from osi3 import osi_trafficlight_pb2 as TL

            C = TL.TrafficLight.Classification
            names = {C.COLOR_GREEN: "green", C.COLOR_YELLOW: "amber", C.COLOR_RED: "red"}
            lit = {tl.id.value: names.get(tl.classification.color, "red")
                   for tl in gt.traffic_light}
            lights = tuple(sim["TrafficLight"](j, s, lit.get(oid, "red"), sid)
                           for j in range(ri, len(self.route))
                           for s, oid, sid in sorted(self.light_stops.get(self.route_ids[j], ())))
        return frozen(sim["Observation"], {
            "t": t, "dt": self.dt, "ego": ego, "route": self.route,
            "route_index": ri, "s": float(s), "r": float(r),
            "agents": tuple([state(oid, mo, None, b, p) for _, oid, mo, b, p in near]),
            "stop_lines": stops,
            "speed_limit": limit, "target_speed": self.target_speed, "goal": self.goal,
            "sensor_range": self.sensor_range, "traffic_lights": lights})

    def answer(self, sv: Any) -> bytes:
        """The serialized MotionRequest answering one SensorView."""
        t_ns = wire.timestamp_ns(sv.timestamp)
        obs = self.observation(sv, t_ns)
        a, d = _SIM["action_pair"](self.driver.act(obs))
        ego = obs.ego
        if self.answer_kind == "trajectory":
            mr = frame._osi()["motionrequest"].MotionRequest()
            wire.set_version(mr.version)
            wire.set_timestamp(mr.timestamp, t_ns)
            frame.action_to_trajectory(mr, t_ns, ego.x, ego.y, ego.heading, ego.speed, ego.length,
                                       self.dt, a, d)
            return mr.SerializeToString()
        # one message for the case: a desired state sets the same fields every step, so
        # overwriting them serializes to the bytes a fresh message would
        mr = self._motion
        if mr is None:
            mr = self._motion = frame._osi()["motionrequest"].MotionRequest()
            wire.set_version(mr.version)
            self._slots = (mr.timestamp, frame.desired_state_slots(mr))
        stamp, slots = self._slots
        stamp.seconds, stamp.nanos = divmod(t_ns, 1_000_000_000)
        frame.action_to_motion(mr, t_ns, ego.x, ego.y, ego.heading, ego.speed, ego.length,
                               self.dt, a, d, slots)
        return mr.SerializeToString()


_NO_INFO: dict = {}
_SIM: dict[str, Any] = {}


def _sim() -> dict[str, Any]:
    """The simulator's pieces an answer needs, imported on first use (not once a step)."""
    if not _SIM:
        from ..sim.drivers import action_pair
        from ..sim.observation import AgentState, Observation, StopLine, TrafficLight
        from ..sim.world import _frozen

        _SIM.update(action_pair=action_pair, AgentState=AgentState, Observation=Observation,
                    StopLine=StopLine, TrafficLight=TrafficLight, frozen=_frozen)
    return _SIM


#: what :func:`serve` answers with: a MotionRequest's desired state one step ahead (the
#: driver's command, exactly), or its desired trajectory (the command held for one second)
ANSWERS = ("desired_state", "trajectory")


def handle(frames: list[bytes], session: Session | None, policy: Any,
           answer: str = "desired_state") -> tuple[list[bytes], Session | None]:
    """The answer to one request and the session after it (a step of :func:`serve`)."""
    try:
        kind, body = wire.unpack(frames, (wire.RESET, wire.SENSOR_VIEW))
        if kind == wire.RESET:
            hello = wire.json_body(body, "Reset")
            if hello.get("revision") != wire.REVISION:
                return wire.pack(wire.ERROR, f"this kit speaks revision {wire.REVISION}, "
                                             f"not {hello.get('revision')!r}"), None
            session = Session(hello, policy, answer)
            return wire.pack(wire.READY, {
                "protocol": wire.PROTOCOL.decode(), "revision": wire.REVISION,
                "osi_version": ".".join(map(str, wire.osi_version())), "dt": hello["dt"],
                "host_vehicle_id": hello["host_vehicle_id"], "answer": "MotionRequest"}), session
        if session is None:
            return wire.pack(wire.ERROR, "SensorView before any Reset"), None
        sv = wire.parse(frame._osi()["sensorview"].SensorView, body, "SensorView")
        return wire.pack(wire.MOTION_REQUEST, session.answer(sv)), session
    except Exception as exc:  # the driver is user code: its error goes back to the plugin
        return wire.pack(wire.ERROR, f"{type(exc).__name__}: {exc}\n{traceback.format_exc()}"), session


def _spin_from_env() -> float:
    """[µs] the spin a spawning plugin handed over (``wire.SPIN_ENV``), else 0."""
    raw = os.environ.get(wire.SPIN_ENV, "")
    try:
        value = float(raw) if raw else 0.0
    except ValueError:
        value = 0.0
    return value if 0 <= value < float("inf") else 0.0


def serve(policy: Any, address: str, *, answer: str = "desired_state",
          requests: int | None = None, spin_us: float | None = None) -> None:
    """Answer the plugin at ``address`` (``tcp://…`` or ``ipc://…``, bound here) with
    ``policy``: anything ``world.ego(driver=...)`` accepts that answers ``act(observation)``
    (a name such as ``"autopilot"``, an object with ``act``, a callable). ``answer`` is the
    MotionRequest sent: ``"desired_state"`` (one step ahead: the plugin applies the driver's
    command exactly) or ``"trajectory"`` (where the command held for ten steps takes the ego:
    the plugin's trajectory controller follows it). ``spin_us``: how long each wait for a
    request keeps the CPU before it blocks [µs]; by default what a plugin that spawned this
    stack hands it (``$AVS_OSI_SPIN_US``, from ``--avs-stack-spin``), else 0. Runs until the
    process is stopped (or after ``requests`` requests, for tests)."""
    from .zmtp import Replier

    if answer not in ANSWERS:
        raise ValueError(f"serve(answer={answer!r}): use one of {', '.join(ANSWERS)}")
    if spin_us is None:
        spin_us = _spin_from_env()
    if not (isinstance(spin_us, (int, float)) and 0 <= spin_us < float("inf")):
        raise ValueError(f"serve(spin_us={spin_us!r}): a number of microseconds >= 0")

    # ZeroMQ's REP spoken on the socket itself (.zmtp): no I/O thread to wake each way
    sock = Replier(address, spin_s=spin_us * 1e-6)
    session = None
    n = 0
    # a stack the plugin spawned (it hands the address in AVS_OSI_ADDRESS) ends with the
    # process that started it, even when that one was killed and could not stop it
    parent = os.getppid() if os.environ.get("AVS_OSI_ADDRESS") == address else None
    wait_s = 1.0 if parent is not None else None  # [s] between looks at the parent
    try:
        while requests is None or n < requests:
            frames = sock.receive(wait_s)
            if frames is None:
                if os.getppid() != parent:
                    return
                continue
            reply, session = handle(frames, session, policy, answer)
            sock.send(reply)
            n += 1
    finally:
        sock.close()

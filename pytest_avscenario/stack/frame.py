"""The world in OSI's terms and back: the one place where frames, ids and units are converted.

The world's frame is x east, y north [m], headings counter-clockwise from +x [rad], and an
agent's position is the centre of its footprint. ASAM OSI uses the same right-handed frame
(z up, yaw counter-clockwise from +x) and puts ``base.position`` at the centre of the 3-D
bounding box. So x, y and yaw carry over unchanged (yaw wrapped into [-pi, pi], as OSI
asks), z is half the object's height, and pitch and roll are 0. highway-env draws y down;
that never reaches the wire (see docs/osi-protocol.md, "Frames").

Ids: an agent's OSI id is 1 + its place in ``world.agents`` (the ego first, so the host
vehicle is 1), stable for a whole case whether or not the agent is on the road yet; lane i
of ``world.view().lanes`` is ``LANE_ID0 + i`` and its right and left boundaries are
``BOUNDARY_ID0 + 2i`` and ``+ 2i + 1``; traffic light k (the world's lights by signal id)
is ``LIGHT_ID0 + k``, its state in ``classification.color``, its stop positions in the
Reset (OSI's TrafficLight has no field for them). Names travel in ``source_reference``.

A MotionRequest's desired state is turned into the ego's (acceleration, steering) by the
one-step inverse of highway-env's kinematic bicycle model (:func:`motion_to_action`), and
:func:`action_to_motion` is its exact counterpart for stacks that think in commands; the
round trip is tested. A desired *trajectory* is followed by a tracking controller in
highway-env's style (:func:`trajectory_to_action`): proportional steering toward the path
with its time constants, speed control toward where the trajectory says the ego should be
at each timestamp, with the trajectory's own acceleration fed forward.
"""

from __future__ import annotations

import math
from bisect import bisect_right
from typing import Any

from . import wire

__all__ = ["LANE_ID0", "BOUNDARY_ID0", "LIGHT_ID0", "light_ids", "add_traffic_lights", "HEIGHT_M", "wrap_yaw", "set_object", "object_state",
           "lane_ground_truth", "sensor_view", "SensorViews", "motion_to_action", "action_to_motion",
           "MIN_TURN_SPEED", "trajectory_to_action", "action_to_trajectory", "TAU_ACC", "TAU_HEADING",
           "TAU_LATERAL"]

LANE_ID0 = 10_000
BOUNDARY_ID0 = 20_000
LIGHT_ID0 = 40_000  # traffic light k of the world's lights (sorted by signal id)
MAX_AGENTS = LANE_ID0 - 1  # agent ids stay below the lanes'

#: heights [m] of the boxes OSI wants (the world is flat; z only places the box centre)
HEIGHT_M = {"ego": 1.5, "car": 1.5, "parked": 1.5, "bus": 3.2, "pedestrian": 1.8}

#: [m/s] below this speed a desired yaw change is read as if the vehicle moved this fast: a
#: standing bicycle cannot turn, so without it the steering a stack asks for at a standstill
#: would be lost (it moves nothing in that step; it shows in the recorded command)
MIN_TURN_SPEED = 1e-3

_SOURCE = "pytest-avscenario"


def wrap_yaw(h: float) -> float:
    """``h`` [rad] in [-pi, pi] (unchanged when it already is, so the common case is exact)."""
    if -math.pi <= h <= math.pi:
        return h
    return math.atan2(math.sin(h), math.cos(h))


_OSI: dict[str, Any] = {}


def _osi() -> dict[str, Any]:
    """osi3's generated modules, imported on first use (every step needs them: no import
    statement per call)."""
    if not _OSI:
        from osi3 import (osi_motionrequest_pb2, osi_object_pb2, osi_sensorview_pb2,
                          osi_trafficupdate_pb2)

        _OSI.update(object=osi_object_pb2, sensorview=osi_sensorview_pb2,
                    motionrequest=osi_motionrequest_pb2, trafficupdate=osi_trafficupdate_pb2)
    return _OSI


def _classify(mo: Any, kind: str) -> None:
    o = _osi()["object"]
    if kind == "pedestrian":
        mo.type = o.MovingObject.TYPE_PEDESTRIAN
        return
    mo.type = o.MovingObject.TYPE_VEHICLE
    vc = mo.vehicle_classification
    vc.type = (o.MovingObject.VehicleClassification.TYPE_BUS if kind == "bus"
               else o.MovingObject.VehicleClassification.TYPE_MEDIUM_CAR)


def set_object(mo: Any, osi_id: int, name: str, kind: str, x: float, y: float, heading: float,
               speed: float, length: float, width: float, acceleration: float = 0.0,
               lane_id: int | None = None, flags: dict | None = None) -> None:
    """Fill an ``osi3.MovingObject`` from one agent's state in the world frame.

    ``acceleration`` [m/s^2] is along the heading (the command of the last step);
    ``flags`` (e.g. a bus's stop arm) travel as ``key=value`` identifiers of a second
    source reference, since OSI has no field for them.
    """
    mo.id.value = osi_id
    b = mo.base
    height = HEIGHT_M.get(kind, 1.5)
    b.dimension.length, b.dimension.width, b.dimension.height = length, width, height
    c, s = math.cos(heading), math.sin(heading)
    b.position.x, b.position.y, b.position.z = x, y, 0.5 * height
    b.orientation.yaw = wrap_yaw(heading)
    b.orientation.pitch = b.orientation.roll = 0.0
    b.velocity.x, b.velocity.y, b.velocity.z = speed * c, speed * s, 0.0
    b.acceleration.x, b.acceleration.y, b.acceleration.z = acceleration * c, acceleration * s, 0.0
    _classify(mo, kind)
    if lane_id is not None:
        mo.assigned_lane_id.add().value = lane_id
    ref = mo.source_reference.add()
    ref.reference, ref.type = _SOURCE, "agent"
    ref.identifier.extend([name, kind])
    if flags:
        extra = mo.source_reference.add()
        extra.reference, extra.type = _SOURCE, "flags"
        extra.identifier.extend(f"{k}={str(v).lower()}" for k, v in sorted(flags.items()))


def object_state(mo: Any) -> dict[str, float]:
    """The world-frame state of an ``osi3.MovingObject``: x, y [m], heading [rad], speed
    [m/s] (signed: negative when moving against the heading), vx, vy [m/s], length, width [m]."""
    b = mo.base
    yaw = b.orientation.yaw
    vx, vy = b.velocity.x, b.velocity.y
    speed = math.hypot(vx, vy)
    if vx * math.cos(yaw) + vy * math.sin(yaw) < 0.0:
        speed = -speed
    return {"x": b.position.x, "y": b.position.y, "heading": yaw, "speed": speed,
            "vx": vx, "vy": vy, "length": b.dimension.length, "width": b.dimension.width}


def object_flags(mo: Any) -> dict[str, bool]:
    """The ``key=value`` flags :func:`set_object` stored (values ``true``/``false``)."""
    out = {}
    for ref in mo.source_reference:
        if ref.type == "flags":
            for item in ref.identifier:
                k, _, v = item.partition("=")
                out[k] = v == "true"
    return out


def lane_ground_truth(view: Any) -> bytes:
    """A serialized ``osi3.SensorView`` holding only the lanes and lane boundaries of a
    :class:`~pytest_avscenario.sim.view.SceneView`: static for a case, so it is built once
    and appended to the case's first SensorView (protobuf merges concatenated messages:
    repeated fields append, so the receiver parses one SensorView with everything)."""
    from osi3 import osi_lane_pb2 as L
    from osi3 import osi_sensorview_pb2 as S

    sv = S.SensorView()
    gt = sv.global_ground_truth
    ids = {lane.id: LANE_ID0 + i for i, lane in enumerate(view.lanes)}
    groups: dict[str, dict[int, int]] = {}
    for i, lane in enumerate(view.lanes):
        if lane.group:
            groups.setdefault(lane.group, {})[lane.number] = ids[lane.id]
    kinds = {"travel": L.Lane.Classification.TYPE_DRIVING,
             "connector": L.Lane.Classification.TYPE_INTERSECTION,
             "parking": L.Lane.Classification.TYPE_NONDRIVING}
    for i, lane in enumerate(view.lanes):
        ol = gt.lane.add()
        ol.id.value = ids[lane.id]
        cl = ol.classification
        cl.type = kinds.get(lane.kind, L.Lane.Classification.TYPE_DRIVING)
        for x, y in lane.centre_line:
            p = cl.centerline.add()
            p.x, p.y, p.z = float(x), float(y), 0.0
        cl.centerline_is_driving_direction = True
        row = groups.get(lane.group, {}) if lane.group else {}
        left, right = row.get(lane.number - 1), row.get(lane.number + 1)
        if left is not None:
            cl.left_adjacent_lane_id.add().value = left
        if right is not None:
            cl.right_adjacent_lane_id.add().value = right
        for succ in lane.successors:
            if succ not in ids:  # a lane left out of this view (an export near the ego's path)
                continue
            pair = cl.lane_pairing.add()
            pair.successor_lane_id.value = ids[succ]
        rb, lb = BOUNDARY_ID0 + 2 * i, BOUNDARY_ID0 + 2 * i + 1
        cl.right_lane_boundary_id.add().value = rb
        cl.left_lane_boundary_id.add().value = lb
        ref = ol.source_reference.add()
        ref.reference, ref.type = _SOURCE, "lane"
        ref.identifier.append(lane.id)
        # boundaries: the centre line offset by half the width, sampled where it is sampled
        n = len(lane.centre_line)
        ss = [lane.length * k / (n - 1) for k in range(n)]
        for bid, side, neighbour in ((rb, -1.0, right), (lb, 1.0, left)):
            ob = gt.lane_boundary.add()
            ob.id.value = bid
            ob.classification.type = (L.LaneBoundary.Classification.TYPE_DASHED_LINE if neighbour
                                      is not None else L.LaneBoundary.Classification.TYPE_SOLID_LINE)
            for s in ss:
                w = lane.width_at(s)
                x, y = lane.position(s, side * 0.5 * w)
                bp = ob.boundary_line.add()
                bp.position.x, bp.position.y, bp.position.z = float(x), float(y), 0.0
    return sv.SerializeToString()


def new_sensor_view(t_ns: int) -> tuple[Any, Any]:
    """An empty ``osi3.SensorView`` at ``t_ns`` and its ``global_ground_truth``: versions,
    timestamps and host vehicle id (1) set, no objects yet."""
    sv = _osi()["sensorview"].SensorView()
    wire.set_version(sv.version)
    wire.set_timestamp(sv.timestamp, t_ns)
    sv.host_vehicle_id.value = 1
    gt = sv.global_ground_truth
    wire.set_version(gt.version)
    wire.set_timestamp(gt.timestamp, t_ns)
    gt.host_vehicle_id.value = 1
    return sv, gt


def light_ids(lights: Any) -> dict[str, int]:
    """The OSI id of every traffic light of a :class:`~..sim.signals.TrafficLights`."""
    return {sid: LIGHT_ID0 + k for k, sid in enumerate(sorted(lights.controller_of))}


_COLOURS: dict[str, int] = {}


def add_traffic_lights(gt: Any, lights: Any, t: float, lane_ids: dict[str, int]) -> None:
    """Append every traffic light of ``lights`` in its state at ``t`` [s] to the
    ``osi3.GroundTruth`` ``gt``: its head's position and yaw, the colour of its lit lamp, the
    OSI ids of the lanes it stops (``lane_ids``: lane name -> OSI id) and its signal id."""
    from osi3 import osi_trafficlight_pb2 as TL

    C = TL.TrafficLight.Classification
    colour = {"green": C.COLOR_GREEN, "amber": C.COLOR_YELLOW, "red": C.COLOR_RED}
    for sid, osi_id in light_ids(lights).items():
        sg = lights.lights[sid]
        tl = gt.traffic_light.add()
        tl.id.value = osi_id
        b = tl.base
        b.dimension.length, b.dimension.width, b.dimension.height = 0.3, 0.3, 1.0
        b.position.x, b.position.y, b.position.z = float(sg.x), float(sg.y), 4.5
        b.orientation.yaw = wrap_yaw(float(sg.heading))
        cl = tl.classification
        cl.color = colour[lights.state(sid, t)]
        cl.icon = C.ICON_NONE
        cl.mode = C.MODE_CONSTANT
        for p in sg.stops:
            if p.lane in lane_ids:
                cl.assigned_lane_id.add().value = lane_ids[p.lane]
        ref = tl.source_reference.add()
        ref.reference, ref.type = _SOURCE, "signal"
        ref.identifier.append(sid)


def sensor_view(world: Any, t_ns: int, static: bytes, ids: dict) -> bytes:
    """The serialized ``osi3.SensorView`` of ``world`` now: header, host vehicle id (1),
    every agent on the road (``ids``: agent -> OSI id), and the case's lanes ``static``
    (:func:`lane_ground_truth`). Built afresh: the first SensorView of a case;
    :class:`SensorViews` gives it and then the same bytes without the lanes at less cost."""
    return SensorViews(static, ids).build(world, t_ns)


def _mover_key(a: Any, lanes: Any, code: Any) -> tuple:
    """What of a mover is set only when its ``MovingObject`` is made: the agent, its lane
    (OSI id or None) and its flags; and the lane index it was read from."""
    li = a.lane_index
    return (a, LANE_ID0 + code[li] if li in lanes else None,
            bool(a.stop_arm) if a.kind == "bus" else None, li)


def _same_movers(movers: list, keys: list) -> bool:
    """True when ``movers`` are those of ``keys`` in the same lanes (the very lane index
    objects the lane tracker keeps: no lookup) with the same flags."""
    if len(movers) != len(keys):
        return False
    for a, (k, _, arm, li) in zip(movers, keys):
        if a is not k or a.lane_index is not li or (arm is not None and bool(a.stop_arm) != arm):
            return False
    return True


class SensorViews:
    """The serialized SensorViews of one case, step after step, from one ``osi3.SensorView``
    kept between steps: while the same agents are on the road in the same lanes (with the
    same flags), only the timestamps and each agent's position, yaw, velocity and
    acceleration are written into it; otherwise it is built again with :func:`set_object`.
    The bytes are those a fresh build gives (protobuf serializes fields in number order,
    whatever order they were set in; tested), at a quarter of the cost.

    The case's lanes (``static``) follow the first SensorView only (avs-osi/1 revision 2:
    they do not change within a case, and on a large map they are megabytes a step)."""

    def __init__(self, static: bytes, ids: dict) -> None:
        self.static = static
        self.ids = ids
        self._keys: list = []
        self._index: Any = None  # the world's lane index the keys were read with
        self._sv: Any = None
        self._stamps: tuple = ()
        self._slots: list = []  # per mover: (position, orientation, velocity, acceleration)
        self._first = True  # the lanes not sent yet
        self._light_lanes: dict | None = None  # lane name -> OSI id, for the lights' lanes

    def build(self, world: Any, t_ns: int) -> bytes:
        index = world.lane_index
        lanes, code = index.lanes, index.code
        movers = world.movers
        fresh = False
        if self._sv is None or index is not self._index or not _same_movers(movers, self._keys):
            keys = [_mover_key(a, lanes, code) for a in movers]
            self._index = index
            if self._sv is None or keys != self._keys:
                self._fresh(keys, t_ns)
                fresh = True
            else:
                self._keys = keys
        if not fresh:
            sec, nanos = divmod(int(t_ns), 1_000_000_000)
            for ts in self._stamps:
                ts.seconds, ts.nanos = sec, nanos
        for a, (pos, ori, vel, acc) in zip(movers, self._slots):
            p = a.position
            h, v = float(a.heading), float(a.speed)
            action = a.action if getattr(a, "action", None) else {}
            u = float(action.get("acceleration", 0.0))
            c, s = math.cos(h), math.sin(h)
            pos.x, pos.y = float(p[0]), float(p[1])
            ori.yaw = h if -math.pi <= h <= math.pi else wrap_yaw(h)
            vel.x, vel.y = v * c, v * s
            acc.x, acc.y = u * c, u * s
        lights = world.traffic_lights
        if lights is not None:  # every light in its state now (they change within a case)
            gt = self._sv.global_ground_truth
            del gt.traffic_light[:]
            if self._light_lanes is None:
                self._light_lanes = {l.id: LANE_ID0 + code[l.index] for l in index.order}
            add_traffic_lights(gt, lights, world.t, self._light_lanes)
        if self._first:
            self._first = False
            return self._sv.SerializeToString() + self.static
        return self._sv.SerializeToString()

    def _fresh(self, keys: list, t_ns: int) -> None:
        sv, gt = new_sensor_view(t_ns)
        slots = []
        for a, lane_id, stop_arm, _ in keys:
            mo = gt.moving_object.add()
            set_object(mo, self.ids[a], a.name, a.kind, 0.0, 0.0, 0.0, 0.0, float(a.LENGTH),
                       float(a.WIDTH), 0.0, lane_id,
                       {"stop_arm": stop_arm} if stop_arm is not None else None)
            b = mo.base
            slots.append((b.position, b.orientation, b.velocity, b.acceleration))
        self._sv, self._keys, self._slots = sv, keys, slots
        self._stamps = (sv.timestamp, gt.timestamp)


# -- motion requests --------------------------------------------------------------------------
def _horizon(t_ns: int, ds_ns: int | None, dt: float) -> float:
    """[s] from now to the desired state: the world's step ``dt`` itself when the desired
    timestamp is one step ahead (so a command round-trips exactly), else the difference."""
    step_ns = wire.ns(dt)
    if ds_ns is None or ds_ns - t_ns == step_ns:
        return dt
    return (ds_ns - t_ns) * 1e-9


def motion_to_action(ds: Any, t_ns: int, heading: float, speed: float, length: float,
                     dt: float) -> tuple[float, float]:
    """(acceleration [m/s^2], steering [rad]) that take the ego to the desired state ``ds``
    (an ``osi3.MotionRequest.DesiredState``) of a stack, by the one-step inverse of the
    kinematic bicycle model: the speed changes at the desired acceleration's component along
    the heading (or, without one, by the desired velocity's change over the horizon), the
    yaw turns to ``ds.orientation.yaw`` over the horizon. ``ValueError`` names a missing or
    non-finite field. The horizon is ``ds.timestamp - now`` (default one step)."""
    if not ds.HasField("orientation"):
        raise ValueError("desired_state has no orientation (the yaw to steer to)")
    ds_ns = wire.timestamp_ns(ds.timestamp) if ds.HasField("timestamp") else None
    if ds_ns is not None and ds_ns <= t_ns:
        raise ValueError(f"desired_state.timestamp {ds_ns} ns is not after the request's {t_ns} ns")
    T = _horizon(t_ns, ds_ns, dt)
    c, s = math.cos(heading), math.sin(heading)
    if ds.HasField("acceleration"):
        acc = ds.acceleration.x * c + ds.acceleration.y * s
    elif ds.HasField("velocity"):
        v_d = ds.velocity.x * c + ds.velocity.y * s
        acc = (v_d - speed) / T
    else:
        raise ValueError("desired_state has neither acceleration nor velocity")
    yaw = ds.orientation.yaw
    if not (math.isfinite(acc) and math.isfinite(yaw)):
        raise ValueError(f"non-finite desired state (acceleration {acc!r}, yaw {yaw!r})")
    turn = math.atan2(math.sin(yaw - heading), math.cos(yaw - heading))
    if -math.pi < yaw - heading < math.pi:
        turn = yaw - heading  # exact when no wrapping is needed
    v_ref = speed if abs(speed) >= MIN_TURN_SPEED else math.copysign(MIN_TURN_SPEED, speed or 1.0)
    sin_beta = max(-1.0, min(1.0, turn / T * (0.5 * length) / v_ref))
    steering = math.atan(2.0 * math.tan(math.asin(sin_beta)))
    return acc, steering


def desired_state_slots(mr: Any) -> tuple:
    """The sub-messages of ``mr.desired_state`` that :func:`action_to_motion` writes
    (timestamp, orientation, position, velocity, acceleration), for a caller that keeps one
    MotionRequest and fills it each step."""
    ds = mr.desired_state
    return ds.timestamp, ds.orientation, ds.position, ds.velocity, ds.acceleration


def action_to_motion(mr: Any, t_ns: int, x: float, y: float, heading: float, speed: float,
                     length: float, dt: float, acceleration: float, steering: float,
                     slots: tuple | None = None) -> None:
    """Fill ``mr`` (an ``osi3.MotionRequest``) with the desired state one step ahead that
    (acceleration, steering) would reach: :func:`motion_to_action`'s exact counterpart.
    ``slots``: :func:`desired_state_slots` of ``mr``, when the caller keeps them."""
    mr.motion_request_type = _osi()["motionrequest"].MotionRequest.MOTION_REQUEST_TYPE_DESIRED_STATE
    ts, ori, pos, vel, acc = slots if slots is not None else desired_state_slots(mr)
    ts.seconds, ts.nanos = divmod(t_ns + wire.ns(dt), 1_000_000_000)
    beta = math.atan(0.5 * math.tan(steering))
    v_ref = speed if abs(speed) >= MIN_TURN_SPEED else math.copysign(MIN_TURN_SPEED, speed or 1.0)
    yaw = heading + v_ref * math.sin(beta) / (0.5 * length) * dt
    ori.yaw = yaw if -math.pi <= yaw <= math.pi and -math.pi <= heading <= math.pi \
        else wrap_yaw(yaw)
    pos.x = x + speed * math.cos(heading + beta) * dt
    pos.y = y + speed * math.sin(heading + beta) * dt
    v1 = speed + acceleration * dt
    vel.x, vel.y = v1 * math.cos(yaw), v1 * math.sin(yaw)
    c, s = math.cos(heading), math.sin(heading)
    acc.x, acc.y = acceleration * c, acceleration * s


# -- desired trajectories ---------------------------------------------------------------------
#: highway-env's ControlledVehicle time constants [s], used to follow a desired trajectory:
#: speed error closed in TAU_ACC, heading error in TAU_HEADING, lateral error in TAU_LATERAL
TAU_ACC = 0.6
TAU_HEADING = 0.2
TAU_LATERAL = 0.6
TAU_PURSUIT = 0.5 * TAU_HEADING  # [s] look-ahead along the path for the heading to follow
#: [1/s^2] along-track position gain (critically damped with the speed gain 1/TAU_ACC)
KP_ALONG = 1.0 / (4.0 * TAU_ACC * TAU_ACC)
MAX_TRAJECTORY_POINTS = 10_000


def _trajectory_points(traj: Any, t_ns: int) -> list[tuple[float, float, float, float | None]]:
    """``(tau [s after now], x, y, yaw or None)`` of each point of an
    ``osi3.MotionRequest.DesiredTrajectory``; ``ValueError`` naming the first bad point."""
    pts = traj.trajectory_point
    if len(pts) == 0:
        raise ValueError("desired_trajectory has no trajectory_point")
    if len(pts) > MAX_TRAJECTORY_POINTS:
        raise ValueError(f"desired_trajectory has {len(pts)} points (at most {MAX_TRAJECTORY_POINTS})")
    out: list[tuple[float, float, float, float | None]] = []
    last_ns = None
    for i, p in enumerate(pts):
        if not p.HasField("timestamp"):
            raise ValueError(f"trajectory_point[{i}] has no timestamp")
        if not p.HasField("position"):
            raise ValueError(f"trajectory_point[{i}] has no position")
        p_ns = wire.timestamp_ns(p.timestamp)
        x, y = p.position.x, p.position.y
        if not (math.isfinite(x) and math.isfinite(y)):
            raise ValueError(f"trajectory_point[{i}] has a non-finite position (x={x!r}, y={y!r})")
        yaw = p.orientation.yaw if p.HasField("orientation") else None
        if yaw is not None and not math.isfinite(yaw):
            raise ValueError(f"trajectory_point[{i}] has a non-finite orientation.yaw ({yaw!r})")
        if p_ns < t_ns:
            raise ValueError(f"trajectory_point[{i}].timestamp {p_ns} ns ({p_ns * 1e-9:.3f} s) is in "
                             f"the past: the request's is {t_ns} ns ({t_ns * 1e-9:.3f} s)")
        if last_ns is not None and p_ns <= last_ns:
            raise ValueError(f"trajectory_point[{i}].timestamp {p_ns} ns is not after "
                             f"trajectory_point[{i - 1}]'s {last_ns} ns (timestamps must increase)")
        last_ns = p_ns
        out.append(((p_ns - t_ns) * 1e-9, x, y, yaw))
    if last_ns is not None and last_ns <= t_ns:
        raise ValueError(f"desired_trajectory ends at the request's timestamp {t_ns} ns: it needs "
                         "a point after it")
    return out


def trajectory_to_action(traj: Any, t_ns: int, x: float, y: float, heading: float, speed: float,
                         length: float, dt: float) -> tuple[float, float]:
    """(acceleration [m/s^2], steering [rad]) that follow a desired trajectory (an
    ``osi3.MotionRequest.DesiredTrajectory``: points of position, timestamp and optionally
    yaw) for one step of ``dt`` [s] from the ego's state now (request time ``t_ns``).

    The points are a path timed by their timestamps (a first point after now is joined to
    the ego's position now). Steering is highway-env's lane-following law with the path in
    place of the lane: the lateral offset from the path closed in TAU_LATERAL, the path's
    heading TAU_PURSUIT·speed ahead reached in TAU_HEADING, through the bicycle model's slip.
    Acceleration is the path's own (its speed change over the coming step, fed forward),
    plus the speed error closed in TAU_ACC, plus the along-path position error (where the
    timestamps say the ego should be now against where it is) with gain KP_ALONG. So a
    trajectory that starts at the ego's state and accelerates at a constant rate is followed
    at that rate. ``ValueError`` names a bad point: none, non-finite, missing fields,
    timestamps in the past or not increasing."""
    pts = _trajectory_points(traj, t_ns)
    if pts[0][0] > 0.0:
        pts.insert(0, (0.0, x, y, None))
    taus = [p[0] for p in pts]
    n = len(pts)
    # arc length at each point, and the path's heading along each segment
    cum = [0.0]
    seg_heading: list[float | None] = []
    for (_, x0, y0, _), (_, x1, y1, _) in zip(pts, pts[1:]):
        d = math.hypot(x1 - x0, y1 - y0)
        cum.append(cum[-1] + d)
        seg_heading.append(math.atan2(y1 - y0, x1 - x0) if d > 1e-9 else None)
    # the ego's place on the path: the nearest point of the nearest segment
    best = (math.inf, 0.0, 0.0, 0)  # distance^2, s, lateral, segment
    for i in range(n - 1):
        _, x0, y0, _ = pts[i]
        _, x1, y1, _ = pts[i + 1]
        sx, sy = x1 - x0, y1 - y0
        seg = cum[i + 1] - cum[i]
        ex, ey = x - x0, y - y0
        # on the first and last segments the path extends beyond its ends: an ego behind the
        # first point (or past the last) is that far behind (or ahead), not on it
        lo = -math.inf if i == 0 else 0.0
        hi = math.inf if i == n - 2 else seg
        u = 0.0 if seg <= 1e-9 else min(max((ex * sx + ey * sy) / seg, lo), hi)
        h = seg_heading[i]
        c, s = (math.cos(h), math.sin(h)) if h is not None else (1.0, 0.0)
        px, py = ex - u * c, ey - u * s
        d2 = px * px + py * py
        if d2 < best[0]:
            lateral = (ey * c - ex * s) if h is not None else 0.0
            best = (d2, cum[i] + u, lateral, i)
    _, s_ego, lateral, _ = best

    def path_heading(s_at: float) -> float:
        # the heading of the segment at arc length s_at (zero-length ones skipped); a path
        # of no length (a stop) has its points' yaw, or the ego's heading
        for i in range(n - 1):
            if seg_heading[i] is not None and cum[i + 1] >= s_at:
                return seg_heading[i]  # type: ignore[return-value]
        moving = [h for h in seg_heading if h is not None]
        if moving:
            return moving[-1]
        yaws = [p[3] for p in pts if p[3] is not None]
        return yaws[-1] if yaws else heading

    # speeds at the points: central differences inside, linear extrapolation at the ends
    seg_v = [(cum[i + 1] - cum[i]) / (taus[i + 1] - taus[i]) for i in range(n - 1)]
    if n == 2:
        knot_v = [seg_v[0], seg_v[0]]
    else:
        knot_v = [0.0] * n
        for i in range(1, n - 1):
            knot_v[i] = 0.5 * (seg_v[i - 1] + seg_v[i])
        knot_v[0] = 2.0 * seg_v[0] - knot_v[1]
        knot_v[-1] = 2.0 * seg_v[-1] - knot_v[-2]

    def at(tau: float) -> tuple[float, float]:
        """(arc length [m], speed [m/s]) the trajectory asks for at ``tau`` s from now:
        standing at its last point once it has ended."""
        if tau >= taus[-1]:
            return cum[-1], 0.0
        i = max(0, bisect_right(taus, tau) - 1)
        w = (tau - taus[i]) / (taus[i + 1] - taus[i])
        return cum[i] + w * (cum[i + 1] - cum[i]), knot_v[i] + w * (knot_v[i + 1] - knot_v[i])

    s_now, v_now = at(0.0)
    _, v_next = at(dt)
    acceleration = (v_next - v_now) / dt + (v_now - speed) / TAU_ACC + KP_ALONG * (s_now - s_ego)
    # steering: highway-env's ControlledVehicle.steering_control, the path as its lane
    v_ref = speed if abs(speed) > 1e-2 else math.copysign(1e-2, speed or 1.0)
    future = path_heading(s_ego + max(speed, 0.0) * TAU_PURSUIT)
    lateral_speed = -lateral / TAU_LATERAL
    heading_cmd = math.asin(max(-1.0, min(1.0, lateral_speed / v_ref)))
    heading_ref = future + max(-math.pi / 4, min(math.pi / 4, heading_cmd))
    turn = math.atan2(math.sin(heading_ref - heading), math.cos(heading_ref - heading))
    slip = math.asin(max(-1.0, min(1.0, 0.5 * length / v_ref * turn / TAU_HEADING)))
    steering = math.atan(2.0 * math.tan(slip))
    return acceleration, steering


def action_to_trajectory(mr: Any, t_ns: int, x: float, y: float, heading: float, speed: float,
                         length: float, dt: float, acceleration: float, steering: float,
                         steps: int = 10) -> None:
    """Fill ``mr`` with a desired trajectory: where the ego goes in ``steps`` steps of ``dt``
    holding (acceleration, steering), by the kinematic bicycle model in continuous time
    (each step at the mean of its speeds, which is how a planner's timed points read; the
    speed bounded below by 0: a braking vehicle stops and stays). The first point is the ego
    now."""
    from osi3 import osi_motionrequest_pb2 as M

    mr.motion_request_type = M.MotionRequest.MOTION_REQUEST_TYPE_TRAJECTORY
    points = mr.desired_trajectory.trajectory_point
    step_ns = wire.ns(dt)
    beta = math.atan(0.5 * math.tan(steering))
    for k in range(steps + 1):
        p = points.add()
        wire.set_timestamp(p.timestamp, t_ns + k * step_ns)
        p.position.x, p.position.y, p.position.z = x, y, 0.0
        p.orientation.yaw = wrap_yaw(heading)
        after = max(speed + acceleration * dt, 0.0) if speed >= 0.0 else speed + acceleration * dt
        mean = 0.5 * (speed + after)
        x += mean * math.cos(heading + beta) * dt
        y += mean * math.sin(heading + beta) * dt
        heading += mean * math.sin(beta) / (0.5 * length) * dt
        speed = after

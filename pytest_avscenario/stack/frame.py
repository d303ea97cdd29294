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
``BOUNDARY_ID0 + 2i`` and ``+ 2i + 1``. Names travel in ``source_reference``.

A MotionRequest's desired state is turned into the ego's (acceleration, steering) by the
one-step inverse of highway-env's kinematic bicycle model (:func:`motion_to_action`), and
:func:`action_to_motion` is its exact counterpart for stacks that think in commands; the
round trip is tested.
"""

from __future__ import annotations

import math
from typing import Any

from . import wire

__all__ = ["LANE_ID0", "BOUNDARY_ID0", "HEIGHT_M", "wrap_yaw", "set_object", "object_state",
           "lane_ground_truth", "sensor_view", "motion_to_action", "action_to_motion",
           "MIN_TURN_SPEED"]

LANE_ID0 = 10_000
BOUNDARY_ID0 = 20_000
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
        from osi3 import osi_object_pb2, osi_sensorview_pb2

        _OSI.update(object=osi_object_pb2, sensorview=osi_sensorview_pb2)
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
    and appended to every step's message (protobuf merges concatenated messages: repeated
    fields append, so the receiver parses one SensorView with everything)."""
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


def sensor_view(world: Any, t_ns: int, static: bytes, ids: dict) -> bytes:
    """The serialized ``osi3.SensorView`` of ``world`` now: header, host vehicle id (1),
    every agent on the road (``ids``: agent -> OSI id), and the case's lanes ``static``
    (:func:`lane_ground_truth`)."""
    sv = _osi()["sensorview"].SensorView()
    wire.set_version(sv.version)
    wire.set_timestamp(sv.timestamp, t_ns)
    sv.host_vehicle_id.value = 1
    gt = sv.global_ground_truth
    wire.set_version(gt.version)
    wire.set_timestamp(gt.timestamp, t_ns)
    gt.host_vehicle_id.value = 1
    index = world.lane_index
    lanes = index.lanes
    code = index.code
    for a in world.movers:
        action = getattr(a, "action", None) or {}
        li = a.lane_index
        set_object(gt.moving_object.add(), ids[a], a.name, a.kind, float(a.position[0]),
                   float(a.position[1]), float(a.heading), float(a.speed), float(a.LENGTH),
                   float(a.WIDTH), float(action.get("acceleration", 0.0)),
                   LANE_ID0 + code[li] if li in lanes else None,
                   {"stop_arm": bool(a.stop_arm)} if a.kind == "bus" else None)
    return sv.SerializeToString() + static


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


def action_to_motion(mr: Any, t_ns: int, x: float, y: float, heading: float, speed: float,
                     length: float, dt: float, acceleration: float, steering: float) -> None:
    """Fill ``mr`` (an ``osi3.MotionRequest``) with the desired state one step ahead that
    (acceleration, steering) would reach: :func:`motion_to_action`'s exact counterpart."""
    from osi3 import osi_motionrequest_pb2 as M

    mr.motion_request_type = M.MotionRequest.MOTION_REQUEST_TYPE_DESIRED_STATE
    ds = mr.desired_state
    wire.set_timestamp(ds.timestamp, t_ns + wire.ns(dt))
    beta = math.atan(0.5 * math.tan(steering))
    v_ref = speed if abs(speed) >= MIN_TURN_SPEED else math.copysign(MIN_TURN_SPEED, speed or 1.0)
    yaw = heading + v_ref * math.sin(beta) / (0.5 * length) * dt
    ds.orientation.yaw = yaw if -math.pi <= yaw <= math.pi and -math.pi <= heading <= math.pi \
        else wrap_yaw(yaw)
    ds.position.x = x + speed * math.cos(heading + beta) * dt
    ds.position.y = y + speed * math.sin(heading + beta) * dt
    v1 = speed + acceleration * dt
    ds.velocity.x, ds.velocity.y = v1 * math.cos(yaw), v1 * math.sin(yaw)
    c, s = math.cos(heading), math.sin(heading)
    ds.acceleration.x, ds.acceleration.y = acceleration * c, acceleration * s

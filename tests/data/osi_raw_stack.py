"""A stack written from docs/osi-protocol.md alone: pyzmq and osi3, nothing of pytest-avscenario.

    python osi_raw_stack.py ADDRESS [--answer motion|traffic|trajectory] [--speed V] [--to-y Y]
                            [--fault KIND --case-suffix SUFFIX --at-step N]

It drives the host vehicle straight along its heading towards the speed V [m/s]: with
``motion`` it sends MotionRequests (desired state one step ahead), with ``traffic`` it moves
the vehicle itself and sends TrafficUpdates. With ``trajectory`` it sends MotionRequests
with a desired trajectory of 2 s (a point every step) along +x, its speed closing on V, its
y moving smoothly to Y (default: staying where it is). ``--fault`` misbehaves on purpose in the case
whose name ends with SUFFIX, at step N: ``hang`` (never answers), ``crash`` (exits with code
3), ``timestamp`` (answers one step late), ``error`` (an Error answer), ``garbage`` (unparseable bytes), ``type`` (a
wrong message type), ``teleport`` (a TrafficUpdate 20 m away), ``nan`` (a NaN position); ``handshake`` answers that case's Reset with revision 1 at dt 0.05;
with ``trajectory``: ``empty`` (no points), ``past`` (the first point one step before the
request), ``nan`` (a NaN point).
"""

import argparse
import json
import math
import os
import sys
import time

import zmq
from osi3 import osi_motionrequest_pb2, osi_sensorview_pb2, osi_trafficupdate_pb2, osi_version_pb2

PROTOCOL = b"avs-osi/1"


def version() -> str:
    v = osi_version_pb2.DESCRIPTOR.GetOptions().Extensions[osi_version_pb2.current_interface_version]
    return f"{v.version_major}.{v.version_minor}.{v.version_patch}"


def main() -> None:
    p = argparse.ArgumentParser()
    p.add_argument("address")
    p.add_argument("--answer", default="motion", choices=["motion", "traffic", "trajectory"])
    p.add_argument("--speed", type=float, default=10.0)
    p.add_argument("--to-y", type=float, default=None)
    p.add_argument("--fault", default="")
    p.add_argument("--case-suffix", default="")
    p.add_argument("--at-step", type=int, default=3)
    args = p.parse_args()
    sock = zmq.Context.instance().socket(zmq.REP)
    sock.bind(args.address)
    case, dt, host, step = "", 0.1, 1, 0
    while True:
        proto, kind, body = sock.recv_multipart()
        assert proto == PROTOCOL, proto
        if kind == b"Reset":
            hello = json.loads(body)
            case, dt, host, step = hello["case"], hello["dt"], hello["host_vehicle_id"], 0
            wrong = args.fault == "handshake" and case.endswith(args.case_suffix)
            sock.send_multipart([PROTOCOL, b"Ready", json.dumps({
                "protocol": "avs-osi/1", "revision": 1 if wrong else 2, "osi_version": version(),
                "dt": 0.05 if wrong else dt, "host_vehicle_id": host}).encode()])
            continue
        sv = osi_sensorview_pb2.SensorView()
        sv.ParseFromString(body)
        me = next(mo for mo in sv.global_ground_truth.moving_object if mo.id.value == host)
        faulty = args.fault and case.endswith(args.case_suffix) and step == args.at_step
        step += 1
        if faulty and args.fault == "hang":
            time.sleep(3600)
        if faulty and args.fault == "crash":
            os._exit(3)
        if faulty and args.fault == "error":
            sock.send_multipart([PROTOCOL, b"Error", b"planner failed: no trajectory found"])
            continue
        if faulty and args.fault == "huge":  # 65 MiB, past the plugin's 64 MiB a message
            sock.send_multipart([PROTOCOL, b"MotionRequest", bytes(65 << 20)])
            continue
        if faulty and args.fault == "garbage":
            sock.send_multipart([PROTOCOL, b"MotionRequest" if args.answer == "motion"
                                 else b"TrafficUpdate", b"\xff\xff\xff\xff"])
            continue
        ts = sv.timestamp.seconds * 10**9 + sv.timestamp.nanos
        if faulty and args.fault == "timestamp":
            ts += round(dt * 1e9)
        b = me.base
        yaw = b.orientation.yaw
        v = math.hypot(b.velocity.x, b.velocity.y)
        acc = max(-3.0, min(2.0, (args.speed - v) / 1.0))
        v1 = v + acc * dt
        if args.answer == "trajectory":
            out = osi_motionrequest_pb2.MotionRequest()
            out.timestamp.seconds, out.timestamp.nanos = divmod(ts, 10**9)
            out.motion_request_type = osi_motionrequest_pb2.MotionRequest.MOTION_REQUEST_TYPE_TRAJECTORY
            to_y = b.position.y if args.to_y is None else args.to_y
            x, speed = b.position.x, v
            step_ns = round(dt * 1e9)
            for k in range(0 if faulty and args.fault == "empty" else 21):
                tau = k * dt
                pt = out.desired_trajectory.trajectory_point.add()
                pt_ns = ts + k * step_ns - (step_ns if faulty and args.fault == "past" else 0)
                pt.timestamp.seconds, pt.timestamp.nanos = divmod(pt_ns, 10**9)
                pt.position.x = x
                pt.position.y = to_y + (b.position.y - to_y) * math.exp(-tau / 1.5)
                if faulty and args.fault == "nan" and k == 5:
                    pt.position.y = float("nan")
                a_k = max(-3.0, min(2.0, (args.speed - speed) / 1.0))
                after = speed + a_k * dt
                x += 0.5 * (speed + after) * dt
                speed = after
            name = b"MotionRequest"
        elif args.answer == "motion":
            out = osi_motionrequest_pb2.MotionRequest()
            out.timestamp.seconds, out.timestamp.nanos = divmod(ts, 10**9)
            out.motion_request_type = osi_motionrequest_pb2.MotionRequest.MOTION_REQUEST_TYPE_DESIRED_STATE
            ds = out.desired_state
            ds.timestamp.seconds, ds.timestamp.nanos = divmod(ts + round(dt * 1e9), 10**9)
            ds.position.x = b.position.x + v * math.cos(yaw) * dt
            ds.position.y = b.position.y + v * math.sin(yaw) * dt
            ds.orientation.yaw = yaw
            ds.velocity.x, ds.velocity.y = v1 * math.cos(yaw), v1 * math.sin(yaw)
            ds.acceleration.x, ds.acceleration.y = acc * math.cos(yaw), acc * math.sin(yaw)
            name = b"MotionRequest"
        else:
            out = osi_trafficupdate_pb2.TrafficUpdate()
            out.timestamp.seconds, out.timestamp.nanos = divmod(ts, 10**9)
            mo = out.update.add()
            mo.id.value = host
            mo.base.position.x = b.position.x + v * math.cos(yaw) * dt
            mo.base.position.y = b.position.y + v * math.sin(yaw) * dt
            mo.base.position.z = b.position.z
            if faulty and args.fault == "teleport":
                mo.base.position.x += 20.0
            if faulty and args.fault == "nan":
                mo.base.position.y = float("nan")
            mo.base.orientation.yaw = yaw
            mo.base.velocity.x, mo.base.velocity.y = v1 * math.cos(yaw), v1 * math.sin(yaw)
            name = b"TrafficUpdate"
        if faulty and args.fault == "type":
            name = b"SensorView"
        sock.send_multipart([PROTOCOL, name, out.SerializeToString()])


if __name__ == "__main__":
    sys.exit(main())

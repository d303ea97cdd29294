"""A ROS 2 bridge for avs-osi/1: a ROS 2 stack drives the ego of pytest-avscenario's cases.

Runs under the ROS 2 Python of the stack under test (Humble's 3.10, Jazzy's 3.12, …), not
the plugin's: it imports nothing of pytest-avscenario, only ``rclpy``, the message packages,
``pyzmq``, ``osi3`` (``pip install osi-python pyzmq pyyaml`` in that environment) and
``yaml``. On one side it is an avs-osi/1 stack (docs/osi-protocol.md: a ZeroMQ REP socket,
OSI messages, lockstep); on the other, for every step of a case, it publishes

* ``/clock`` (``rosgraph_msgs/Clock``): the simulation time (run the stack with
  ``use_sim_time:=true``);
* the ego (``nav_msgs/Odometry``, frame ``map``, child ``base_link``): position, yaw,
  speed along its heading, yaw rate since the last step;
* the other agents as an object list (``visualization_msgs/MarkerArray``, one CUBE per
  agent: ``id`` its OSI id, ``ns`` its kind, ``text`` its name, pose, size; or
  ``geometry_msgs/PoseArray``): everything on the road, the ego excepted;

then waits for the stack's control command on the control topic, **stamped with the
simulation time of this step** (``header.stamp`` equal to the ``/clock`` just published; a
message with another stamp is stale and ignored), and answers the plugin with a
MotionRequest whose desired state is one step ahead:

* ``ackermann_msgs/AckermannDriveStamped``: ``drive.steering_angle`` [rad] (front wheel),
  ``drive.speed`` [m/s] the speed to reach, or ``drive.acceleration`` [m/s^2] when not 0;
* ``geometry_msgs/TwistStamped``: ``twist.linear.x`` the speed to reach [m/s],
  ``twist.angular.z`` the yaw rate [rad/s].

No command within ``control_timeout_s`` is answered with an avs-osi ``Error`` naming the
topic and the time (the case is an error; the plugin's own ``--avs-stack-timeout`` must be
longer). Topic names, types and the timeout come from a YAML file (``--topics``)::

    clock: /clock
    odometry: {topic: /avs/ego/odometry}
    objects: {topic: /avs/objects, type: visualization_msgs/MarkerArray}
    control: {topic: /avs/control, type: ackermann_msgs/AckermannDriveStamped}
    control_timeout_s: 2.0

Run it as the plugin's spawned stack, with the ROS Python and this file's path::

    pytest --avs-driver "osi+spawn:/usr/bin/python3 /path/to/ros2_bridge.py {address} --topics ros2.yaml"

(``python -c "import pytest_avscenario.stack as s, os; print(os.path.dirname(s.__file__))"``
prints the folder; the file may also be copied anywhere, it stands alone.)
"""

from __future__ import annotations

import argparse
import importlib
import json
import math
import os
import sys
import time

PROTOCOL = b"avs-osi/1"
REVISION = 2
RESEND_S = 0.5  # [s] while no command answers a step, its messages are published again this often

DEFAULTS = {
    "clock": "/clock",
    "odometry": {"topic": "/avs/ego/odometry"},
    "objects": {"topic": "/avs/objects", "type": "visualization_msgs/MarkerArray"},
    "control": {"topic": "/avs/control", "type": "ackermann_msgs/AckermannDriveStamped"},
    "control_timeout_s": 2.0,
}
CONTROL_TYPES = ("ackermann_msgs/AckermannDriveStamped", "geometry_msgs/TwistStamped")
OBJECT_TYPES = ("visualization_msgs/MarkerArray", "geometry_msgs/PoseArray")


def load_topics(path: str | None) -> dict:
    """The bridge's settings: DEFAULTS updated by the YAML file at ``path``; ValueError names
    an unknown key or message type."""
    cfg = json.loads(json.dumps(DEFAULTS))
    if path:
        import yaml

        with open(path, encoding="utf-8") as fh:
            given = yaml.safe_load(fh) or {}
        if not isinstance(given, dict):
            raise ValueError(f"{path}: expected a mapping of settings, got {type(given).__name__}")
        for key, value in given.items():
            if key not in DEFAULTS:
                raise ValueError(f"{path}: unknown setting {key!r} (known: {', '.join(DEFAULTS)})")
            if isinstance(DEFAULTS[key], dict):
                if isinstance(value, str):
                    value = {"topic": value}
                if not isinstance(value, dict):
                    raise ValueError(f"{path}: {key} must be a topic name or a mapping")
                cfg[key].update(value)
            else:
                cfg[key] = value
    if cfg["control"]["type"] not in CONTROL_TYPES:
        raise ValueError(f"control type {cfg['control']['type']!r}: use one of {', '.join(CONTROL_TYPES)}")
    if cfg["objects"]["type"] not in OBJECT_TYPES:
        raise ValueError(f"objects type {cfg['objects']['type']!r}: use one of {', '.join(OBJECT_TYPES)}")
    cfg["control_timeout_s"] = float(cfg["control_timeout_s"])
    return cfg


def message_class(name: str):
    """The class of a ROS message type ``package/Type``."""
    package, _, kind = name.partition("/")
    return getattr(importlib.import_module(f"{package}.msg"), kind)


def osi_version() -> str:
    from osi3 import osi_version_pb2

    v = osi_version_pb2.DESCRIPTOR.GetOptions().Extensions[osi_version_pb2.current_interface_version]
    return f"{v.version_major}.{v.version_minor}.{v.version_patch}"


def stamp_ns(msg) -> int:
    return int(msg.seconds) * 1_000_000_000 + int(msg.nanos)


def yaw_quaternion(q, yaw: float) -> None:
    q.x, q.y, q.z, q.w = 0.0, 0.0, math.sin(0.5 * yaw), math.cos(0.5 * yaw)


class Bridge:
    """One ROS node and one REP socket; :meth:`answer` turns one request into its answer."""

    def __init__(self, cfg: dict) -> None:
        import rclpy
        from rclpy.node import Node
        from rclpy.qos import QoSProfile, ReliabilityPolicy, HistoryPolicy

        self.rclpy = rclpy
        self.cfg = cfg
        rclpy.init(args=None)
        self.node = Node("avs_osi_bridge")
        qos = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE, history=HistoryPolicy.KEEP_LAST)
        self.Clock = message_class("rosgraph_msgs/Clock")
        self.Odometry = message_class("nav_msgs/Odometry")
        self.Objects = message_class(cfg["objects"]["type"])
        self.Control = message_class(cfg["control"]["type"])
        self.clock_pub = self.node.create_publisher(self.Clock, cfg["clock"], qos)
        self.odom_pub = self.node.create_publisher(self.Odometry, cfg["odometry"]["topic"], qos)
        self.objects_pub = self.node.create_publisher(self.Objects, cfg["objects"]["topic"], qos)
        self.node.create_subscription(self.Control, cfg["control"]["topic"], self._on_control, qos)
        self.pending = {}  # stamp [ns] -> the command stamped so
        self.hello: dict = {}
        self.last_yaw = None

    def _on_control(self, msg) -> None:
        self.pending[msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec] = msg

    def close(self) -> None:
        self.node.destroy_node()
        self.rclpy.shutdown()

    # -- avs-osi/1 ------------------------------------------------------------------------
    def answer(self, frames: list) -> list:
        if len(frames) != 3 or frames[0] != PROTOCOL:
            return [PROTOCOL, b"Error", b"expected 3 frames [avs-osi/1, kind, body]"]
        _, kind, body = frames
        if kind == b"Reset":
            self.hello = json.loads(body)
            self.last_yaw = None
            self.pending.clear()
            return [PROTOCOL, b"Ready", json.dumps({
                "protocol": "avs-osi/1", "revision": REVISION, "osi_version": osi_version(),
                "dt": self.hello["dt"], "host_vehicle_id": self.hello["host_vehicle_id"]}).encode()]
        if kind != b"SensorView":
            return [PROTOCOL, b"Error", b"expected a Reset or a SensorView, got " + bytes(kind[:40])]
        if not self.hello:
            return [PROTOCOL, b"Error", b"SensorView before any Reset"]
        from osi3 import osi_sensorview_pb2

        sv = osi_sensorview_pb2.SensorView()
        sv.ParseFromString(body)
        t_ns = stamp_ns(sv.timestamp)
        ego = self.publish(sv, t_ns)
        command = self.wait_for(t_ns)
        if command is None:
            return [PROTOCOL, b"Error", (
                f"no {self.cfg['control']['type']} stamped {t_ns * 1e-9:.3f} s (the simulation "
                f"time) on {self.cfg['control']['topic']} within {self.cfg['control_timeout_s']:g} s"
            ).encode()]
        return [PROTOCOL, b"MotionRequest", self.motion_request(ego, command, t_ns)]

    def publish(self, sv, t_ns: int):
        """/clock, the ego's odometry and the object list of one SensorView; the ego's OSI object."""
        sec, nanosec = divmod(t_ns, 1_000_000_000)
        clock = self.Clock()
        clock.clock.sec, clock.clock.nanosec = sec, nanosec
        self.clock_pub.publish(clock)
        host = self.hello["host_vehicle_id"]
        kinds = {a["id"]: a for a in self.hello["agents"]}
        ego = None
        objects = self.Objects()
        for mo in sv.global_ground_truth.moving_object:
            b = mo.base
            if mo.id.value == host:
                ego = mo
                continue
            info = kinds.get(mo.id.value, {})
            if self.cfg["objects"]["type"] == "geometry_msgs/PoseArray":
                objects.header.stamp.sec, objects.header.stamp.nanosec = sec, nanosec
                objects.header.frame_id = "map"
                pose = message_class("geometry_msgs/Pose")()
                pose.position.x, pose.position.y, pose.position.z = b.position.x, b.position.y, b.position.z
                yaw_quaternion(pose.orientation, b.orientation.yaw)
                objects.poses.append(pose)
                continue
            marker = message_class("visualization_msgs/Marker")()
            marker.header.stamp.sec, marker.header.stamp.nanosec = sec, nanosec
            marker.header.frame_id = "map"
            marker.ns = info.get("kind", "car")
            marker.id = int(mo.id.value)
            marker.type = marker.CUBE
            marker.action = marker.ADD
            marker.text = info.get("name", str(mo.id.value))
            marker.pose.position.x, marker.pose.position.y = b.position.x, b.position.y
            marker.pose.position.z = b.position.z
            yaw_quaternion(marker.pose.orientation, b.orientation.yaw)
            marker.scale.x, marker.scale.y = b.dimension.length, b.dimension.width
            marker.scale.z = b.dimension.height
            marker.color.r, marker.color.g, marker.color.b, marker.color.a = 0.2, 0.4, 0.9, 1.0
            objects.markers.append(marker)
        if ego is None:
            raise ValueError(f"the SensorView has no host vehicle (id {host})")
        b = ego.base
        yaw = b.orientation.yaw
        speed = b.velocity.x * math.cos(yaw) + b.velocity.y * math.sin(yaw)
        odom = self.Odometry()
        odom.header.stamp.sec, odom.header.stamp.nanosec = sec, nanosec
        odom.header.frame_id, odom.child_frame_id = "map", "base_link"
        odom.pose.pose.position.x, odom.pose.pose.position.y = b.position.x, b.position.y
        yaw_quaternion(odom.pose.pose.orientation, yaw)
        odom.twist.twist.linear.x = speed  # in the child frame: along the heading
        dt = float(self.hello["dt"])
        if self.last_yaw is not None:
            turn = math.atan2(math.sin(yaw - self.last_yaw), math.cos(yaw - self.last_yaw))
            odom.twist.twist.angular.z = turn / dt
        self.last_yaw = yaw
        self.odom_pub.publish(odom)
        self.objects_pub.publish(objects)
        self.last_sent = ((self.clock_pub, clock), (self.odom_pub, odom), (self.objects_pub, objects))
        return ego

    def wait_for(self, t_ns: int):
        """The control command stamped ``t_ns``, or None after the timeout (stale ones dropped)."""
        start = time.monotonic()
        deadline = start + self.cfg["control_timeout_s"]
        resend = start + RESEND_S
        while t_ns not in self.pending:
            now = time.monotonic()
            left = deadline - now
            if left <= 0:
                return None
            if now >= resend:
                # the same messages again: a node whose subscriptions DDS had not matched yet
                # (the first step of a run) missed them; a command answers a stamp only once
                for pub, msg in self.last_sent:
                    pub.publish(msg)
                resend = now + RESEND_S
            self.rclpy.spin_once(self.node, timeout_sec=min(left, 0.05))
        command = self.pending.pop(t_ns)
        for stamp in [s for s in self.pending if s <= t_ns]:
            del self.pending[stamp]
        return command

    def motion_request(self, ego, command, t_ns: int) -> bytes:
        """A MotionRequest, desired state one step ahead, from a control command."""
        from osi3 import osi_motionrequest_pb2

        dt = float(self.hello["dt"])
        b = ego.base
        yaw = b.orientation.yaw
        speed = b.velocity.x * math.cos(yaw) + b.velocity.y * math.sin(yaw)
        length = b.dimension.length
        acceleration = None
        if self.cfg["control"]["type"] == "geometry_msgs/TwistStamped":
            target_speed = command.twist.linear.x
            yaw_to = yaw + command.twist.angular.z * dt
        else:
            drive = command.drive
            target_speed = drive.speed
            if drive.acceleration != 0.0:
                acceleration = drive.acceleration
            beta = math.atan(0.5 * math.tan(drive.steering_angle))
            v_ref = speed if abs(speed) >= 1e-3 else math.copysign(1e-3, speed or 1.0)
            yaw_to = yaw + v_ref * math.sin(beta) / (0.5 * length) * dt
        mr = osi_motionrequest_pb2.MotionRequest()
        mr.timestamp.seconds, mr.timestamp.nanos = divmod(t_ns, 1_000_000_000)
        mr.motion_request_type = osi_motionrequest_pb2.MotionRequest.MOTION_REQUEST_TYPE_DESIRED_STATE
        ds = mr.desired_state
        ds.timestamp.seconds, ds.timestamp.nanos = divmod(t_ns + int(round(dt * 1e9)), 1_000_000_000)
        ds.orientation.yaw = math.atan2(math.sin(yaw_to), math.cos(yaw_to))
        if acceleration is not None:
            ds.acceleration.x, ds.acceleration.y = acceleration * math.cos(yaw), acceleration * math.sin(yaw)
        else:
            ds.velocity.x, ds.velocity.y = target_speed * math.cos(yaw_to), target_speed * math.sin(yaw_to)
        return mr.SerializeToString()


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description="avs-osi/1 <-> ROS 2 bridge")
    p.add_argument("address", nargs="?", default=os.environ.get("AVS_OSI_ADDRESS"),
                   help="tcp://HOST:PORT or ipc://PATH to bind (default $AVS_OSI_ADDRESS)")
    p.add_argument("--topics", default=None, help="YAML file of topic names and types")
    args = p.parse_args(argv)
    if not args.address:
        p.error("give an ADDRESS or set AVS_OSI_ADDRESS")
    cfg = load_topics(args.topics)
    import zmq

    bridge = Bridge(cfg)
    sock = zmq.Context.instance().socket(zmq.REP)
    sock.setsockopt(zmq.LINGER, 0)
    sock.bind(args.address)
    parent = os.getppid() if os.environ.get("AVS_OSI_ADDRESS") == args.address else None
    try:
        while True:
            while not sock.poll(1000):
                if parent is not None and os.getppid() != parent:
                    return 0  # spawned by a plugin that is gone
            frames = sock.recv_multipart()
            try:
                reply = bridge.answer(frames)
            except Exception as exc:  # the plugin shows it as the case's error
                reply = [PROTOCOL, b"Error", f"ros2 bridge: {type(exc).__name__}: {exc}".encode()]
            sock.send_multipart(reply)
    finally:
        sock.close(linger=0)
        bridge.close()


if __name__ == "__main__":
    sys.exit(main())

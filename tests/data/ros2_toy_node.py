"""A toy ROS 2 driving stack for the bridge's test: rclpy and message packages only.

    python ros2_toy_node.py CONTROL_TOPIC ODOMETRY_TOPIC [--speed V]

On every odometry message of the ego it publishes a ``geometry_msgs/TwistStamped`` on
CONTROL_TOPIC, stamped with the odometry's stamp (the simulation time): drive straight on
toward the speed V [m/s] (at most 1 m/s more than now), no turning. It also counts the
/clock messages and the objects it saw, in the file REPORT (rewritten as they come).
"""

import argparse
import sys

import rclpy
from geometry_msgs.msg import TwistStamped
from nav_msgs.msg import Odometry
from rclpy.node import Node
from rclpy.qos import QoSProfile
from rosgraph_msgs.msg import Clock
from visualization_msgs.msg import MarkerArray


def main() -> int:
    p = argparse.ArgumentParser()
    p.add_argument("control")
    p.add_argument("odometry")
    p.add_argument("--objects", default="/avs/objects")
    p.add_argument("--speed", type=float, default=12.0)
    p.add_argument("--report", required=True)
    args = p.parse_args()
    rclpy.init()
    node = Node("toy_stack")
    qos = QoSProfile(depth=10)
    pub = node.create_publisher(TwistStamped, args.control, qos)
    seen = {"clock": 0, "objects": set()}

    def on_odometry(msg: Odometry) -> None:
        out = TwistStamped()
        out.header.stamp = msg.header.stamp
        out.header.frame_id = "base_link"
        out.twist.linear.x = min(args.speed, msg.twist.twist.linear.x + 1.0)
        pub.publish(out)

    def report() -> None:
        with open(args.report, "w") as fh:
            fh.write(f"clock={seen['clock']} objects={sorted(seen['objects'])}\n")

    def on_clock(msg: Clock) -> None:
        seen["clock"] += 1
        report()

    def on_objects(msg: MarkerArray) -> None:
        seen["objects"].update((mk.ns, mk.text) for mk in msg.markers)
        report()

    node.create_subscription(Odometry, args.odometry, on_odometry, qos)
    node.create_subscription(Clock, "/clock", on_clock, qos)
    node.create_subscription(MarkerArray, args.objects, on_objects, qos)
    print("ready", flush=True)
    rclpy.spin(node)  # until killed
    return 0


if __name__ == "__main__":
    sys.exit(main())

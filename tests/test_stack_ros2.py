"""The ROS 2 bridge (pytest_avscenario/stack/ros2_bridge.py): a file that stands alone.

It runs under the ROS 2 Python of the stack under test (Humble's 3.10, Jazzy's 3.12), so it
must parse as Python 3.10 and import nothing of this project. Where a ROS 2 Python is at
hand — ``$AVS_ROS_PYTHON``, or this interpreter — with rclpy, nav_msgs, geometry_msgs,
visualization_msgs, rosgraph_msgs, osi3, pyzmq and yaml, a campaign is driven through it
by a toy ROS node (tests/data/ros2_toy_node.py) that answers each odometry message with a
``geometry_msgs/TwistStamped`` stamped with the simulation time. PyPI's unofficial
``ros-*`` wheels (cp311) provide all of those but ``ackermann_msgs``, which has no wheel:
the toy node uses the bridge's TwistStamped control instead.
"""

from __future__ import annotations

import ast
import os
import random
import subprocess
import sys
import time
from pathlib import Path

import pytest

import pytest_avscenario

ROOT = Path(__file__).resolve().parent.parent
BRIDGE = Path(pytest_avscenario.__file__).parent / "stack" / "ros2_bridge.py"
TOY = ROOT / "tests" / "data" / "ros2_toy_node.py"
NEEDS = ("rclpy", "nav_msgs.msg", "geometry_msgs.msg", "visualization_msgs.msg", "rosgraph_msgs.msg",
         "osi3", "zmq", "yaml")


def test_the_bridge_stands_alone_and_parses_as_python_3_10():
    source = BRIDGE.read_text()
    tree = ast.parse(source, feature_version=(3, 10))
    imported = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            imported |= {a.name.split(".")[0] for a in node.names}
        elif isinstance(node, ast.ImportFrom):
            assert node.level == 0, f"relative import at line {node.lineno}: the bridge must stand alone"
            imported.add((node.module or "").split(".")[0])
    assert "pytest_avscenario" not in imported
    allowed = {"__future__", "argparse", "importlib", "json", "math", "os", "sys", "time",
               "yaml", "zmq", "osi3", "rclpy"}
    assert imported <= allowed, imported - allowed
    # nothing in the package imports it (it is data for another interpreter)
    for path in BRIDGE.parent.parent.rglob("*.py"):
        if path != BRIDGE:
            assert "ros2_bridge" not in path.read_text(), path


def test_the_topics_file_is_checked(tmp_path):
    sys.path.insert(0, str(BRIDGE.parent))
    try:
        import ros2_bridge
    finally:
        sys.path.remove(str(BRIDGE.parent))
    pytest.importorskip("yaml")
    good = tmp_path / "good.yaml"
    good.write_text("odometry: /ego/odom\ncontrol: {topic: /cmd, type: geometry_msgs/TwistStamped}\n"
                    "control_timeout_s: 1\n")
    cfg = ros2_bridge.load_topics(str(good))
    assert cfg["odometry"]["topic"] == "/ego/odom" and cfg["control"]["type"] == "geometry_msgs/TwistStamped"
    assert cfg["objects"]["topic"] == "/avs/objects" and cfg["control_timeout_s"] == 1.0
    bad = tmp_path / "bad.yaml"
    bad.write_text("odometri: /ego/odom\n")
    with pytest.raises(ValueError, match="unknown setting 'odometri'"):
        ros2_bridge.load_topics(str(bad))
    bad.write_text("control: {type: std_msgs/Float64}\n")
    with pytest.raises(ValueError, match="control type 'std_msgs/Float64': use one of"):
        ros2_bridge.load_topics(str(bad))


def _ros_python() -> tuple[str | None, str]:
    """A Python with everything the bridge and the toy node need, or (None, why not)."""
    python = os.environ.get("AVS_ROS_PYTHON", sys.executable)
    code = ("import importlib\nmissing = []\n"
            f"for m in {NEEDS!r}:\n"
            "    try:\n        importlib.import_module(m)\n"
            "    except Exception as exc:\n        missing.append(f'{m} ({type(exc).__name__}: {exc})'[:160])\n"
            "print('; '.join(missing))\n")
    try:
        out = subprocess.run([python, "-c", code], capture_output=True, text=True, timeout=120)
    except (OSError, subprocess.TimeoutExpired) as exc:
        return None, f"{python}: {exc}"
    missing = out.stdout.strip() or (out.stderr.strip()[-300:] if out.returncode else "")
    if missing:
        return None, (f"no ROS 2 Python: {python} lacks {missing} (set AVS_ROS_PYTHON to a Python "
                      "with rclpy, nav_msgs, geometry_msgs, visualization_msgs, rosgraph_msgs, "
                      "osi-python, pyzmq, pyyaml)")
    return python, ""


SCENARIO = """
import numpy as np
from pytest_avscenario import scenario, Uniform

@scenario(gap=Uniform(40, 60), samples=2, monitors=[])
def test_ros(case, world):
    road = world.straight_road(lanes=2, length=300)
    world.ego(road.lane(0), s=10.0, speed=8.0)
    world.car(road.lane(1), s=10.0 + case.gap, speed=5.0, name="slowpoke")
    world.run(seconds=3)
    ego = world.trajectory.agent("ego")
    # the toy ROS node asks for one more m/s each step up to 12 m/s, straight on
    assert abs(ego.speed[-1] - 12.0) < 1e-6 and ego.speed[5] > 9.0, ego.speed
    assert np.allclose(ego.y, 0.0) and np.allclose(ego.heading, 0.0)
"""


@pytest.mark.slow
def test_a_ros2_node_drives_a_campaign_through_the_bridge(pytester, monkeypatch):
    python, why = _ros_python()
    if python is None:
        pytest.skip(why)
    # DDS kept on this machine, in a domain of its own (runs side by side do not meet)
    domain = str(random.Random(os.getpid() ^ time.monotonic_ns()).randint(1, 200))
    for key, value in (("ROS_DOMAIN_ID", domain), ("ROS_LOCALHOST_ONLY", "1"),
                       ("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")):
        monkeypatch.setenv(key, value)
    seen = pytester.path / "seen.txt"
    toy = subprocess.Popen([python, str(TOY), "/avs/control", "/avs/ego/odometry", "--report", str(seen)],
                           stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    try:
        assert toy.stdout.readline().strip() == "ready"
        pytester.makefile(".yaml", topics="control: {topic: /avs/control, type: geometry_msgs/TwistStamped}\n"
                                          "control_timeout_s: 10\n")
        pytester.makepyfile(test_ros=SCENARIO)
        driver = f"osi+spawn:{python} {BRIDGE} {{address}} --topics {pytester.path / 'topics.yaml'}"
        result = pytester.runpytest_subprocess(f"--avs-driver={driver}", "--avs-stack-timeout=30",
                                               "--avs-db=none", "--avs-report=none",
                                               "--avs-shrink-budget=0", "-p", "no:xdist")
        result.assert_outcomes(passed=2)
    finally:
        toy.kill()
        out = toy.communicate(timeout=30)[0]
    counts = seen.read_text().strip()
    clock = int(counts.split()[0].split("=")[1])
    assert clock >= 2 * 30, out  # /clock for every step of both cases
    assert "('car', 'slowpoke')" in counts, out  # the other agent, in the object list

"""avs-osi/1: a stack out of process drives the ego over ZeroMQ with ASAM OSI messages.

The stack in these tests is tests/data/osi_raw_stack.py, written with nothing but pyzmq and
osi3 from docs/osi-protocol.md (it imports nothing of this project), run as a subprocess
the plugin spawns (``--avs-driver osi+spawn:COMMAND``). Also here: what the SensorView holds,
and the one frame conversion and its round trip.
"""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np
import pytest

zmq = pytest.importorskip("zmq")
pytest.importorskip("osi3")

# imported before any pytester run, which forgets what a run imported (see conftest.py);
# protobuf's descriptor pool aborts the process when osi3's modules are imported twice
from osi3 import (osi_lane_pb2, osi_motionrequest_pb2, osi_object_pb2,  # noqa: E402,F401
                  osi_sensorview_pb2, osi_trafficupdate_pb2, osi_version_pb2)
import google.protobuf.message  # noqa: E402,F401
from pytest_avscenario.stack import client, frame, kit, vehicle, wire  # noqa: E402,F401
from pytest_avscenario.sim.errors import SimError  # noqa: E402
from pytest_avscenario.sim.world import World  # noqa: E402
from pytest_avscenario.stack import OSIStack  # noqa: E402

RAW = Path(__file__).resolve().parent / "data" / "osi_raw_stack.py"


def raw_stack(*args: str) -> str:
    return f"osi+spawn:{sys.executable} {RAW} {{address}} " + " ".join(args)


@pytest.fixture(autouse=True)
def _stop_stacks():
    """Every stack process a test started is stopped when it ends (not at interpreter exit)."""
    yield
    client.stop_all()


SCENARIO = """
from pytest_avscenario import scenario, Uniform

@scenario(gap=Uniform(30, 50), samples=3, monitors=[])
def test_drive(case, world):
    road = world.straight_road(lanes=2, length=300)
    world.ego(road.lane(0), s=10.0, speed=8.0)
    world.car(road.lane(1), s=10.0 + case.gap, speed=5.0)
    world.run(seconds=2)
    ego = world.trajectory.agent("ego")
    # the raw stack drives along its heading, closing its speed error to 10 m/s in about 1 s
    assert 9.5 < ego.speed[-1] < 10.0 and np.all(np.diff(ego.speed) > 0), ego.speed
    assert np.allclose(ego.y, ego.y[0]) and np.all(np.diff(ego.x) > 0)
"""


@pytest.mark.parametrize("answer", ["motion", "traffic"])
def test_a_stack_written_from_the_protocol_alone_drives_a_campaign(pytester, answer):
    pytester.makepyfile(test_raw="import numpy as np\n" + SCENARIO)
    result = pytester.runpytest("--avs-driver", raw_stack("--answer", answer), "--avs-db=none",
                                "--avs-report=none", "--avs-shrink-budget=0", "-p", "no:xdist",
                                "-p", "no:cacheprovider")
    result.assert_outcomes(passed=3)


TRAJECTORY_SCENARIO = """
import numpy as np
from pytest_avscenario import scenario, Uniform

@scenario(gap=Uniform(60, 80), samples=2, monitors=[])
def test_change_lane(case, world):
    road = world.straight_road(lanes=2, length=400)
    world.ego(road.lane(0), s=10.0, speed=8.0)
    world.car(road.lane(0), s=10.0 + case.gap, speed=5.0)
    world.run(seconds=6)
    ego = world.trajectory.agent("ego")
    # the stack's trajectories lead to lane 1's centre (y = -3.5) at 10 m/s; the plugin's
    # controller follows them there: moved over, straightened out, at speed
    assert abs(ego.y[-1] + 3.5) < 0.2 and abs(ego.heading[-1]) < 0.02, (ego.y[-1], ego.heading[-1])
    assert 9.5 < ego.speed[-1] < 10.3, ego.speed[-1]
    assert ego.y.min() > -3.5 - 0.3  # no overshoot into the next lane
    assert np.all(np.diff(ego.x) > 0)
"""


def test_a_stack_answering_desired_trajectories_drives_a_campaign(pytester):
    pytester.makepyfile(test_traj=TRAJECTORY_SCENARIO)
    result = pytester.runpytest("--avs-driver", raw_stack("--answer", "trajectory", "--to-y", "-3.5"),
                                "--avs-db=none", "--avs-report=none", "--avs-shrink-budget=0",
                                "-p", "no:xdist", "-p", "no:cacheprovider")
    result.assert_outcomes(passed=2)


def test_the_driver_spec_is_checked_at_start_up(pytester):
    pytester.makepyfile(test_raw=SCENARIO)
    result = pytester.runpytest("--avs-driver", "osi:udp://127.0.0.1:5", "-p", "no:xdist")
    assert result.ret == pytest.ExitCode.USAGE_ERROR
    result.stderr.fnmatch_lines(["*--avs-driver*use tcp://HOST:PORT or ipc://PATH*"])


@pytest.mark.parametrize("command, said", [
    ("no_such_stack_program {address}", "*--avs-driver*no program 'no_such_stack_program' on PATH*"),
    ("./no/such/stack {address}", "*--avs-driver*'./no/such/stack' is not an executable file*"),
    ("python -m 'mystack {address}", "*--avs-driver*stack command*No closing quotation*"),
])
def test_a_spawn_command_that_cannot_start_is_refused_at_start_up(pytester, command, said):
    """Not one error per case: the run stops before any case, naming the option and why."""
    pytester.makepyfile(test_raw=SCENARIO)
    result = pytester.runpytest("--avs-driver", f"osi+spawn:{command}", "-p", "no:xdist")
    assert result.ret == pytest.ExitCode.USAGE_ERROR
    result.stderr.fnmatch_lines([said])


def test_an_osi_stack_object_with_a_command_that_cannot_start_is_refused_when_made():
    with pytest.raises(SimError, match="OSIStack: stack command .*no program 'no_such_stack_program'"):
        OSIStack(spawn="no_such_stack_program --bind {address}")


def _world() -> World:
    w = World(seed=1, name="t::frames")
    road = w.straight_road(lanes=2, length=200)
    w.ego(road.lane(1), s=20.0, speed=7.0, driver="autopilot")
    w.car(road.lane(0), s=40.0, speed=5.0)
    w.bus(road.lane(1), s=80.0, speed=3.0)
    return w


def test_the_sensor_view_holds_the_host_every_agent_and_the_lanes_of_world_view():
    from osi3 import osi_object_pb2, osi_sensorview_pb2

    w = _world()
    w.run(seconds=0.1)  # a run sets up the agents' order; the view is of its end
    ids = {a: i + 1 for i, a in enumerate(w.agents)}
    view = w.view()
    sv = osi_sensorview_pb2.SensorView()
    sv.ParseFromString(frame.sensor_view(w, wire.ns(1.25), frame.lane_ground_truth(view), ids))
    gt = sv.global_ground_truth
    assert sv.host_vehicle_id.value == gt.host_vehicle_id.value == 1
    assert wire.timestamp_ns(sv.timestamp) == 1_250_000_000 == wire.timestamp_ns(gt.timestamp)
    assert (sv.version.version_major, gt.version.version_major) == (3, 3)
    assert [mo.id.value for mo in gt.moving_object] == [1, 2, 3]
    lane_names = {lane.id.value: lane.source_reference[0].identifier[0] for lane in gt.lane}
    assert list(lane_names.values()) == [lane.id for lane in view.lanes]
    for mo, a in zip(gt.moving_object, view.agents):
        st = frame.object_state(mo)
        assert (st["x"], st["y"], st["heading"], st["speed"]) == pytest.approx(
            (a.x, a.y, a.heading, a.speed), abs=1e-12)
        assert mo.source_reference[0].identifier[0] == a.name
        assert lane_names[mo.assigned_lane_id[0].value] == view.agent_lanes[a.name]
        assert mo.base.position.z == pytest.approx(mo.base.dimension.height / 2)
    bus = gt.moving_object[2]
    assert bus.vehicle_classification.type == osi_object_pb2.MovingObject.VehicleClassification.TYPE_BUS
    assert frame.object_flags(bus) == {"stop_arm": False}
    # lanes: centre lines as in world.view(), a boundary each side, neighbours by number
    for lane, lv in zip(gt.lane, view.lanes):
        pts = [(p.x, p.y) for p in lane.classification.centerline]
        assert np.allclose(pts, lv.centre_line)
    left, right = gt.lane[0].classification, gt.lane[1].classification
    assert right.left_adjacent_lane_id[0].value == gt.lane[0].id.value
    assert left.right_adjacent_lane_id[0].value == gt.lane[1].id.value
    boundaries = {b.id.value: b for b in gt.lane_boundary}
    rb = boundaries[right.right_lane_boundary_id[0].value]
    assert rb.boundary_line[0].position.y == pytest.approx(view.lanes[1].position(0, -view.lanes[1].width / 2)[1])


@pytest.mark.parametrize("heading", [0.3, -2.9, 3.5, -7.0])
@pytest.mark.parametrize("speed", [0.0, 12.5, -1.5])
def test_an_agent_survives_the_round_trip_through_osi(heading, speed):
    from osi3 import osi_object_pb2

    mo = osi_object_pb2.MovingObject()
    frame.set_object(mo, 7, "car1", "car", 12.5, -3.5, heading, speed, 5.0, 2.0, acceleration=-2.0)
    st = frame.object_state(mo)
    assert -math.pi <= mo.base.orientation.yaw <= math.pi
    assert st["x"] == 12.5 and st["y"] == -3.5
    assert math.isclose(math.cos(st["heading"]), math.cos(heading), abs_tol=1e-12)
    assert math.isclose(math.sin(st["heading"]), math.sin(heading), abs_tol=1e-12)
    assert st["speed"] == pytest.approx(speed, abs=1e-12)
    assert mo.base.acceleration.x == pytest.approx(-2.0 * math.cos(heading))
    if -math.pi <= heading <= math.pi:
        assert st["heading"] == heading  # inside OSI's range the yaw is the world's heading, bit for bit


@pytest.mark.parametrize("speed", [0.0, 1e-4, 0.5, 14.0, -2.0])
@pytest.mark.parametrize("acceleration, steering", [(0.0, 0.0), (-6.0, 0.4), (2.0, -1.04), (1e-9, 1e-7)])
def test_a_command_survives_the_round_trip_through_a_motion_request(speed, acceleration, steering):
    from osi3 import osi_motionrequest_pb2

    mr = osi_motionrequest_pb2.MotionRequest()
    t_ns = wire.ns(3.2)
    frame.action_to_motion(mr, t_ns, 10.0, -3.5, 0.2, speed, 5.0, 0.1, acceleration, steering)
    a, d = frame.motion_to_action(mr.desired_state, t_ns, 0.2, speed, 5.0, 0.1)
    assert a == pytest.approx(acceleration, abs=1e-12)
    assert d == pytest.approx(steering, abs=1e-9)


def test_a_desired_state_without_orientation_is_refused():
    from osi3 import osi_motionrequest_pb2

    mr = osi_motionrequest_pb2.MotionRequest()
    mr.desired_state.velocity.x = 3.0
    with pytest.raises(ValueError, match="no orientation"):
        frame.motion_to_action(mr.desired_state, 0, 0.0, 1.0, 5.0, 0.1)


@pytest.mark.parametrize("speed, acceleration, steering", [(8.0, 1.5, 0.0), (14.0, -4.0, 0.0), (6.0, 0.0, 0.05),
                                                          (12.0, 1.0, 0.2)])
def test_a_trajectory_from_the_ego_now_is_followed_with_its_own_acceleration(speed, acceleration, steering):
    # the kit's trajectory: where (acceleration, steering) held takes the ego, from its state now
    from osi3 import osi_motionrequest_pb2

    mr = osi_motionrequest_pb2.MotionRequest()
    t_ns = wire.ns(2.0)
    frame.action_to_trajectory(mr, t_ns, 10.0, -3.5, 0.3, speed, 5.0, 0.1, acceleration, steering)
    a, d = frame.trajectory_to_action(mr.desired_trajectory, t_ns, 10.0, -3.5, 0.3, speed, 5.0, 0.1)
    assert a == pytest.approx(acceleration, abs=1e-9)
    if steering == 0.0:
        assert d == pytest.approx(0.0, abs=1e-12)
    else:  # on a curve the path-following law (no curvature feed-forward, as highway-env's
        # lane following) steers the same way, more at low speed: within a factor of 3
        assert steering < d < 3.0 * steering


def test_the_trajectory_controller_steers_back_to_the_path_and_brakes_for_a_stop():
    from osi3 import osi_motionrequest_pb2

    def trajectory(points):
        mr = osi_motionrequest_pb2.MotionRequest()
        for t, x, y in points:
            p = mr.desired_trajectory.trajectory_point.add()
            wire.set_timestamp(p.timestamp, wire.ns(t))
            p.position.x, p.position.y = x, y
        return mr.desired_trajectory

    along_x = trajectory([(1.0 + k * 0.1, 10.0 + k, 0.0) for k in range(20)])  # 10 m/s along y = 0
    # 1 m left of the path, heading along it: steer right (negative), keep the speed
    a, d = frame.trajectory_to_action(along_x, wire.ns(1.0), 10.0, 1.0, 0.0, 10.0, 5.0, 0.1)
    assert d < -0.01 and abs(a) < 1e-9
    # 1 m right of it: steer left, the mirror image
    a2, d2 = frame.trajectory_to_action(along_x, wire.ns(1.0), 10.0, -1.0, 0.0, 10.0, 5.0, 0.1)
    assert d2 == pytest.approx(-d, abs=1e-12)
    # 2 m behind where the timestamps say the ego should be: speed up
    a3, _ = frame.trajectory_to_action(along_x, wire.ns(1.0), 8.0, 0.0, 0.0, 10.0, 5.0, 0.1)
    assert a3 > 0.5
    # a trajectory that stands at the ego's place: brake
    stop = trajectory([(1.0, 10.0, 0.0), (1.5, 10.0, 0.0), (2.0, 10.0, 0.0)])
    a4, d4 = frame.trajectory_to_action(stop, wire.ns(1.0), 10.0, 0.0, 0.0, 5.0, 5.0, 0.1)
    assert a4 < -5.0 and d4 == 0.0


@pytest.mark.parametrize("points, says", [
    ([], "desired_trajectory has no trajectory_point"),
    ([(1.0, 0.0, 0.0), (1.0, 1.0, 0.0)], r"trajectory_point\[1\].timestamp 1000000000 ns is not after trajectory_point\[0\]'s"),
    ([(0.9, 0.0, 0.0), (1.1, 1.0, 0.0)], r"trajectory_point\[0\].timestamp 900000000 ns \(0.900 s\) is in the past"),
    ([(1.0, 0.0, 0.0)], "ends at the request's timestamp"),
    ([(1.1, 0.0, 0.0), (1.2, float("inf"), 0.0)], r"trajectory_point\[1\] has a non-finite position \(x=inf"),
])
def test_a_bad_trajectory_is_refused_naming_the_point(points, says):
    from osi3 import osi_motionrequest_pb2

    mr = osi_motionrequest_pb2.MotionRequest()
    mr.motion_request_type = mr.MOTION_REQUEST_TYPE_TRAJECTORY
    for t, x, y in points:
        p = mr.desired_trajectory.trajectory_point.add()
        wire.set_timestamp(p.timestamp, wire.ns(t))
        p.position.x, p.position.y = x, y
    with pytest.raises(ValueError, match=says):
        frame.trajectory_to_action(mr.desired_trajectory, wire.ns(1.0), 0.0, 0.0, 0.0, 5.0, 5.0, 0.1)


def test_the_stack_is_named_in_the_ini_file_or_by_the_test_itself(pytester):
    pytester.makeini(f"""
        [pytest]
        avs_driver = {raw_stack("--answer", "traffic")}
        avs_stack_timeout = 10
    """)
    pytester.makepyfile(test_raw="import numpy as np\n" + SCENARIO.replace("samples=3", "samples=2"))
    pytester.makepyfile(test_own=f"""
        import sys
        from pytest_avscenario import scenario, Uniform
        from pytest_avscenario.stack import OSIStack

        STACK = OSIStack(spawn={raw_stack()[len("osi+spawn:"):]!r}, timeout_s=10)

        @scenario(gap=Uniform(30, 50), samples=2, monitors=[])
        def test_own(case, world):
            road = world.straight_road(lanes=1, length=300)
            world.ego(road.lane(0), s=10.0, speed=8.0, driver=STACK)
            world.run(seconds=1)
            assert world.trajectory.agent("ego").speed[-1] > 8.5
    """)
    result = pytester.runpytest("--avs-db=none", "--avs-report=none", "--avs-shrink-budget=0",
                                "-p", "no:xdist", "-p", "no:cacheprovider")
    result.assert_outcomes(passed=4)


def test_one_stack_at_an_address_is_refused_for_several_processes(pytester):
    pytester.makepyfile(test_raw=SCENARIO)
    result = pytester.runpytest("--avs-driver", "osi:tcp://127.0.0.1:5555", "-n", "2")
    assert result.ret == pytest.ExitCode.USAGE_ERROR
    result.stderr.fnmatch_lines(["*--avs-driver: 'osi:tcp://127.0.0.1:5555' is one stack for one "
                                 "process, but pytest-xdist (-n) runs cases in several: use "
                                 "'osi+spawn:COMMAND'*"])


def test_sensor_views_kept_between_steps_give_the_bytes_of_a_fresh_build():
    """The plugin writes each step into the case's one SensorView (frame.SensorViews); what it
    sends must be what building the message afresh gives, step after step, while agents appear
    and leave and the ego changes lanes; the lanes go with the first SensorView only."""
    checked: list[tuple[tuple, int, bool]] = []

    class Check:
        def reset(self, world):
            self.w, self.views = world, None

        def act(self, obs):
            w = self.w
            if self.views is None:
                self.ids = {a: i + 1 for i, a in enumerate(w.agents)}
                self.static = frame.lane_ground_truth(w.view())
                self.views = frame.SensorViews(self.static, self.ids)
            t_ns = wire.ns(w.t)
            kept = self.views.build(w, t_ns)
            lanes = self.static if not checked else b""  # the lanes go with the first only
            checked.append((w.agents[0].lane_index, len(w.movers),
                            kept == frame.sensor_view(w, t_ns, lanes, self.ids)))
            return 0.5, (0.1 if 1.0 < w.t < 2.0 else 0.0)

    w = World(seed=5, name="test::views")
    road = w.straight_road(lanes=2, length=300)
    w.ego(road.lane(1), s=20.0, speed=8.0, driver=Check())
    w.car(road.lane(0), s=60.0, speed=6.0, appear=1.0, disappear=3.0)
    w.bus(road.lane(1), s=120.0, speed=0.0)
    w.run(seconds=4.0)
    assert all(same for _, _, same in checked), [c for c in checked if not c[2]][:3]
    assert {n for _, n, _ in checked} == {2, 3}  # the car came and went
    assert len({lane for lane, _, _ in checked}) == 2  # the ego changed lanes


def test_the_kits_motion_request_kept_between_steps_gives_the_bytes_of_a_fresh_one():
    """The kit answers each step from the case's one MotionRequest (kit.Session.answer); the
    bytes must be those of a message built afresh, step after step, while the command and
    the ego's state change."""
    answers: list[tuple[bytes, bytes]] = []

    class Check:
        def reset(self, world):
            self.w, self.views = world, None

        def act(self, obs):
            w = self.w
            if self.views is None:
                ids = {a: i + 1 for i, a in enumerate(w.agents)}
                self.views = frame.SensorViews(frame.lane_ground_truth(w.view()), ids)
                view = w.view()
                hello = {"dt": w.dt, "host_vehicle_id": 1,
                         "agents": [{"id": i + 1, "name": a.name, "kind": a.kind}
                                    for i, a in enumerate(w.agents)],
                         "lanes": [{"id": frame.LANE_ID0 + i, "width": l.width,
                                    "speed_limit": l.speed_limit} for i, l in enumerate(view.lanes)],
                         "ego": {"route": [frame.LANE_ID0 + w.lane_index.code[l.index]
                                           for l in w.agents[0].plan],
                                 "route_index": w.agents[0].route_index}}
                self.kept, self.fresh = kit.Session(hello, "autopilot"), kit.Session(hello, "autopilot")
            sv = osi_sensorview_pb2.SensorView.FromString(self.views.build(w, wire.ns(w.t)))
            self.fresh._motion = None  # a new message each step, as before it was kept
            answers.append((self.kept.answer(sv), self.fresh.answer(sv)))
            return 2.0 - w.t, 0.05 * math.sin(w.t)

    w = World(seed=3, name="test::motion")
    road = w.straight_road(lanes=2, length=300)
    w.ego(road.lane(1), s=20.0, speed=8.0, driver=Check())
    w.car(road.lane(1), s=45.0, speed=6.0)
    w.run(seconds=3.0)
    assert len(answers) == 30
    assert len({kept for kept, _ in answers}) == 30  # every step's answer differs
    assert all(kept == fresh for kept, fresh in answers)


def test_the_kit_sees_a_map_lane_s_width_where_the_ego_is():
    """lane_width_and_offset.xodr: lane 4/0/-1 widens as its s (0 at its start). The
    SensorView's boundaries are half the width at each centre-line point to either side, and
    the kit's route lanes give the width along the lane from them: at the ego's s the width
    the driver sees in process, not the Reset's width at s = 0."""
    seen: list[tuple[float, float, float]] = []
    sent: list[bytes] = []

    class Check:
        def reset(self, world):
            self.w, self.views = world, None
            from pytest_avscenario.sim.drivers import resolve
            self.auto = resolve("autopilot")

        def act(self, obs):
            w = self.w
            if self.views is None:
                ids = {a: i + 1 for i, a in enumerate(w.agents)}
                view = w.view()
                self.views = frame.SensorViews(frame.lane_ground_truth(view), ids)
                lane_ids = {l.id: frame.LANE_ID0 + i for i, l in enumerate(view.lanes)}
                hello = {"dt": w.dt, "host_vehicle_id": 1,
                         "agents": [{"id": 1, "name": "ego", "kind": "ego"}],
                         "lanes": [{"id": lane_ids[l.id], "width": l.width,
                                    "speed_limit": l.speed_limit} for l in view.lanes],
                         "ego": {"route": [lane_ids[l.id] for l in w.agents[0].plan],
                                 "route_index": w.agents[0].route_index}}
                self.session = kit.Session(hello, "autopilot")
            msg = self.views.build(w, wire.ns(w.t))
            sent.append(msg)
            served = self.session.observation(osi_sensorview_pb2.SensorView.FromString(msg))
            lane = served.route[served.route_index]
            here = obs.route[obs.route_index]
            seen.append((obs.s, here.width_at(obs.s), lane.width_at(served.s)))
            return self.auto.act(obs)

    w = World(0, name="t::widths")
    road = w.map(Path(__file__).parent / "data" / "maps" / "lane_width_and_offset.xodr")
    w.ego(road.lane("4/0/-1"), s=3.0, speed=2.0, driver=Check())
    w.run(4)
    # the boundaries: half the width at each centre-line point, to either side
    sv = osi_sensorview_pb2.SensorView.FromString(sent[0])
    view = w.view()
    i = next(k for k, l in enumerate(view.lanes) if l.id == "4/0/-1")
    lane, gt = view.lanes[i], sv.global_ground_truth
    bounds = {b.id.value: b for b in gt.lane_boundary}
    left, right = bounds[frame.BOUNDARY_ID0 + 2 * i + 1], bounds[frame.BOUNDARY_ID0 + 2 * i]
    n = len(lane.centre_line)
    gaps = [math.hypot(a.position.x - b.position.x, a.position.y - b.position.y)
            for a, b in zip(left.boundary_line, right.boundary_line)]
    assert len(gaps) == n and lane.width == 0.0
    assert np.allclose(gaps, [lane.width_at(lane.length * k / (n - 1)) for k in range(n)], atol=1e-9)
    # the width the served driver sees is the in-process one at the ego's s (it widens by 3 m)
    s, here, served = np.array(seen).T
    assert here[-1] > here[0] + 3.0
    assert np.abs(served - here).max() < 1e-3


# -- waiting: --avs-stack-spin ------------------------------------------------------------------
@pytest.mark.parametrize("cpus, workers, spins", [(2, None, True), (2, "2", False), (4, "2", True),
                                                   (1, None, False), (8, "3", True), (8, "5", False)])
def test_auto_spins_only_with_two_cpus_for_each_process_running_cases(monkeypatch, cpus, workers, spins):
    monkeypatch.setattr(client.os, "sched_getaffinity", lambda pid: set(range(cpus)))
    if workers is None:
        monkeypatch.delenv("PYTEST_XDIST_WORKER_COUNT", raising=False)
    else:
        monkeypatch.setenv("PYTEST_XDIST_WORKER_COUNT", workers)
    assert client.auto_spin_s() == (client.AUTO_SPIN_S if spins else 0.0)


def test_a_dask_worker_gets_the_stack_settings_of_the_run(monkeypatch):
    """--avs-stack-timeout and the spin travel with the test's spec: a local cluster's
    workers share this machine (auto decides by their number), a remote one's do not spin."""
    monkeypatch.setattr(client.os, "sched_getaffinity", lambda pid: {0, 1, 2, 3})
    monkeypatch.setattr(client, "_settings", {"timeout_s": 12.5, "spin_s": None})
    assert client.settings_for(2) == {"timeout_s": 12.5, "spin_s": client.AUTO_SPIN_S}
    assert client.settings_for(3) == {"timeout_s": 12.5, "spin_s": 0.0}
    assert client.settings_for(None) == {"timeout_s": 12.5, "spin_s": 0.0}
    client.configure(spin_s=50e-6)
    assert client.settings_for(None) == {"timeout_s": 12.5, "spin_s": 50e-6}


@pytest.mark.parametrize("value", ["abc", "-1", "2000000", "nan"])
def test_a_bad_stack_spin_is_refused_at_start_up(pytester, value):
    pytester.makepyfile(test_raw=SCENARIO)
    result = pytester.runpytest(f"--avs-stack-spin={value}", "-p", "no:xdist")
    assert result.ret == pytest.ExitCode.USAGE_ERROR
    result.stderr.fnmatch_lines(["*--avs-stack-spin: stack_spin must be 'auto' or a number of "
                                 "microseconds from 0 to 1000000*"])


def test_a_spawned_stack_is_handed_the_spin_and_the_kit_takes_it(pytester):
    """osi+spawn: puts the run's spin into $AVS_OSI_SPIN_US; the kit's serve() reads it."""
    pytester.makepyfile(test_raw=SCENARIO)
    pytester.path.joinpath("stack.py").write_text(
        "import os, sys\n"
        "from pytest_avscenario.stack import kit, zmtp\n"
        "made = []\n"
        "class Seen(zmtp.Replier):\n"
        "    def __init__(self, *a, **k):\n"
        "        super().__init__(*a, **k)\n"
        "        made.append(self.spin_s)\n"
        "        open(sys.argv[1], 'a').write(f\"{os.environ.get('AVS_OSI_SPIN_US')} {self.spin_s!r}\\n\")\n"
        "zmtp.Replier = Seen\n"
        "kit.serve('autopilot', os.environ['AVS_OSI_ADDRESS'])\n")
    seen = pytester.path / "seen.txt"
    result = pytester.runpytest(f"--avs-driver=osi+spawn:{sys.executable} stack.py {seen}",
                                "--avs-stack-spin=250", "--avs-db=none", "--avs-report=none",
                                "--avs-shrink-budget=0", "-p", "no:xdist", "-p", "no:cacheprovider")
    assert result.ret in (0, 1), result.stdout.str()[-2000:]
    assert seen.read_text().split() == ["250", "0.00025"]


def test_a_spinning_wait_still_ends_at_its_deadline(tmp_path):
    """The spin is bounded by the wait's deadline: a stack that never answers is still a
    timeout at the deadline, and a REP with nothing to read still returns at its timeout."""
    import threading
    import time
    from pytest_avscenario.stack import zmtp

    address = f"ipc://{tmp_path}/spin.sock"
    rep = zmtp.Replier(address, spin_s=30.0)
    got: list = []
    server = threading.Thread(target=lambda: got.append(rep.receive(timeout_s=20)))
    server.start()  # greets the requester, reads its request and never answers
    req = zmtp.Requester(address, spin_s=30.0)
    try:
        assert req.connect(time.monotonic() + 10)
        req.send([b"hello"])
        start = time.monotonic()
        with pytest.raises(TimeoutError):
            req.receive(time.monotonic() + 0.2)
        assert time.monotonic() - start < 10  # the deadline, not the 30-s spin
        server.join(20)
        assert got == [[b"hello"]]
        start = time.monotonic()
        assert rep.receive(timeout_s=0.2) is None
        assert time.monotonic() - start < 10
    finally:
        req.close()
        server.join(20)
        rep.close()

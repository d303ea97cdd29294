"""The safety metrics on hand-built trajectories, with the arithmetic written out."""

from __future__ import annotations

import math

import numpy as np
import pytest

from pytest_avscenario.monitors import (
    MonitorError,
    collision,
    distance,
    lane_keeping,
    off_road,
    progress,
    reaches,
    time_headway,
    ttc,
)
from pytest_avscenario.trajectory import Trajectory


def one_step(ego, other, **kw):
    """Single-step scene: each of ego/other is (x, y, vx, vy)."""
    agents = {
        "ego": dict(zip(("x", "y", "vx", "vy"), ego)),
        "other": dict(zip(("x", "y", "vx", "vy"), other)),
    }
    return Trajectory.from_arrays([0.0], agents, **kw)


def straight(n=11, dt=0.1, **agents):
    """Agents moving at constant velocity: name=(x0, y0, vx, vy[, extra dict])."""
    t = np.arange(n) * dt
    spec = {}
    for name, a in agents.items():
        x0, y0, vx, vy, *extra = a
        d = {"x": x0 + vx * t, "y": y0 + vy * t, "vx": vx, "vy": vy}
        if extra:
            d.update(extra[0])
        spec[name] = d
    return Trajectory.from_arrays(t, spec)


# -- TTC: the four hand-worked cases of the issue --------------------------------------------

def test_ttc_head_on_closing_at_20_mps():
    # 20 m apart, each closing at 10 m/s: relative speed 20 m/s, the 5-m circle is reached
    # after (20 - 5) / 20 = 0.75 s, so rho = 0.75 - 2 = -1.25.
    r = ttc(2.0).evaluate(one_step((0, 0, 10, 0), (20, 0, -10, 0)))
    assert r.rho == pytest.approx((20 - 5) / 20 - 2.0)
    assert r.agent == "other" and r.t == 0.0 and r.threshold == 2.0
    assert r.rho < 0


def test_ttc_same_speed_parallel_lanes_is_infinite():
    # 10 m ahead in the next lane (11.4 m away, outside the circle), same velocity: dv = 0,
    # the relative position never changes, no root
    r = ttc().evaluate(one_step((0, 0, 15, 0), (10, 3.5, 15, 0)))
    assert r.rho == math.inf and r.agent is None


def test_ttc_inside_the_circle_is_zero():
    # 3 m apart < 5 m radius: TTC 0, rho = 0 - 2
    r = ttc(2.0).evaluate(one_step((0, 0, 10, 0), (3, 0, 10, 0)))
    assert r.rho == -2.0


def test_ttc_receding_is_infinite():
    # the other is ahead and faster: both roots are in the past
    r = ttc().evaluate(one_step((0, 0, 10, 0), (10, 0, 20, 0)))
    assert r.rho == math.inf


def test_ttc_respects_radius_and_threshold_arguments():
    # 30 m apart, closing at 10 m/s, radius 10 m: (30 - 10) / 10 = 2 s; threshold 1.5 s
    r = ttc(1.5, radius=10.0).evaluate(one_step((0, 0, 10, 0), (30, 0, 0, 0)))
    assert r.rho == pytest.approx(2.0 - 1.5)


def test_ttc_checks_every_agent_not_only_the_first():
    # the first other agent is harmless, the second is on a collision course
    t = np.arange(3) * 0.1
    traj = Trajectory.from_arrays(t, {
        "ego": {"x": 10 * t, "y": 0 * t, "vx": 10, "vy": 0},
        "far": {"x": 500 + 10 * t, "y": 0 * t, "vx": 10, "vy": 0},
        "oncoming": {"x": 25 - 10 * t, "y": 0 * t, "vx": -10, "vy": 0},
    })
    r = ttc().evaluate(traj)
    assert r.agent == "oncoming"
    # worst at the last step: gap 25 - 4 = 21 m at t=0.2, (21 - 5) / 20 = 0.8 s
    assert r.t == pytest.approx(0.2)
    assert r.rho == pytest.approx(0.8 - 2.0)


def test_ttc_grazing_pass_counts_when_the_path_enters_the_circle():
    # other drives past at lateral offset 3 m (< 5 m radius): dp=(20,3), dv=(-10,0);
    # |dp + dv t| = 5  ->  (20 - 10t)^2 = 25 - 9 = 16  ->  t1 = (20 - 4) / 10 = 1.6 s
    r = ttc().evaluate(one_step((0, 0, 0, 0), (20, 3, -10, 0)))
    assert r.rho == pytest.approx(1.6 - 2.0)
    # at lateral offset 6 m the path never enters the circle
    assert ttc().evaluate(one_step((0, 0, 0, 0), (20, 6, -10, 0))).rho == math.inf


# -- distance ------------------------------------------------------------------------------

def test_distance_is_min_centre_distance_minus_threshold_over_steps_and_agents():
    traj = straight(
        n=5, dt=1.0,
        ego=(0, 0, 1, 0),
        lead=(12, 0, 0, 0),        # gap 12, 11, 10, 9, 8
        side=(0, 6.5, 1, 0),       # constant 6.5
    )
    r = distance(5.0).evaluate(traj)
    assert r.rho == pytest.approx(6.5 - 5.0)
    assert r.agent == "side" and r.t == 0.0
    r2 = distance(9.0).evaluate(traj)
    assert r2.rho == pytest.approx(6.5 - 9.0)


def test_distance_reports_time_and_agent_of_the_worst_value():
    traj = straight(n=11, dt=0.5, ego=(0, 0, 2, 0), lead=(20, 0, 0, 0))
    r = distance().evaluate(traj)
    # ego ends at x = 10 at t = 5 s: 20 - 10 - 5 = 5
    assert (r.rho, r.t, r.agent) == (pytest.approx(5.0), 5.0, "lead")
    assert "lead" in r.detail and "t=5.00" in r.detail


def test_distance_footprint_gap_uses_the_rectangles():
    # two 5 m x 2 m cars nose to tail 8 m between centres: gap 8 - 5 = 3 m
    traj = one_step((0, 0, 1, 0), (8, 0, 1, 0))
    assert distance(1.0, footprint=True).evaluate(traj).rho == pytest.approx(3.0 - 1.0)
    assert distance(1.0).evaluate(traj).rho == pytest.approx(8.0 - 1.0)


def test_distance_with_no_other_agent_holds_trivially():
    traj = Trajectory.from_arrays([0.0, 0.1], {"ego": {"x": [0, 1], "y": [0, 0]}})
    r = distance().evaluate(traj)
    assert r.rho == math.inf and r.agent is None and r.t is None


def test_absent_steps_are_ignored_not_nan():
    # the pedestrian is present only for the last 3 steps; before that its (NaN) kinematics
    # and even a close stale position must not count
    t = np.arange(6) * 1.0
    x_ped = np.array([np.nan, 1.0, np.nan, 30.0, 29.0, 28.0])  # 1.0 while absent: ignored
    present = np.array([False, False, False, True, True, True])
    traj = Trajectory.from_arrays(t, {
        "ego": {"x": 0 * t, "y": 0 * t, "vx": 0, "vy": 0},
        "ped": {"x": x_ped, "y": 0 * t, "vx": -1.0, "vy": 0, "present": present},
    })
    assert distance().evaluate(traj).rho == pytest.approx(28.0 - 5.0)
    r = ttc().evaluate(traj)
    # closing at 1 m/s from 28 m at t=5: (28 - 5) / 1 = 23 s
    assert r.rho == pytest.approx(23.0 - 2.0) and r.t == 5.0
    assert collision().evaluate(traj).rho > 0
    assert time_headway(1.0).evaluate(traj).rho == math.inf  # ego stands still


def test_nan_while_present_is_an_error_naming_the_agent():
    t = np.arange(3) * 1.0
    traj = Trajectory.from_arrays(t, {
        "ego": {"x": [0.0, 1.0, 2.0], "y": 0 * t},
        "lead": {"x": [20.0, np.nan, 22.0], "y": 0 * t, "vx": 1.0, "vy": 0.0},
    })
    for m in (distance(), ttc(), collision()):
        with pytest.raises(MonitorError, match=r"lead.*t=1\.000"):
            m.evaluate(traj)


# -- progress and lane keeping --------------------------------------------------------------

def test_progress_is_straight_line_displacement_minus_threshold():
    # from (0, 0) to (8, 6): 10 m, threshold 11 -> rho -1; the detour in between is ignored
    traj = Trajectory.from_arrays([0, 1, 2], {"ego": {"x": [0, 50, 8], "y": [0, 0, 6]}})
    r = progress(11.0).evaluate(traj)
    assert r.rho == pytest.approx(10.0 - 11.0) and r.agent == "ego"
    assert progress(9.0).evaluate(traj).rho == pytest.approx(1.0)


def test_progress_uses_first_and_last_present_steps():
    traj = Trajectory.from_arrays([0, 1, 2, 3], {"ego": {
        "x": [np.nan, 0, 12, np.nan], "y": [np.nan, 0, 0, np.nan],
        "present": [False, True, True, False]}})
    assert progress(11.0).evaluate(traj).rho == pytest.approx(12.0 - 11.0)


def test_lane_keeping_sideways_offset_for_half_the_steps():
    # ego 0.3 m to the side of its lane centre for 10 of 20 steps, centred otherwise:
    # mean offset = (10 * 0.3 + 10 * 0) / 20 = 0.15 m; rho = 0.5 - 0.15 = 0.35
    n = 20
    t = np.arange(n) * 0.1
    y = np.where(np.arange(n) < n // 2, 0.3, 0.0)
    traj = Trajectory.from_arrays(t, {"ego": {
        "x": 10 * t, "y": y, "lane": "a->b/0", "lane_offset": y}})
    r = lane_keeping(0.5).evaluate(traj)
    assert r.rho == pytest.approx(0.35)
    assert r.t == 0.0 and "0.3" in r.detail


def test_lane_keeping_uses_distance_not_signed_offset():
    # +0.4 and -0.4 alternate: signed mean 0, distance mean 0.4 -> rho 0.1
    off = np.array([0.4, -0.4] * 5)
    traj = Trajectory.from_arrays(np.arange(10.0), {"ego": {"x": np.arange(10.0), "y": off,
                                                            "lane_offset": off}})
    assert lane_keeping().evaluate(traj).rho == pytest.approx(0.1)


def test_lane_keeping_without_lane_offsets_is_an_error_not_a_pass():
    traj = Trajectory.from_arrays([0, 1], {"ego": {"x": [0, 1], "y": [0, 0]}})
    with pytest.raises(MonitorError, match="lane offset"):
        lane_keeping().evaluate(traj)


def test_lane_keeping_nan_offset_on_a_known_lane_is_an_error():
    traj = Trajectory.from_arrays([0, 1], {"ego": {"x": [0, 1], "y": [0, 0], "lane": "l0",
                                                   "lane_offset": [0.1, np.nan]}})
    with pytest.raises(MonitorError, match="lane_offset"):
        lane_keeping().evaluate(traj)


# -- collision, headway, off-road, reaches ---------------------------------------------------

def test_collision_rho_is_separation_then_penetration_depth():
    # 5 x 2 m cars, same heading: centres 7 m apart -> 2 m apart; 4 m apart -> 1 m overlap
    assert collision().evaluate(one_step((0, 0, 1, 0), (7, 0, 1, 0))).rho == pytest.approx(2.0)
    r = collision().evaluate(one_step((0, 0, 1, 0), (4, 0, 1, 0)))
    assert r.rho == pytest.approx(-1.0) and "overlap" in r.detail
    # side by side 2.5 m apart laterally: 0.5 m gap
    assert collision().evaluate(one_step((0, 0, 1, 0), (0, 2.5, 1, 0))).rho == pytest.approx(0.5)


def test_collision_rotated_rectangles_corner_case():
    # other turned 90 degrees: its half-extent along x is 1 m; 4 m between centres
    # -> 4 - 2.5 - 1 = 0.5 m apart
    traj = one_step((0, 0, 1, 0), (4, 0, 0, 1))
    assert collision().evaluate(traj).rho == pytest.approx(0.5)


def test_collision_counts_a_recorded_crash_flag():
    traj = Trajectory.from_arrays([0, 1], {"ego": {"x": [0, 1], "y": [0, 0],
                                                   "crashed": [False, True]}})
    r = collision().evaluate(traj)
    assert r.rho < 0 and r.t == 1.0
    assert collision(use_crash_flag=False).evaluate(traj).rho == math.inf


def test_time_headway_to_the_vehicle_ahead_in_the_lane():
    # ego 20 m/s, lead 30 m ahead (centres) -> bumper gap 25 m -> 1.25 s; threshold 2 s
    traj = one_step((0, 0, 20, 0), (30, 0, 20, 0))
    r = time_headway(2.0).evaluate(traj)
    assert r.rho == pytest.approx(25 / 20 - 2.0) and r.agent == "other"
    # a car in the next lane or behind does not count
    assert time_headway(2.0).evaluate(one_step((0, 0, 20, 0), (30, 3.5, 20, 0))).rho == math.inf
    assert time_headway(2.0).evaluate(one_step((0, 0, 20, 0), (-30, 0, 20, 0))).rho == math.inf


def test_time_headway_uses_lane_ids_when_recorded():
    traj = Trajectory.from_arrays([0.0], {
        "ego": {"x": [0], "y": [0], "vx": 10, "vy": 0, "lane": "r/0"},
        "lead": {"x": [20], "y": [0.5], "vx": 10, "vy": 0, "lane": "r/1"},
    })
    assert time_headway().evaluate(traj).rho == math.inf


def test_off_road_duration():
    on = np.array([True, True, False, False, True])
    traj = Trajectory.from_arrays(np.arange(5) * 0.5, {"ego": {"x": np.arange(5.0), "y": 0 * on,
                                                                "on_road": on}})
    r = off_road().evaluate(traj)
    assert r.rho == pytest.approx(-2 * 0.5) and r.t == 1.0
    ok = Trajectory.from_arrays([0, 1], {"ego": {"x": [0, 1], "y": [0, 0]}})
    assert off_road().evaluate(ok).rho == 0.0


def test_reaches_point_and_polygon():
    from shapely.geometry import Polygon

    traj = Trajectory.from_arrays(np.arange(11.0), {"ego": {"x": np.arange(11.0), "y": 0 * np.arange(11.0)}})
    # closest approach to (10, 3) is 3 m at x=10: radius 2 -> -1, radius 4 -> +1
    assert reaches((10, 3), radius=2.0).evaluate(traj).rho == pytest.approx(-1.0)
    r = reaches((10, 3), radius=4.0).evaluate(traj)
    assert r.rho == pytest.approx(1.0) and r.t == 10.0
    box = Polygon([(6, -2), (9, -2), (9, 2), (6, 2)])
    # deepest inside at x=7 or 8: 1 m from the nearest edge (x edges 6/9, y edges +-2 m)
    assert reaches(box).evaluate(traj).rho == pytest.approx(1.0)
    far = Polygon([(20, -2), (25, -2), (25, 2), (20, 2)])
    assert reaches(far).evaluate(traj).rho == pytest.approx(-10.0)


# -- argument validation at construction -------------------------------------------------------

@pytest.mark.parametrize("build, match", [
    (lambda: distance(math.inf), "finite"),
    (lambda: distance(math.nan), "finite"),
    (lambda: distance("5"), "number"),
    (lambda: ttc(2.0, radius=-1.0), "radius"),
    (lambda: ttc(2.0, radius=0.0), "radius"),
    (lambda: progress(None), "number"),
    (lambda: lane_keeping(True), "number"),
    (lambda: time_headway(-1.0), "seconds"),
    (lambda: reaches((1, 2)), "radius"),
    (lambda: reaches("goal", radius=1.0), "place"),
    (lambda: reaches((0, 0), radius=-2.0), "radius"),
])
def test_bad_arguments_fail_at_construction(build, match):
    with pytest.raises(MonitorError, match=match):
        build()


def test_metrics_have_report_names():
    ms = [distance(), ttc(), progress(), lane_keeping(), collision(), time_headway(),
          off_road(), reaches((0, 0), radius=1.0)]
    assert [m.name for m in ms] == ["distance", "ttc", "progress", "lane_keeping", "collision",
                                    "time_headway", "off_road", "reaches"]
    assert distance(2.0).named("distance_2m").name == "distance_2m"

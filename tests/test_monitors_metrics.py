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
from pytest_avscenario.monitors.base import first_violation
from pytest_avscenario.monitors.metrics import footprint_separation, swept_contacts
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
    r = ttc(2.0, kind="centre").evaluate(one_step((0, 0, 10, 0), (20, 0, -10, 0)))
    assert r.rho == pytest.approx((20 - 5) / 20 - 2.0)
    assert r.agent == "other" and r.t == 0.0 and r.threshold == 2.0
    assert r.rho < 0


def test_ttc_same_speed_parallel_lanes_is_infinite():
    # 10 m ahead in the next lane (11.4 m away, outside the circle), same velocity: dv = 0,
    # the relative position never changes, no root
    r = ttc(kind="centre").evaluate(one_step((0, 0, 15, 0), (10, 3.5, 15, 0)))
    assert r.rho == math.inf and r.agent is None


def test_ttc_inside_the_circle_is_zero():
    # 3 m apart < 5 m radius: TTC 0, rho = 0 - 2
    r = ttc(2.0, kind="centre").evaluate(one_step((0, 0, 10, 0), (3, 0, 10, 0)))
    assert r.rho == -2.0


def test_ttc_receding_is_infinite():
    # the other is ahead and faster: both roots are in the past
    r = ttc(kind="centre").evaluate(one_step((0, 0, 10, 0), (10, 0, 20, 0)))
    assert r.rho == math.inf


def test_ttc_respects_radius_and_threshold_arguments():
    # 30 m apart, closing at 10 m/s, radius 10 m: (30 - 10) / 10 = 2 s; threshold 1.5 s
    r = ttc(1.5, radius=10.0, kind="centre").evaluate(one_step((0, 0, 10, 0), (30, 0, 0, 0)))
    assert r.rho == pytest.approx(2.0 - 1.5)


def test_ttc_checks_every_agent_not_only_the_first():
    # the first other agent is harmless, the second is on a collision course
    t = np.arange(3) * 0.1
    traj = Trajectory.from_arrays(t, {
        "ego": {"x": 10 * t, "y": 0 * t, "vx": 10, "vy": 0},
        "far": {"x": 500 + 10 * t, "y": 0 * t, "vx": 10, "vy": 0},
        "oncoming": {"x": 25 - 10 * t, "y": 0 * t, "vx": -10, "vy": 0},
    })
    r = ttc(kind="centre").evaluate(traj)
    assert r.agent == "oncoming"
    # worst at the last step: gap 25 - 4 = 21 m at t=0.2, (21 - 5) / 20 = 0.8 s
    assert r.t == pytest.approx(0.2)
    assert r.rho == pytest.approx(0.8 - 2.0)


def test_ttc_grazing_pass_counts_when_the_path_enters_the_circle():
    # other drives past at lateral offset 3 m (< 5 m radius): dp=(20,3), dv=(-10,0);
    # |dp + dv t| = 5  ->  (20 - 10t)^2 = 25 - 9 = 16  ->  t1 = (20 - 4) / 10 = 1.6 s
    r = ttc(kind="centre").evaluate(one_step((0, 0, 0, 0), (20, 3, -10, 0)))
    assert r.rho == pytest.approx(1.6 - 2.0)
    # at lateral offset 6 m the path never enters the circle
    assert ttc(kind="centre").evaluate(one_step((0, 0, 0, 0), (20, 6, -10, 0))).rho == math.inf


# -- distance ------------------------------------------------------------------------------

def test_distance_is_min_centre_distance_minus_threshold_over_steps_and_agents():
    traj = straight(
        n=5, dt=1.0,
        ego=(0, 0, 1, 0),
        lead=(12, 0, 0, 0),        # gap 12, 11, 10, 9, 8
        side=(0, 6.5, 1, 0),       # constant 6.5
    )
    r = distance(5.0, kind="centre").evaluate(traj)
    assert r.rho == pytest.approx(6.5 - 5.0)
    assert r.agent == "side" and r.t == 0.0
    r2 = distance(9.0, kind="centre").evaluate(traj)
    assert r2.rho == pytest.approx(6.5 - 9.0)


def test_distance_reports_time_and_agent_of_the_worst_value():
    traj = straight(n=11, dt=0.5, ego=(0, 0, 2, 0), lead=(20, 0, 0, 0))
    r = distance(kind="centre").evaluate(traj)
    # ego ends at x = 10 at t = 5 s: 20 - 10 - 5 = 5
    assert (r.rho, r.t, r.agent) == (pytest.approx(5.0), 5.0, "lead")
    assert "lead" in r.detail and "t=5.00" in r.detail


def test_distance_footprint_gap_uses_the_rectangles():
    # two 5 m x 2 m cars nose to tail 8 m between centres: gap 8 - 5 = 3 m
    traj = one_step((0, 0, 1, 0), (8, 0, 1, 0))
    assert distance(1.0, footprint=True).evaluate(traj).rho == pytest.approx(3.0 - 1.0)
    assert distance(1.0, kind="centre").evaluate(traj).rho == pytest.approx(8.0 - 1.0)


def test_distance_with_no_other_agent_holds_trivially():
    traj = Trajectory.from_arrays([0.0, 0.1], {"ego": {"x": [0, 1], "y": [0, 0]}})
    r = distance(kind="centre").evaluate(traj)
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
    assert distance(kind="centre").evaluate(traj).rho == pytest.approx(28.0 - 5.0)
    r = ttc(kind="centre").evaluate(traj)
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


# -- collisions between recorded steps ---------------------------------------------------------

def crossing(x_cross, dt=0.5):
    """The ego (5 x 2 m) stands at the origin facing +x; a car crosses its path northward at
    30 m/s at ``x_cross``, recorded 7.5 m south and 7.5 m north of it: two samples that
    straddle the moment they meet."""
    return Trajectory.from_arrays([0.0, dt], {
        "ego": {"x": [0.0, 0.0], "y": [0.0, 0.0], "vx": 0.0, "vy": 0.0, "heading": 0.0},
        "crossing": {"x": [x_cross, x_cross], "y": [-7.5, 7.5], "vx": 0.0, "vy": 30.0,
                     "heading": math.pi / 2},
    })


def test_collision_between_recorded_steps_names_the_agent_and_the_moment():
    traj = crossing(0.0)
    ego0, car0 = traj.footprints(0)
    ego1, car1 = traj.footprints(1)
    assert not ego0.intersects(car0) and not ego1.intersects(car1)  # no sample shows it
    r = collision().evaluate(traj)
    assert r.agent == "crossing" and "between the recorded steps" in r.detail
    # its front (2.5 m ahead of its centre) meets the ego's side (1 m off centre) after
    # (7.5 - 3.5) m at 30 m/s
    assert r.t == pytest.approx(4.0 / 30.0, abs=1e-3)
    assert first_violation(collision(), traj) == (r.t, "crossing")  # what reports show
    # halfway through the step the two are centred on each other: 3.5 m deep either way
    assert r.rho == pytest.approx(-3.5)


@pytest.mark.parametrize("x_cross, holds", [(3.6, True), (3.502, True), (3.498, False)])
def test_collision_near_miss_between_steps(x_cross, holds):
    # the ego's front is at x = 2.5, the crossing car's near side at x_cross - 1
    r = collision().evaluate(crossing(x_cross))
    assert r.ok == holds
    if holds:
        assert r.rho == pytest.approx(4.0)  # the separation at the recorded steps
    else:
        assert r.rho == pytest.approx(-0.002, abs=1e-6) and r.agent == "crossing"


def test_collision_between_steps_while_both_turn():
    # the ego turns left through 90 degrees while the other drives straight past its corner;
    # the samples are 1.3 m and 0.5 m apart; halfway the ego's corner reaches y = 2.47 m under
    # the other's side at 2.3 m
    t = [0.0, 1.0]
    traj = Trajectory.from_arrays(t, {
        "ego": {"x": [0.0, 0.0], "y": [0.0, 0.0], "heading": [0.0, math.pi / 2],
                "vx": 0.0, "vy": 0.0},
        "other": {"x": [-4.0, 4.0], "y": [3.3, 3.3], "heading": [0.0, 0.0], "vx": 8.0, "vy": 0.0},
    })
    assert all(not a.intersects(b) for a, b in (traj.footprints(0), traj.footprints(1)))
    r = collision().evaluate(traj)
    assert r.rho < 0 and r.agent == "other" and 0.0 < r.t < 1.0
    # at the reported moment the interpolated footprints do overlap (shapely)
    u = r.t
    at = Trajectory.from_arrays([0.0], {
        "ego": {"x": [0.0], "y": [0.0], "heading": [u * math.pi / 2], "vx": 0.0, "vy": 0.0},
        "other": {"x": [-4.0 + 8.0 * u], "y": [3.3], "heading": [0.0], "vx": 0.0, "vy": 0.0},
    })
    ego, other = at.footprints(0)
    assert ego.intersection(other).area > 0


def hw_crash(other_vy, pushed=True):
    """The record highway-env leaves of a side swipe between samples: at t = 0 a car 0.3 m
    beside the ego moves toward it at ``other_vy`` m/s; highway-env predicts the contact,
    pushes the pair apart (so the t = 0.2 s sample shows them 0.05 m apart) and flags both."""
    y_other = [2.3, 2.05 if pushed else 2.3 + 0.2 * other_vy]
    return Trajectory.from_arrays([0.0, 0.2], {
        "ego": {"x": [0.0, 5.0], "y": [0.0, 0.0], "vx": 25.0, "vy": 0.0, "heading": 0.0,
                "crashed": [False, True]},
        "cutter": {"x": [1.0, 5.0], "y": y_other, "vx": 20.0, "vy": other_vy, "heading": 0.0,
                   "crashed": [False, True]},
    })


def test_a_crash_flag_between_steps_is_explained_by_the_swept_footprints():
    traj = hw_crash(-2.5)
    assert collision(use_crash_flag=False).evaluate(traj).ok  # no overlap, even interpolated
    r = collision().evaluate(traj)
    # at their recorded velocities the 0.3 m gap closes at 2.5 m/s: contact at 0.12 s,
    # 0.2 m deep by the end of the step
    assert r.agent == "cutter" and r.t == pytest.approx(0.12, abs=1e-3)
    assert r.rho == pytest.approx(-0.2, abs=1e-3) and "recorded velocities" in r.detail


def test_an_overlap_after_an_earlier_crash_flag_keeps_its_rho_and_the_first_contact():
    # as hw_crash(-2.5), then the pushed pair settles 1 mm into each other at t = 0.4 s
    traj = Trajectory.from_arrays([0.0, 0.2, 0.4], {
        "ego": {"x": [0.0, 5.0, 10.0], "y": [0.0, 0.0, 0.0], "vx": 25.0, "vy": 0.0,
                "heading": 0.0, "crashed": [False, True, True]},
        "cutter": {"x": [1.0, 5.0, 9.0], "y": [2.3, 2.05, 1.999], "vx": 20.0, "vy": [-2.5, 0, 0],
                   "heading": 0.0, "crashed": [False, True, True]},
    })
    r = collision().evaluate(traj)
    assert r.rho == pytest.approx(-0.001) and r.t == 0.4  # the step overlap, as always
    assert "flagged the ego's crash earlier, at t=0.20 s" in r.detail
    t, agent = first_violation(collision(), traj, r)
    assert agent == "cutter" and t == pytest.approx(0.12, abs=1e-3)


def test_a_crash_flag_nobody_explains_is_a_static_object():
    r = collision().evaluate(hw_crash(+2.5))  # the car moves away: something else hit the ego
    assert r.rho == collision().FLAG_RHO and r.agent is None and "static object" in r.detail


def test_a_crash_flag_from_highway_envs_swept_box_test_names_the_agent():
    # the step before a flagged crash in a highway-env run at dt = 0.2 s (a car cutting in
    # from the left, rounded): moving on at their velocities the two pass 0.14 m apart, but
    # highway-env's test, which projects on the four edge normals only, predicts a contact
    x, y = [[120.0, 125.1563], [115.9268, 119.2677]], [[-4.0, -4.0492], [-0.7617, -1.7219]]
    h, vx, vy = [[0.0, 0.0], [-0.3047, -0.2702]], [25.0, 17.3617], [0.0, -5.46]
    traj = Trajectory.from_arrays([0.8, 1.0], {
        name: {"x": x[i], "y": y[i], "heading": h[i], "vx": vx[i], "vy": vy[i],
               "crashed": [False, True]} for i, name in enumerate(("ego", "cutter"))})
    from shapely import affinity

    ego, cutter = traj.footprints(0)
    passes = [affinity.translate(ego, 25.0 * 0.2 * u, 0).distance(
        affinity.translate(cutter, vx[1] * 0.2 * u, vy[1] * 0.2 * u)) for u in np.linspace(0, 1, 501)]
    assert min(passes) > 0.1
    hw_utils = pytest.importorskip("highway_env.utils")
    a, b = (np.asarray(p.exterior.coords) for p in (ego, cutter))
    assert hw_utils.are_polygons_intersecting(a, b, np.array([5.0, 0.0]),
                                              np.array([vx[1], vy[1]]) * 0.2)[1]
    r = collision().evaluate(traj)
    assert r.agent == "cutter" and r.rho == collision().FLAG_RHO and r.t == 1.0
    assert "swept-box" in r.detail


def test_a_highway_env_side_swipe_at_5_hz_is_seen_between_the_steps():
    # a real run: the ego holds 25 m/s in the middle lane, a car beside it cuts in over 1.5 s;
    # at dt = 0.2 s highway-env flags the crash while no recorded step shows an overlap
    from pytest_avscenario.sim import World, behaviors as b

    world = World(seed=0, driver=lambda obs: (0.0, 0.0))
    road = world.straight_road(lanes=3, length=600.0, lane_width=4.0, speed_limit=30.0)
    world.ego(road.lane(1), s=100.0, speed=25.0)
    world.car(road.lane(0), s=100.0, speed=25.0, name="cutter",
              behavior=b.change_lane("right", at=0.5, duration=1.5))
    traj = world.run(seconds=2.0, dt=0.2)
    k = int(np.argmax(traj.crashed[0]))
    assert traj.crashed[0, k], "the scene no longer crashes"
    assert footprint_separation(traj)[0, :k + 1].min() > 0.1, "the crash shows at a step"
    r = collision().evaluate(traj)
    assert r.agent == "cutter" and traj.t[k - 1] < r.t < traj.t[k]
    assert r.rho < -0.1  # how deep the cutter would have gone had highway-env not pushed


def test_rounding_at_contact_is_touching_not_an_overlap():
    # highway-env pushes crashed cars exactly into contact; at x ~ 1e3 m the separation of
    # two cars nose to tail on a heading of 0.3 rad reads as -1.8e-14 m, which the monitor
    # must not report as an "overlap 1.8e-14 m deep"
    x, h = 1001.3, 0.3
    traj = Trajectory.from_arrays([0.0], {
        "ego": {"x": [x], "y": [0.2], "heading": [h], "vx": 1.0, "vy": 0.0},
        "other": {"x": [x + 5 * math.cos(h)], "y": [0.2 + 5 * math.sin(h)], "heading": [h],
                  "vx": 1.0, "vy": 0.0}})
    assert footprint_separation(traj)[0, 0] < 0
    assert collision(use_crash_flag=False).evaluate(traj).rho == 0.0


def test_swept_search_agrees_with_a_brute_force_sweep_on_a_fine_grid():
    # many agents crossing the ego's path at random places, speeds and turn rates: the
    # earliest contact found equals the first overlapping sub-step of 4000 per interval
    rng = np.random.default_rng(3)
    A, T, dt = 40, 4, 0.25
    t = np.arange(T) * dt
    agents = {"ego": {"x": 12.0 * t, "y": 0.0 * t, "vx": 12.0, "vy": 0.0,
                      "heading": 0.2 * t}}
    for a in range(1, A):
        x0, y0 = rng.uniform(-5, 15), rng.uniform(-25, -8)
        v, h0, w = rng.uniform(10, 40), rng.uniform(0.8, 2.3), rng.uniform(-1, 1)
        h = h0 + w * t
        agents[f"car{a}"] = {"x": x0 + v * np.cumsum(np.r_[0, np.cos(h[:-1]) * dt]),
                             "y": y0 + v * np.cumsum(np.r_[0, np.sin(h[:-1]) * dt]),
                             "vx": 0.0, "vy": 0.0, "heading": h}
    traj = Trajectory.from_arrays(t, agents)
    t_contact, depth = swept_contacts(traj)
    u = np.linspace(0.0, 1.0, 4001)
    checked = 0
    for a in range(1, A):
        for k in range(T - 1):
            sub = interpolate(traj, k, u, [0, a])
            sep = footprint_separation(sub)[0]
            overlapping = np.flatnonzero(sep < -1e-3)  # deeper than the search's tolerance
            if overlapping.size == 0:
                assert not depth[a - 1, k] > 1e-3
                continue
            checked += 1
            first = traj.t[k] + u[overlapping[0]] * dt
            assert t_contact[a - 1, k] <= first + 1e-9
            assert t_contact[a - 1, k] >= first - dt / 4000 - 1e-3  # within 1 mm of travel
            assert depth[a - 1, k] == pytest.approx(-sep.min(), abs=1e-3)  # the deepest moment
    assert checked >= 5


def interpolate(traj, k, u, rows):
    """Sub-steps ``u`` (fractions) of recorded interval k of agents ``rows``, poses linear."""
    out = {}
    for a in rows:
        dh = (traj.heading[a, k + 1] - traj.heading[a, k] + math.pi) % (2 * math.pi) - math.pi
        out[traj.names[a]] = {
            "x": traj.x[a, k] + u * (traj.x[a, k + 1] - traj.x[a, k]),
            "y": traj.y[a, k] + u * (traj.y[a, k + 1] - traj.y[a, k]),
            "heading": traj.heading[a, k] + u * dh, "vx": 0.0, "vy": 0.0,
            "length": traj.length[a], "width": traj.width[a]}
    return Trajectory.from_arrays(traj.t[k] + u * (traj.t[k + 1] - traj.t[k]), out)


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
    (lambda: ttc(2.0, radius=-1.0, kind="centre"), "radius"),
    (lambda: ttc(2.0, radius=0.0, kind="centre"), "radius"),
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

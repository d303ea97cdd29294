"""The criteria monitors share work per trajectory and take fast paths; each fast form is held
here to the plain definition it replaces, bit for bit, so their verdicts (ρ, time, agent) are
the definitions' own."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from pytest_avscenario.monitors import (
    MonitorError,
    brake_threat_number,
    ettc,
    off_road,
    on_sidewalk,
    outside_route_lanes,
    post_encroachment_time,
    ran_stop,
    required_deceleration,
    route_completion,
    time_to_brake,
    time_to_steer,
    wrong_way,
)
from pytest_avscenario.monitors import criticality as cr
from pytest_avscenario.monitors import road as rd
from pytest_avscenario.monitors.metrics import _sat_separation
from pytest_avscenario.trajectory import Trajectory


def test_the_time_to_brake_grid_test_is_required_deceleration_after_advancing():
    """``_too_hard`` fuses the ego's and the lead's advance and the required deceleration of
    the state reached; it must answer ``required_deceleration_values(...) > max`` exactly,
    also for braking, standing and reversing-free leads, closed gaps and NaN inputs."""
    rng = np.random.default_rng(0)
    n = 400
    gap = rng.uniform(-2.0, 80.0, n)
    v_e, v_l = rng.uniform(-1.0, 30.0, n), rng.choice([0.0, 3.0, 12.0, 25.0], n)
    a_e = rng.choice([0.0, -3.0, 1.5, -8.0], n) + rng.normal(0, 1e-3, n) * (rng.random(n) < 0.5)
    a_l = rng.choice([0.0, -2.0, -6.0, 1.0, 0.4], n)
    gap[::37] = np.nan
    a_l[5::41] = np.nan
    k = cr.LeadKinematics(gap=gap, lat=np.zeros(n), v_e=v_e, v_l=v_l, a_e=a_e, a_l=a_l,
                          width_l=np.full(n, 2.0), idx=np.arange(n), shape=(1, n))
    tau = np.concatenate([np.arange(0.0, 10.25, 0.5), rng.uniform(0, 10, 30), [1.25, 2.5]])
    with np.errstate(all="ignore"):
        got = cr._too_hard(tau, cr._pair_columns(k), 8.0)
        ve0, vl0 = np.maximum(v_e, 0.0)[:, None], np.maximum(v_l, 0.0)[:, None]
        de, ve = cr._advance(ve0, a_e[:, None], tau)
        dl, vl = cr._advance(vl0, a_l[:, None], tau)
        al = np.where(vl <= 0, 0.0, a_l[:, None])
        want = cr.required_deceleration_values(gap[:, None] + dl - de, ve, vl, al) > 8.0
    assert got.shape == want.shape and (got == want).all()
    assert want.any() and (~want).any()


def test_velocity_derivatives_at_the_pairs_equal_the_whole_derivative():
    rng = np.random.default_rng(1)
    for T in (1, 2, 3, 50):
        t = np.cumsum(rng.uniform(0.05, 0.2, T))
        v = rng.normal(size=(2, 4, T))
        rows = rng.integers(0, 4, size=(2, 30))
        cols = rng.integers(0, T, size=30)
        want = cr._derivative(v, t)[:, rows, cols]
        assert np.array_equal(cr._derivative_at(v, t, rows, cols), want)


@pytest.mark.parametrize("xy", [[[0.0, 0.0], [200.0, 0.0]], [[500.0, 1.535], [0.0, 1.535]],
                                [[3.0, -7.0], [-40.0, 91.0]]])
def test_a_straight_lane_projects_as_the_search_over_segments_does(xy):
    lane = rd._polyline("l", {"xy": xy, "width": 3.5})
    rng = np.random.default_rng(2)
    x, y = rng.uniform(-300, 600, 200), rng.uniform(-100, 100, 200)
    fast, slow = lane.project(x, y), lane._project_segments(x, y)
    for a, b in zip(fast, slow):
        assert np.array_equal(a, b)


def _drive(lane_ids, meta, n=60):
    t = np.arange(n) * 0.1
    x = 5.0 + 10.0 * t
    return Trajectory.from_arrays(t, {
        "ego": {"x": x, "y": 0.2 * np.sin(t), "lane": lane_ids},
        "car": {"x": x + 30.0, "y": 0 * t, "vx": 6.0, "vy": 0.0, "lane": "a"}}, meta=meta)


ROAD = {"lanes": {"a": {"xy": [[0, 0], [100, 0], [200, 5]], "width": 3.5, "group": "e"},
                  "b": {"xy": [[0, -3.5], [200, -3.5]], "width": 3.5, "group": "e"}},
        "ego_route": ["a"], "stops": [{"lane": "a", "s": 30.0, "kind": "stop"}]}


def test_the_one_lane_frame_and_route_projection_are_the_per_lane_ones():
    one = _drive("a", ROAD)
    # the same drive with the lane unknown at the last sample takes the per-lane path
    ids = np.array(["a"] * one.n_steps, dtype=object)
    ids[-1] = ""
    mixed = _drive(ids, ROAD)
    f1, f2 = rd.lane_frame(one), rd.lane_frame(mixed)
    for a, b in zip((f1.s, f1.r, f1.heading, f1.width), (f2.s, f2.r, f2.heading, f2.width)):
        assert np.array_equal(a[:-1], b[:-1])
    poly = rd.lanes_of(one)["a"]
    s, r, _ = poly._project_segments(one.x[0], one.y[0])
    assert np.array_equal(f1.s, s) and np.array_equal(f1.r, r)
    # route completion read off the lane frame equals the projection on the route
    assert route_completion(0.5).evaluate(one).rho == pytest.approx(
        (min(s[-1], poly.length) - s[0]) / (poly.length - s[0]) - 0.5, abs=1e-12)


def test_shared_results_belong_to_their_trajectory():
    """Every monitor on a trajectory, then on a prefix and on a copy: the per-trajectory
    memo never leaks a longer run's values into a shorter one."""
    full = _drive("a", ROAD)
    monitors = [off_road(), on_sidewalk(), wrong_way(), outside_route_lanes(), ran_stop(),
                route_completion(0.5), ettc(), required_deceleration(), brake_threat_number(),
                time_to_brake(), time_to_steer(), post_encroachment_time()]
    first = [m.evaluate(full) for m in monitors]
    short = full.prefix(20)
    for m, r in zip(monitors, first):
        fresh_short = m.evaluate(dataclasses.replace(short))
        assert m.evaluate(short) == fresh_short
        assert m.evaluate(dataclasses.replace(full)) == r
    assert route_completion(0.5).evaluate(short).rho < first[5].rho


def test_a_broken_agent_fails_the_monitors_that_read_it_and_only_those():
    traj = _drive("a", ROAD)
    heading = traj.heading.copy()
    heading[1, 10] = np.nan  # the car's heading, while it is present
    broken = dataclasses.replace(traj, heading=heading)
    assert ran_stop().evaluate(broken).agent == "ego"  # reads the ego only
    with pytest.raises(MonitorError, match=r"heading of agent 'car' is nan at t=1\.000 s"):
        ettc().evaluate(broken)


def _pet_brute_force(traj, min_angle_deg=30.0):
    """Every pair of samples of the ego and each agent, footprints overlapping and headings
    crossing: the smallest time apart."""
    out = []
    sin_min = math.sin(math.radians(min_angle_deg))
    for a in range(1, traj.n_agents):
        i, j = np.meshgrid(np.arange(traj.n_steps), np.arange(traj.n_steps), indexing="ij")
        i, j = i.ravel(), j.ravel()
        ok = traj.present[0, i] & traj.present[a, j]
        i, j = i[ok], j[ok]
        sep = _sat_separation(traj.x[0, i], traj.y[0, i], traj.heading[0, i],
                              traj.length[0] / 2, traj.width[0] / 2, traj.x[a, j],
                              traj.y[a, j], traj.heading[a, j], traj.length[a] / 2,
                              traj.width[a] / 2)
        cross = np.abs(np.sin(traj.heading[a, j] - traj.heading[0, i])) >= sin_min
        hit = (sep <= 1e-9) & cross
        out.append(float(np.abs(traj.t[i[hit]] - traj.t[j[hit]]).min()) if hit.any()
                   else math.inf)
    return np.array(out)


def _crossing_scene(seed):
    """The ego east along y = 0 and four road users on straight paths at random angles,
    speeds and start times (some cross it, some not)."""
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, 8.0, 0.1)
    agents = {"ego": {"x": -30 + rng.uniform(6, 12) * t, "y": 0.3 * np.sin(t)}}
    for a in range(4):
        ang = rng.choice([0.0, math.pi / 2, -math.pi / 2, 0.6, math.pi])
        v = rng.uniform(1, 12)
        x0, y0 = rng.uniform(-10, 30), rng.uniform(-25, 25)
        present = t >= rng.uniform(0, 3)
        agents[f"a{a}"] = {"x": np.where(present, x0 + v * math.cos(ang) * t, np.nan),
                           "y": np.where(present, y0 + v * math.sin(ang) * t, np.nan),
                           "vx": v * math.cos(ang), "vy": v * math.sin(ang), "heading": ang,
                           "present": present, "kind": "pedestrian" if a == 0 else "car"}
    return Trajectory.from_arrays(t, agents)


def test_post_encroachment_time_equals_a_search_of_every_sample_pair():
    pets = []
    for seed in range(6):
        traj = _crossing_scene(seed)
        pet, _, _ = cr.pet_values(traj)
        assert np.array_equal(pet, _pet_brute_force(traj)), seed
        pets.append(pet)
    pets = np.concatenate(pets)
    assert np.isfinite(pets).sum() >= 3 and np.isinf(pets).sum() >= 3  # both kinds of case


def test_time_to_brake_for_a_verdict_refines_only_what_can_be_smallest():
    rng = np.random.default_rng(4)
    for case in range(30):
        n = int(rng.integers(1, 40))
        k = cr.LeadKinematics(
            gap=rng.uniform(1.0, 90.0, n), lat=np.zeros(n), v_e=rng.uniform(5, 30, n),
            v_l=rng.uniform(0, 20, n), a_e=rng.uniform(-1, 2, n),
            a_l=rng.choice([0.0, -1.0, -4.0, 0.5], n), width_l=np.full(n, 2.0),
            idx=np.arange(n), shape=(1, n))
        full = cr.time_to_brake_values(k, 8.0)
        fast = cr.time_to_brake_values(k, 8.0, smallest_only=True)
        assert (fast <= full).all(), case  # the others are lower bounds...
        smallest = full.min()
        assert fast.min() == smallest, case  # ...above the exact smallest
        assert np.array_equal(fast == smallest, full == smallest), case

"""The default distance and TTC judge the road users in the ego's path: a car passing in the
next lane is not a conflict, a car ahead in the lane or one cutting in is. The paper's centre
definitions stay available as ``kind="centre"``."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings

from pytest_avscenario.monitors import MonitorError, MonitorSet, distance, ttc
from pytest_avscenario.monitors.metrics import footprint_ttc, in_path
from pytest_avscenario.trajectory import Trajectory

from test_monitors_properties import build, pairs, scenes

T = np.arange(0.0, 5.0, 0.1)
EGO = {"x": 20.0 * T, "y": 0.0 * T, "vx": 20.0, "vy": 0.0}


def rho(**agents):
    traj = Trajectory.from_arrays(T, {"ego": EGO, **agents})
    return MonitorSet([ttc(2.0), distance(5.0), ttc(2.0, kind="centre", name="ttc_centre"),
                       distance(5.0, kind="centre", name="distance_centre")]).evaluate(traj).rho


def test_a_car_in_the_next_lane_of_a_highway_is_no_conflict():
    # 3.75 m lanes: a slower car 5 m ahead in the next lane, overtaken by the ego
    r = rho(other={"x": 5.0 + 15.0 * T, "y": 3.75 + 0 * T, "vx": 15.0, "vy": 0.0})
    assert r["ttc"] == math.inf and r["distance"] == math.inf
    # ... while the paper's centre metrics fail it at t = 0 (centres 6.3 m, then 3.75 m apart)
    assert r["ttc_centre"] == -2.0 and r["distance_centre"] == pytest.approx(3.75 - 5.0)


def test_a_car_ahead_in_the_lane_is_a_conflict():
    # 15 m ahead, 5 m/s slower: the bumpers (5-m cars) meet after (15 - 5) / 5 = 2 s
    traj = Trajectory.from_arrays([0.0], {"ego": {"x": 0.0, "y": 0.0, "vx": 20.0, "vy": 0.0},
                                          "lead": {"x": 15.0, "y": 0.3, "vx": 15.0, "vy": 0.0}})
    assert footprint_ttc(traj)[0, 0] == pytest.approx((15.0 - 5.0) / 5.0)
    assert ttc(2.5).evaluate(traj).rho == pytest.approx(2.0 - 2.5)
    # in a line the footprint TTC is the paper's with a circle of one car length
    assert ttc(2.5, kind="centre", radius=5.0).evaluate(traj).rho == pytest.approx(
        ttc(2.5).evaluate(traj).rho, abs=0.01)
    r = rho(lead={"x": 4.5 + 20.0 * T, "y": 0 * T, "vx": 20.0, "vy": 0.0})
    assert r["distance"] == pytest.approx(4.5 - 5.0)


def test_a_car_cutting_in_is_a_conflict_before_it_reaches_the_lane():
    y = np.maximum(3.75 - 1.0 * T, 0.0)
    cut = {"x": 12.0 + 18.0 * T, "y": y, "vx": 18.0, "vy": np.where(y > 0, -1.0, 0.0)}
    traj = Trajectory.from_arrays(T, {"ego": EGO, "cutter": cut})
    res = ttc(2.0).evaluate(traj)
    assert res.rho < 0 and res.agent == "cutter"
    # the first TTC violation comes while the cutter is still across the lane line
    first = np.flatnonzero(footprint_ttc(traj)[0] < 2.0)[0]
    assert y[first] > 1.75
    assert distance(5.0).evaluate(traj).rho < 0


def test_path_means_ahead_in_the_direction_of_travel():
    # a car 6 m behind in the lane is not in the path of an ego driving forward ...
    behind = {"x": -6.0 + 20.0 * T, "y": 0 * T, "vx": 20.0, "vy": 0.0}
    assert rho(behind=behind)["distance"] == math.inf
    # ... but it is for an ego reversing toward it
    traj = Trajectory.from_arrays(T, {"ego": {"x": -1.0 * T, "y": 0 * T, "vx": -1.0, "vy": 0.0},
                                      "parked": {"x": -6.0 + 0 * T, "y": 0 * T, "vx": 0.0, "vy": 0.0}})
    assert in_path(traj)[0].all()
    assert distance(5.0).evaluate(traj).rho == pytest.approx((6.0 - 4.9) - 5.0)


def test_a_crossing_car_meets_the_ego_footprint_in_time():
    # perpendicular approach: the crossing car's nose reaches the ego's side at t = 1 s
    traj = Trajectory.from_arrays([0.0], {
        "ego": {"x": 0.0, "y": 0.0, "vx": 0.0, "vy": 0.0, "heading": 0.0},
        "cross": {"x": 0.0, "y": -13.5, "vx": 0.0, "vy": 10.0, "heading": math.pi / 2}})
    # ego half width 1 m, crossing car half length 2.5 m: gap 13.5 - 3.5 = 10 m at 10 m/s
    assert footprint_ttc(traj)[0, 0] == pytest.approx(1.0)


def test_kind_is_checked_and_radius_belongs_to_the_circle():
    with pytest.raises(MonitorError, match="kind must be one of 'path', 'centre'"):
        ttc(2.0, kind="circle")
    with pytest.raises(MonitorError, match="radius applies to the paper's circle"):
        ttc(2.0, radius=3.5)
    with pytest.raises(MonitorError, match="kind must be one of"):
        distance(5.0, kind="lane")
    assert ttc(2.0, kind="centre").radius == 5.0
    assert distance(1.0, footprint=True).kind == "footprint"


@settings(max_examples=100, deadline=None)
@given(scenes())
def test_footprint_ttc_agrees_with_shapely_on_the_extrapolated_footprints(s):
    """Where the footprint TTC is finite the footprints, moved on at their velocities, touch
    at that moment and were apart just before; where it is infinite (and the agent is ahead)
    they stay apart for the next 60 s."""
    import shapely
    from shapely import affinity

    traj = build(s)
    ours = footprint_ttc(traj)
    ahead = in_path(traj, math.inf)
    for a, k in pairs(s):
        if not ahead[a - 1, k]:
            assert ours[a - 1, k] == math.inf
            continue
        ego, other = traj.footprints(k)[0], traj.footprints(k)[a]
        dvx = s["vx"][a, k] - s["vx"][0, k]
        dvy = s["vy"][a, k] - s["vy"][0, k]
        at = lambda t: shapely.distance(ego, affinity.translate(other, dvx * t, dvy * t))
        got = ours[a - 1, k]
        if got == math.inf:
            assert min(at(t) for t in np.linspace(0, 60, 601)) > 0
        elif got == 0:
            assert at(0.0) == pytest.approx(0.0, abs=1e-7)
        else:
            assert at(got) == pytest.approx(0.0, abs=1e-6)
            assert at(got * (1 - 1e-3)) > 0

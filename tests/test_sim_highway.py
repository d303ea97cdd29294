"""Highways (curves, on-ramps, lane drops), triggers and speed profiles: what a scenario
author relies on when writing a motorway scenario."""

from __future__ import annotations

import math

import numpy as np
import pytest

from pytest_avscenario.sim import SimError, World
from pytest_avscenario.sim import behaviors as b
from pytest_avscenario.sim.highway import arc, straight


def test_curved_highway_geometry_and_lane_numbering():
    w = World(seed=0, driver="idm", name="t")
    road = w.highway(lanes=3, segments=[straight(100), arc(radius=200, angle=90),
                                        arc(radius=300, angle=-45)], lane_width=4.0)
    # Lane 0 leftmost, lanes to its right 4 m apart, as on every road here.
    assert [l.number for l in road.segments[0]] == [0, 1, 2]
    assert road.lane(2).position(50)[1] == pytest.approx(-8.0)
    bend = road.segments[1]
    # A left bend: centre (100, 200); lane i has radius 200 + 4 i and turns 90 degrees.
    for i, lane in enumerate(bend):
        r = 200 + 4.0 * i
        assert lane.length == pytest.approx(r * math.pi / 2)
        mid = lane.position(lane.length / 2)
        assert math.hypot(mid[0] - 100, mid[1] - 200) == pytest.approx(r)
        assert lane.heading_at(lane.length / 2) == pytest.approx(math.pi / 4)
        assert lane.heading_at(lane.length) == pytest.approx(math.pi / 2)
        # Continuous with the straight before it, in the same lane.
        assert np.allclose(lane.position(0), road.segments[0][i].position(100))
    # The right bend after it: headings back to 45 degrees, lane 2 now on the inside.
    right = road.segments[2]
    assert right[0].heading_at(right[0].length) == pytest.approx(math.pi / 4)
    assert right[2].length < right[0].length
    # Stations run along lane 0; the lanes beside are at the same angle into a bend.
    spot = road.at(100 + 100 * math.pi / 2, lane=2)
    assert spot.lane is bend[2] and spot.s == pytest.approx(bend[2].length / 2)
    # The lane index follows lane i through every segment.
    route = w.road.default_route(road.lane(1))
    assert [l.id for l in route.lanes] == ["lane[1]@0", "lane[1]@1", "lane[1]@2"]


@pytest.mark.parametrize("driver", ["autopilot", "idm", "careful"])
def test_every_ego_driver_keeps_its_lane_through_the_bends(driver):
    w = World(seed=0, driver=driver, name="t")
    road = w.highway(lanes=2, segments=[straight(50), arc(250, 40), arc(250, -40),
                                        straight(100)])
    w.ego(road.at(10, lane=1), speed=20.0, target_speed=20.0)
    tr = w.run(seconds=22)
    assert not tr.crashed[0].any()
    assert np.nanmax(np.abs(tr.lane_offset[0])) < 0.5
    i = tr.names.index("ego")
    lanes = set(tr.lane[i][tr.present[i]])
    assert lanes <= {"lane[1]@0", "lane[1]@1", "lane[1]@2", "lane[1]@3"}
    assert "lane[1]@3" in lanes  # made it through both bends


def test_on_ramp_car_merges_into_the_rightmost_lane():
    w = World(seed=0, driver="idm", name="t")
    road = w.highway(lanes=2, segments=[straight(600)])
    ramp = road.on_ramp(at=150, merge_length=100)
    assert road.merge_lane().end.position[1] == pytest.approx(-7.5)  # beside lane 1
    w.ego(road.at(0, lane=0), speed=20.0)
    # a car in lane 1 that the merging one has to find a gap around
    w.car(road.at(160, lane=1), speed=15.0, name="main")
    w.car(ramp, s=40, speed=15.0, name="ramp")
    tr = w.run(seconds=20)
    k = tr.names.index("ramp")
    assert not tr.crashed[k].any()
    assert tr.lane[k][-1] == "lane[1]@0"  # on the main road, in the rightmost lane
    assert tr.y[k][-1] == pytest.approx(-3.75, abs=0.3)
    merged = np.flatnonzero(tr.lane[k] == "lane[1]@0")[0]
    assert 150.0 <= tr.x[k][merged] <= 250.0 + 2.5  # joined along the acceleration lane


def test_lane_drop_traffic_merges_before_its_lane_ends():
    w = World(seed=0, driver="idm", name="t")
    road = w.highway(lanes=3, segments=[straight(200), straight(300, lanes=2)])
    assert road.lane_ends and road.lane_ends[0].lane is road.lane(2)
    w.ego(road.at(0, lane=0), speed=20.0)
    w.car(road.at(20, lane=2), speed=18.0, name="dropped")
    w.car(road.at(40, lane=1), speed=18.0, name="beside")
    tr = w.run(seconds=18)
    k = tr.names.index("dropped")
    assert not tr.crashed[k].any()
    assert tr.lane[k][-1] == "lane[1]@1"
    assert np.all(tr.x[k][tr.lane[k] == "lane[2]@0"] <= 200.0)


def test_time_gap_trigger_starts_the_cut_in_when_the_ego_is_that_close():
    w = World(seed=0, driver="idm", name="t")
    road = w.highway(lanes=2, segments=[straight(800)])
    v_ego, v_cut, tg = 25.0, 15.0, 1.0
    w.ego(road.at(0, lane=0), speed=v_ego, target_speed=v_ego)
    w.car(road.at(80, lane=1), speed=v_cut, name="cutter",
          behavior=b.cut_in(time_gap=tg, lateral_speed=1.5))
    tr = w.run(seconds=8)
    k = tr.names.index("cutter")
    gap = (tr.x[k] - tr.x[0]) - 5.0  # bumper to bumper, both on straight lanes
    due = np.flatnonzero(gap < tg * tr.speed[0])[0]
    moved = np.flatnonzero(tr.y[k] > -3.75 + 0.05)[0]
    # it turns toward the ego's lane in the step after the one the time gap drops below 1 s
    assert due <= moved <= due + 3
    assert tr.lane[k][-1] == "lane[0]@0"
    # lateral speed as asked: across 3.75 m at 1.5 m/s takes 2.5 s (plus the settling lag)
    across = np.flatnonzero(tr.y[k] > -0.5)[0]
    assert 2.0 <= tr.t[across] - tr.t[moved] <= 3.8


def test_gap_trigger_brakes_for_another_agent():
    w = World(seed=0, driver="idm", name="t")
    road = w.highway(lanes=2, segments=[straight(600)])
    w.ego(road.at(0), speed=10.0)
    w.car(road.at(50), speed=20.0, name="lead",
          behavior=b.brake_at(when=b.gap_below(30.0, "stopped"), decel=4.0))
    # in the next lane, so the lead's car following does not brake for it first
    w.car(road.at(300, lane=1), speed=0.0, name="stopped", behavior=b.stopped())
    tr = w.run(seconds=16)
    k = tr.names.index("lead")
    gap = tr.x[tr.names.index("stopped")] - tr.x[k] - 5.0
    braking = np.flatnonzero(np.diff(tr.speed[k]) < -0.3)[0]
    assert gap[braking] == pytest.approx(30.0, abs=20.0 * 0.1 + 0.5)
    assert not tr.crashed[k].any() and tr.speed[k][-1] == pytest.approx(0.0, abs=0.05)


def test_speed_profile_by_time_and_by_distance():
    w = World(seed=0, driver="idm", name="t")
    road = w.highway(lanes=2, segments=[straight(1000)])
    w.ego(road.at(0, lane=0), speed=10.0)
    w.car(road.at(50, lane=1), speed=20.0, name="timed",
          behavior=b.speed_profile([(2.0, 20.0), (6.0, 10.0), (8.0, 10.0), (10.0, 16.0)]))
    w.car(road.at(20, lane=0), speed=10.0, name="placed",
          behavior=b.speed_profile([(0.0, 10.0), (100.0, 20.0)], by="distance", max_accel=1.0))
    tr = w.run(seconds=14)
    k = tr.names.index("timed")
    at = lambda t: float(tr.speed[k][int(round(t / 0.1))])  # noqa: E731
    assert at(1.5) == pytest.approx(20.0, abs=0.2)
    assert at(4.0) == pytest.approx(15.0, abs=0.6)  # halfway down the ramp
    assert at(7.0) == pytest.approx(10.0, abs=0.3)
    assert at(13.0) == pytest.approx(16.0, abs=0.3)  # held beyond the last point
    j = tr.names.index("placed")
    acc = np.diff(tr.speed[j]) / 0.1
    assert acc.max() <= 1.0 + 1e-6  # the acceleration limit holds
    assert tr.speed[j][-1] == pytest.approx(20.0, abs=0.3)


@pytest.mark.parametrize("behavior, words", [
    (lambda: b.speed_profile([]), "speed_profile(points=()): need at least one"),
    (lambda: b.speed_profile([(3.0, 10.0), (1.0, 5.0)]), "must increase strictly"),
    (lambda: b.speed_profile([(0.0, -1.0)]), "speed >= 0"),
    (lambda: b.speed_profile([(0.0, 5.0)], by="space"), "by='space'"),
    (lambda: b.cut_in(time_gap=-1.0), "time_gap_below(seconds)=-1.0"),
    (lambda: b.cut_in(), "exactly one of time_gap="),
    (lambda: b.cut_out(gap=20.0), "ahead="),
    (lambda: b.change_lane(when=b.gap_below(-5)), "gap_below(metres)=-5"),
    (lambda: b.change_lane(when=3.0), "need a trigger"),
    (lambda: b.change_lane(lateral_speed=0.0), "lateral_speed"),
])
def test_bad_behaviour_input_names_test_agent_and_parameter(behavior, words):
    w = World(seed=0, driver="idm", name="test_x[halton-000]")
    road = w.highway(lanes=2, segments=[straight(300)])
    w.ego(road.at(0, lane=0), speed=10.0)
    with pytest.raises(SimError) as err:
        w.car(road.at(50, lane=1), speed=10.0, behavior=behavior(), name="adv")
    msg = str(err.value)
    assert "test_x[halton-000]" in msg and "'adv'" in msg and words in msg


@pytest.mark.parametrize("call, words", [
    (lambda w: w.highway(segments=[]), "non-empty list"),
    (lambda w: w.highway(segments=[straight(-5)]), "segment 0 (straight): length=-5"),
    (lambda w: w.highway(segments=[arc(100, 0)]), "angle=0"),
    (lambda w: w.highway(lanes=3, segments=[arc(5, -30)]), "too small for 3 lanes"),
    (lambda w: w.highway(lanes=0), "lanes=0"),
    (lambda w: w.highway(segments=[straight(100)]).on_ramp(at=50, merge_length=100),
     "must lie on one straight segment"),
    (lambda w: w.highway(segments=[straight(100)]).at(150), "highway.at(s=150)"),
])
def test_bad_highway_input_is_a_clear_error(call, words):
    w = World(seed=0, driver="idm", name="test_y")
    with pytest.raises(SimError) as err:
        call(w)
    assert "test_y" in str(err.value) and words in str(err.value)


def test_bad_profile_in_a_scenario_is_an_error_naming_the_test(pytester):
    pytester.makepyfile(
        """
        from pytest_avscenario import Uniform, scenario
        from pytest_avscenario.monitors import collision
        from pytest_avscenario.sim import behaviors as b
        from pytest_avscenario.sim.highway import straight

        @scenario(v=Uniform(10.0, 20.0), samples=1, monitors=[collision()])
        def test_profile(case, world):
            road = world.highway(lanes=2, segments=[straight(300)])
            world.ego(road.at(0, lane=0), speed=case.v)
            world.car(road.at(40, lane=1), speed=10.0, name="lead",
                      behavior=b.speed_profile([(4.0, 10.0), (2.0, 0.0)]))
            world.run(seconds=2)
        """
    )
    result = pytester.runpytest("-p", "no:cacheprovider", "--avs-seed=0", "--avs-db", "none")
    result.assert_outcomes(errors=1)
    result.stdout.fnmatch_lines(["*test_profile*agent 'lead'*speed_profile(points=...)*"
                                 "must increase strictly*"])


def test_an_ego_whose_lane_ends_is_refused_for_drivers_that_do_not_merge():
    from pytest_avscenario.sim.errors import SimError
    from pytest_avscenario.sim.highway import straight
    from pytest_avscenario.sim.world import World

    for driver in ("autopilot", "careful"):
        w = World(name="test_drop", seed=1)
        road = w.highway(lanes=2, segments=[straight(200), straight(300, lanes=1)])
        with pytest.raises(SimError, match=rf"test_drop.*lane\[1\]@0, a lane that ends, and the {driver} driver"):
            w.ego(road.at(10, lane=1), speed=20, driver=driver)
    w = World(name="test_drop", seed=1)  # highway-env's IDM merges off the ending lane
    road = w.highway(lanes=2, segments=[straight(200), straight(300, lanes=1)])
    w.ego(road.at(10, lane=1), speed=20, driver="idm")
    w.run(seconds=15)
    assert abs(float(w.trajectory.y[0, -1])) < 0.5  # in the lane that continues

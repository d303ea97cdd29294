"""Traffic-rule criteria (CARLA's names), criticality measures (CriMe's names) and the
Leaderboard's driving score, each against a closed form on a trajectory built by hand, and
on a simulated intersection."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest

from pytest_avscenario.monitors import (
    MonitorError,
    blocked,
    brake_threat_number,
    driving_score,
    ettc,
    min_speed_route,
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
from pytest_avscenario.monitors.criticality import (
    ettc_values,
    required_deceleration_values,
)
from pytest_avscenario.trajectory import Trajectory

# one straight lane east along y = 0 from x = 0 to 200 (3.5 m wide), the one beside it
# (y = -3.5) in the same carriageway and the opposite lane (y = 3.5) heading west
ROAD = {
    "lanes": {
        "a": {"xy": [[0, 0], [200, 0]], "width": 3.5, "group": "east", "kind": "travel"},
        "b": {"xy": [[0, -3.5], [200, -3.5]], "width": 3.5, "group": "east", "kind": "travel"},
        "w": {"xy": [[200, 3.5], [0, 3.5]], "width": 3.5, "group": "west", "kind": "travel"},
    },
    "stops": [{"lane": "a", "s": 50.0, "kind": "stop"}],
    "ego_route": ["a"],
}


def following(v_e, v_l, a_l, gap, *, a_e=0.0, heading=0.0, T=2.0, dt=0.05, lane="a"):
    """Ego and lead on one line along ``heading`` with constant accelerations; bumper gap
    ``gap`` [m] at t = 0 (5-m cars)."""
    t = np.arange(0.0, T + dt / 2, dt)
    c, s = math.cos(heading), math.sin(heading)
    se = v_e * t + 0.5 * a_e * t * t
    sl = gap + 5.0 + v_l * t + 0.5 * a_l * t * t
    ve = v_e + a_e * t
    vl = v_l + a_l * t
    return Trajectory.from_arrays(t, {
        "ego": {"x": se * c, "y": se * s, "vx": ve * c, "vy": ve * s, "heading": heading,
                "lane": lane},
        "lead": {"x": sl * c, "y": sl * s, "vx": vl * c, "vy": vl * s, "heading": heading,
                 "lane": lane},
    }, meta=ROAD)


# -- criticality: closed forms ------------------------------------------------------------------

@pytest.mark.parametrize("heading", [0.0, math.pi, math.pi / 2, -2.0])
def test_required_deceleration_of_an_accelerating_lead_in_any_direction(heading):
    # u = 10 m/s closing on 25 m, lead +1 m/s²: a_req = u²/(2g) - a_l = 2 - 1 = 1 m/s²
    traj = following(20.0, 10.0, 1.0, 25.0, heading=heading)
    assert required_deceleration(4.0).series(traj)[0] == pytest.approx(3.0, abs=1e-9)
    # BTN = 1 / 8 against the default 8 m/s² capability
    assert brake_threat_number(1.0).series(traj)[0] == pytest.approx(1 - 1 / 8, abs=1e-9)


def test_required_deceleration_behind_a_lead_that_brakes_to_a_stop():
    # lead 10 m/s braking 2 m/s² stops after 5 s and 25 m; the speeds would match only at
    # 6 s, so the ego must stop behind it: 20² / (2 (30 + 25)) = 3.636 m/s²
    traj = following(20.0, 10.0, -2.0, 30.0)
    assert 4.0 - required_deceleration(4.0).series(traj)[0] == pytest.approx(400 / 110, rel=1e-9)
    # a standing lead: v² / 2g
    assert float(required_deceleration_values(20.0, 10.0, 0.0, 0.0)) == pytest.approx(2.5)
    # speeds match before the lead stops: u²/2g - a_l = 4 + 1 = 5 (t* = 10 / (5-1) = 2.5 s < 10 s)
    assert float(required_deceleration_values(12.5, 20.0, 10.0, -1.0)) == pytest.approx(5.0)
    # not closing and the lead not braking: nothing needed
    assert float(required_deceleration_values(10.0, 10.0, 12.0, 0.5)) == 0.0


def test_ettc_keeps_the_sign_of_the_lead_acceleration():
    # 30 - 10 t - t² = 0 -> t = -5 + sqrt(55); dropping the sign of a_l = -2 (CriMe) would
    # give 30 - 10 t + t², which never reaches 0
    traj = following(20.0, 10.0, -2.0, 30.0)
    r = ettc(2.0).evaluate(traj)
    assert ettc(2.0).series(traj)[0] + 2.0 == pytest.approx(-5 + math.sqrt(55), rel=1e-9)
    assert r.agent == "lead" and r.rho < ettc(2.0).series(traj)[0]  # it only gets closer
    assert float(ettc_values(30.0, 20.0, 10.0, 0.0, 2.0)) == math.inf
    assert float(ettc_values(30.0, 20.0, 10.0, 0.0, 0.0)) == pytest.approx(3.0)


def test_time_to_brake_and_to_steer_behind_a_standing_car():
    # 20 m/s toward a standing car 50 m ahead, 8 m/s² brakes: braking must start when
    # 400 / (2 (50 - 20 τ)) = 8, at τ = 1.25 s; steering 2 m aside at 5 m/s² takes
    # sqrt(0.8) s, so it must start by 50/20 - sqrt(0.8)
    traj = following(20.0, 0.0, 0.0, 50.0)
    assert time_to_brake(0.0).series(traj)[0] == pytest.approx(1.25, abs=1e-6)
    assert time_to_steer(0.0).series(traj)[0] == pytest.approx(2.5 - math.sqrt(0.8), rel=1e-9)
    r = time_to_brake(1.0).evaluate(traj)
    assert r.rho < 0 and r.agent == "lead"  # 1.25 s at first, then less


def test_nothing_ahead_is_infinitely_safe():
    traj = following(10.0, 20.0, 0.0, 30.0)  # the lead pulls away
    for mon in (required_deceleration(), ettc(), time_to_brake()):
        assert mon.evaluate(traj).rho > 0
    assert ettc().evaluate(traj).rho == math.inf


def crossing(t_ego_leaves, t_other_enters, dt=0.05):
    """Ego east along y = 0 and a car north along x = 0 at 10 m/s, 5 x 2 m: the ego's rear
    leaves the 2 x 2 m square both cover (x = 1) at ``t_ego_leaves`` and the other's front
    reaches it (y = -1) at ``t_other_enters``."""
    t = np.arange(0.0, 10.0 + dt / 2, dt)
    xe = 3.5 + 10.0 * (t - t_ego_leaves)
    yo = -3.5 + 10.0 * (t - t_other_enters)
    return Trajectory.from_arrays(t, {
        "ego": {"x": xe, "y": 0 * t, "vx": 10.0, "vy": 0.0},
        "cross": {"x": 0 * t, "y": yo, "vx": 0.0, "vy": 10.0},
        "follower": {"x": xe - 20.0, "y": 0 * t, "vx": 10.0, "vy": 0.0},  # same path: no PET
    })


def test_post_encroachment_time_of_a_car_crossing_the_junction():
    r = post_encroachment_time(1.0).evaluate(crossing(2.35, 4.65))
    assert r.rho == pytest.approx(2.3 - 1.0, abs=1e-9)
    assert r.agent == "cross" and r.t == pytest.approx(4.65)
    # the other way round (the crossing car first) is the same measure
    r = post_encroachment_time(1.0).evaluate(crossing(8.0, 5.0))
    # the other's rear leaves y = 1 at 5 + 0.7 s; the ego's front reaches x = -1 at 8 - 0.7 s
    assert r.rho + 1.0 == pytest.approx(8.0 - 0.7 - (5.0 + 0.7), abs=1e-9)
    assert r.t == pytest.approx(7.3)


def test_post_encroachment_time_is_zero_for_a_collision():
    r = post_encroachment_time(0.5).evaluate(crossing(3.0, 2.5))
    assert r.rho == pytest.approx(-0.5) and r.agent == "cross"


# -- rules of the road -------------------------------------------------------------------------

def drive(x, *, y=0.0, lane="a", t=None, on_road=True, extra=None, meta=ROAD, dt=0.1, vx=None):
    t = np.arange(len(x)) * dt if t is None else t
    agents = {"ego": {"x": np.asarray(x, float), "y": np.broadcast_to(y, len(t)).astype(float),
                      "lane": lane, "on_road": on_road}}
    if vx is not None:
        agents["ego"].update(vx=vx, vy=0.0)
    agents.update(extra or {})
    return Trajectory.from_arrays(t, agents, meta=meta)


def test_ran_stop_at_a_known_speed_and_a_proper_stop():
    t = np.arange(0.0, 8.0, 0.1)
    r = ran_stop().evaluate(drive(10.0 * t))  # 10 m/s over the line at s = 50
    assert r.rho == pytest.approx(0.5 - 10.0, abs=1e-6) and not r.ok
    assert r.t == pytest.approx(4.9)  # the front bumper (centre + 2.5 m) passes 51 m
    # brake to stand with the front bumper 1 m before the line, wait 2 s, go
    x = np.concatenate([np.linspace(0, 46.5, 40), np.full(20, 46.5), 46.5 + np.arange(1, 30)])
    r = ran_stop().evaluate(drive(x))
    assert r.rho == pytest.approx(0.5) and r.ok
    assert ran_stop().evaluate(drive(10.0 * t[:30])).rho == math.inf  # never reached it


def test_wrong_way_counts_the_metres_driven_against_the_lane():
    t = np.arange(0.0, 3.01, 0.1)
    r = wrong_way().evaluate(drive(100.0 - 10.0 * t))  # westward in an eastbound lane
    assert r.rho == pytest.approx(-30.0) and r.t == 0.0
    assert wrong_way().evaluate(drive(100.0 + 10.0 * t)).rho == 0.0
    # the same westward drive in the westbound lane is right
    assert wrong_way().evaluate(drive(100.0 - 10.0 * t, y=3.5, lane="w")).rho == 0.0


def test_blocked_when_standing_longer_than_allowed():
    t = np.arange(0.0, 15.0, 0.1)
    v = np.where(t < 1.95, 5.0, 0.0)  # stands from t = 2 s to the end (14.9 s)
    x = np.minimum(5.0 * t, 10.0)
    r = blocked(10.0).evaluate(drive(x, t=t, vx=v))
    assert r.rho == pytest.approx(10.0 - 12.9, abs=1e-9) and r.t == pytest.approx(12.1)
    assert blocked(13.0).evaluate(drive(x, t=t, vx=v)).rho == pytest.approx(0.1, abs=1e-9)
    assert blocked(10.0).series(drive(x, t=t, vx=v))[-1] == pytest.approx(-2.9)


def test_route_completion_outside_route_lanes_on_sidewalk_and_min_speed():
    t = np.arange(0.0, 10.0, 0.1)
    half = drive(10.0 * t)  # 99 m of the 200-m route
    assert route_completion(0.5).evaluate(half).rho == pytest.approx(0.495 - 0.5)
    # three samples in the opposite lane (outside the route), one beside in the same direction
    lane = np.array(["a"] * 100, dtype=object)
    lane[50:53] = "w"
    lane[60:70] = "b"
    r = outside_route_lanes().evaluate(drive(10.0 * t, lane=lane))
    assert r.rho == pytest.approx(-3.0) and r.t == pytest.approx(5.0)
    # 1 m beyond the outer edge of lane b, off the road: sidewalk; 3 m beyond: off road only
    y = np.where((t > 4) & (t < 5.05), -3.5 - 1.75 - 1.0, 0.0)
    r = on_sidewalk().evaluate(drive(10.0 * t, y=y, lane=np.where(y < 0, "b", "a"),
                                     on_road=y == 0))
    assert r.rho < 0 and r.t == pytest.approx(4.1)
    assert off_road().evaluate(drive(10.0 * t, y=y, on_road=y == 0)).rho < 0
    far = np.where(y < 0, -3.5 - 1.75 - 3.0, 0.0)
    assert on_sidewalk().evaluate(drive(10.0 * t, y=far, lane=np.where(far < 0, "b", "a"),
                                        on_road=far == 0)).rho == 0.0
    traffic = {"car": {"x": 20 + 10.0 * t, "y": -3.5 + 0 * t}, "ped": {"x": 0 * t, "y": 5 + t,
                                                                       "kind": "pedestrian"}}
    r = min_speed_route(0.9).evaluate(drive(5.0 * t, extra=traffic))
    assert r.rho == pytest.approx(0.5 - 0.9, rel=1e-6)


def test_rule_monitors_need_the_road_and_say_so():
    plain = Trajectory.from_arrays([0.0, 0.1], {"ego": {"x": [0, 1], "y": [0, 0], "lane": "a"}})
    for mon in (wrong_way(), ran_stop(), route_completion(), outside_route_lanes()):
        with pytest.raises(MonitorError, match="meta"):
            mon.evaluate(plain)
    assert driving_score(plain) is None


def test_thresholds_match_the_worlds_all_way_stop_rule():
    from pytest_avscenario.monitors import rules
    from pytest_avscenario.sim import right_of_way

    assert (rules.STANDING_MPS, rules.STOP_ZONE_BEFORE_M, rules.STOP_ZONE_PAST_M) == \
        (right_of_way.STANDING, right_of_way.BEFORE, right_of_way.PAST)


# -- driving score -----------------------------------------------------------------------------

def test_driving_score_multiplies_route_completion_by_the_leaderboard_penalties():
    t = np.arange(0.0, 10.0, 0.1)
    x = 10.0 * t  # runs the stop line at 10 m/s, completes 99 of 200 m
    ped = {"ped": {"x": np.full(t.size, 80.0), "y": np.zeros(t.size), "kind": "pedestrian",
                   "length": 0.5, "width": 0.5}}  # the ego drives through it
    s = driving_score(drive(x, extra=ped))
    assert [i["kind"] for i in s.infractions] == ["stop", "collision_pedestrian"]
    assert s.route_completion == pytest.approx(0.495)
    assert s.penalty == pytest.approx(0.8 * 0.5)
    assert s.score == pytest.approx(0.495 * 0.4)
    clean = driving_score(drive(np.concatenate([np.linspace(0, 46.5, 40), np.full(20, 46.5),
                                                46.5 + np.arange(1, 141)])))
    assert clean.penalty == 1.0 and clean.score == clean.route_completion


# -- on the simulator's roads ------------------------------------------------------------------

def test_a_simulated_stop_sign_run_and_stop():
    from pytest_avscenario.sim import World
    from pytest_avscenario.sim import behaviors as b

    got = {}
    for drv in ("autopilot", "idm"):  # the autopilot stops at the line; plain IDM does not
        w = World(seed=1, driver=drv, name="t_stop")
        inter = w.intersection()
        w.ego(inter.stop_line("south").before(20), speed=8.0, route=inter.route("south", "left"))
        w.car(inter.stop_line("west").before(25), speed=8.0, behavior=b.turn("straight"), name="w")
        traj = w.run(10.0)
        assert traj.meta["lanes"]["south.in[0]"]["width"] > 0
        got[drv] = (ran_stop().evaluate(traj), wrong_way().evaluate(traj),
                    outside_route_lanes().evaluate(traj), driving_score(traj))
    assert got["autopilot"][0].ok and not got["idm"][0].ok
    assert got["idm"][0].rho == pytest.approx(0.5 - 8.0, abs=0.2)
    assert all(g[1].rho == 0.0 and g[2].rho == 0.0 for g in got.values())
    assert [i["kind"] for i in got["idm"][3].infractions] == ["stop"]


SCENARIO = """
import numpy as np
from pytest_avscenario import scenario, Uniform
from pytest_avscenario.monitors import post_encroachment_time, ran_stop
from pytest_avscenario.trajectory import Trajectory

ROAD = {road!r}

@scenario(stop_speed=Uniform(0.0, 3.0), samples=6, monitors=[ran_stop(), post_encroachment_time(1.0)]{accept})
def test_stop(case):
    t = np.arange(0.0, 8.0, 0.1)
    # brakes to stop_speed with its front bumper 2 m before the line (s = 50), then on
    v = np.where(t < 4.0, 10.0 - (10.0 - case.stop_speed) * t / 4.0, case.stop_speed + 2 * (t - 4))
    x = np.concatenate([[0.0], np.cumsum(v[1:] * 0.1)])
    x = x - np.interp(4.0, t, x) + 45.5
    return Trajectory.from_arrays(t, {{"ego": {{"x": x, "y": 0 * t, "vx": v, "vy": 0 * t, "lane": "a"}},
                                      "ped": {{"x": 0 * t + 62, "y": -12 + 2 * t, "kind": "pedestrian",
                                              "length": 0.5, "width": 0.5}}}},
                                  meta=ROAD)
"""


def test_a_scenario_judges_ran_stop_and_shows_the_driving_score(pytester):
    import json

    pytester.makepyfile(test_stop=SCENARIO.format(road=ROAD, accept=""))
    result = pytester.runpytest("--avs-db=none", "--avs-seed=1", "--avs-shrink-budget=0",
                                "--junitxml=out.xml")
    # the pedestrian crosses 0.2-0.9 s after the ego everywhere; only stop_speed 0.375 m/s
    # (of the Halton points 1.5, 0.75, 2.25, 0.375, 1.875, 1.125) stands at the line
    result.assert_outcomes(failed=6)
    result.stdout.fnmatch_lines(["*ran_stop: rho -1.000, threshold 0.5 — ego ran the stop line of a: "
                                 "lowest speed 1.5 m/s*", "*post_encroachment_time: rho -0.6*ped*"])
    summary = json.loads((pytester.path / "avs-report" / "summary.json").read_text())
    (test,) = summary["tests"]
    assert test["violations"] == {"ran_stop": 5, "post_encroachment_time": 6}
    # 99 m of the 200-m route, a stop sign charged in 5 of the 6 cases: about 0.25 x 0.8
    assert 0.15 < test["driving_score"] < 0.25 and test["scored"] == 6
    cards = list((pytester.path / "avs-report" / "cases").glob("*.html"))
    ran = [c for c in cards if c.name.endswith("halton-000.html")]  # stop_speed 1.5 m/s
    assert len(ran) == 1 and "Driving score" in ran[0].read_text()
    assert "<td>stop</td>" in ran[0].read_text()
    xml = (pytester.path / "out.xml").read_text()
    assert xml.count("name=\"avs.driving_score\"") == 6 and "name=\"avs.infractions\" value=\"stop\"" in xml


def test_min_score_accepts_or_rejects_the_campaign_on_its_driving_score(pytester):
    import json

    text = SCENARIO.format(road=ROAD, accept="").replace(
        "from pytest_avscenario.monitors import", "from pytest_avscenario.acceptance import min_score\n"
        "from pytest_avscenario.monitors import")
    low = text.replace("monitors=[ran_stop(), post_encroachment_time(1.0)]",
                       "monitors=[ran_stop(), post_encroachment_time(1.0)], accept=[min_score(0.1)]")
    high = low.replace("min_score(0.1)", "min_score(0.9)").replace("def test_stop", "def test_stop_high")
    pytester.makepyfile(test_low=low, test_high=high)
    result = pytester.runpytest("--avs-db=none", "--avs-seed=1", "--avs-shrink-budget=0")
    # running the line is accepted by a score bound alone (an expected failure), but the
    # campaign's score (about 0.8 x the 0.25 route completion) is held to the bound
    result.stdout.fnmatch_lines(["REJECTED test_stop_high [[]halton]: driving score 0.* < 0.9 (mean of 6 cases)"])
    summary = {t["test"].rpartition("::")[2]: t
               for t in json.loads((pytester.path / "avs-report" / "summary.json").read_text())["tests"]}
    assert summary["test_stop_high"]["verdict"] == "rejected"
    assert summary["test_stop"]["verdict"] == "accepted"
    assert result.parseoutcomes() == {"xfailed": 12}
    assert result.ret == pytest.ExitCode.TESTS_FAILED  # a rejected campaign fails the run


def test_score_criteria_read_from_text_and_checked():
    from pytest_avscenario.acceptance import min_score, parse_accept

    assert parse_accept("collision, score>=0.8").text() == "collision,score>=0.8"
    assert parse_accept([min_score(0.5)]).score.at_least == 0.5
    assert parse_accept("score>=80%").score.at_least == pytest.approx(0.8)
    for bad in ("score>0.8", "score>=1.5", [min_score(0.5), min_score(0.6)]):
        with pytest.raises(ValueError):
            parse_accept(bad)
    with pytest.raises(ValueError):
        min_score(-0.1)



# -- on map roads ------------------------------------------------------------------------------

MAPS = Path(__file__).parent / "data" / "maps"
SHARED_MAPS = Path(__file__).parents[1].parent / "shared" / "maps"


def _swerve_to(y_target):
    """A policy holding its speed (no acceleration) and steering the ego's centre onto the
    line y = ``y_target`` [m] (a road along +x)."""
    def policy(obs):
        e = obs.ego
        return 0.0, float(np.clip(0.08 * (y_target - e.y) - 0.8 * math.sin(e.heading), -0.2, 0.2))
    return policy


def _drift_to(r_target, after):
    """A policy holding its speed and steering, from ``after`` [s] on, to ``r_target`` [m]
    left of its lane's centre line (damped on the offset's rate)."""
    prev = {}

    def policy(obs):
        rate = (obs.r - prev["r"]) / obs.dt if "r" in prev else 0.0
        prev["r"] = obs.r
        goal = r_target if obs.t >= after else 0.0
        return 0.0, float(np.clip(0.06 * (goal - obs.r) - 0.35 * rate, -0.15, 0.15))
    return policy


def _metres(traj, at):
    """Metres the ego drove into the samples ``at`` (from the sample before each)."""
    d = np.hypot(np.diff(traj.x[0]), np.diff(traj.y[0]))
    return float(d[at[1:]].sum())


def test_rules_and_criticality_on_a_map_road_with_lanes_both_ways():
    """straight_500m.xodr: lane 1/0/-1 runs east at y = -1.535, lane 1/0/1 west at y = +1.535
    (3.07 m wide each, the centre line y = 0 between them). The ego (10 m/s, no
    acceleration) swerves into the westbound lane toward a car parked there at x = 150."""
    from pytest_avscenario.sim import World

    w = World(0, name="t_map")
    road = w.map(MAPS / "straight_500m.xodr")
    w.ego(road.lane("1/0/-1"), s=50, speed=10, driver=_swerve_to(1.535))
    w.parked_car(road.lane("1/0/1"), s=350, name="parked")  # 350 m from x = 500: x = 150
    traj = w.run(8)
    assert set(traj.meta["lanes"]) >= {"1/0/1", "1/0/-1"} and traj.meta["ego_route"] == ["1/0/-1"]
    # against the lane from the first sample whose centre is north of y = 0
    west = traj.y[0] > 0
    k = int(np.argmax(west))
    assert west[k:].all()
    for mon in (wrong_way(), outside_route_lanes()):
        r = mon.evaluate(traj)
        assert r.t == pytest.approx(traj.t[k]) and r.rho == pytest.approx(-_metres(traj, west))
    assert off_road().evaluate(traj).rho == 0.0 and on_sidewalk().evaluate(traj).rho == 0.0
    # along the 500-m route from x = 50 to where the ego ends
    x0, x1 = traj.x[0, 0], traj.x[0, -1]
    assert route_completion(1.0).evaluate(traj).rho == pytest.approx((x1 - x0) / (500 - x0) - 1)
    assert min_speed_route(0.5).evaluate(traj).rho == math.inf  # no moving traffic
    # the parked car ahead in its lane, at the end: gap g, speed v, no accelerations
    g = traj.x[1, -1] - x1 - (traj.length[0] + traj.length[1]) / 2
    v = float(np.hypot(traj.vx[0, -1], traj.vy[0, -1]))
    d = (traj.width[0] + traj.width[1]) / 2 - abs(traj.y[1, -1] - traj.y[0, -1])
    expect = {ettc(2.0): g / v - 2.0, required_deceleration(4.0): 4.0 - v * v / (2 * g),
              brake_threat_number(1.0): 1.0 - v * v / (2 * g) / 8.0,
              time_to_brake(1.0): (g - v * v / 16.0) / v - 1.0,  # until v²/(2(g - vτ)) > 8
              time_to_steer(0.5): g / v - math.sqrt(2 * d / 5.0) - 0.5}
    for mon, rho in expect.items():
        r = mon.evaluate(traj)
        assert r.agent == "parked" and r.t == pytest.approx(traj.t[-1])
        assert r.rho == pytest.approx(rho, abs=2e-3 if mon.name == "time_to_brake" else 1e-4)
    assert post_encroachment_time(1.0).evaluate(traj).rho == math.inf  # nothing crosses


def test_on_sidewalk_is_the_maps_own_sidewalk():
    """fabriksgatan.xodr: beside the 3.5-m driving lane 3/0/-1 (straight) lie a 0.3-m border
    and a 2-m sidewalk. The ego drifts right off the road: the border is off the road but
    not sidewalk; the sidewalk starts 1.75 + 0.3 m right of the lane's centre line."""
    from pytest_avscenario.sim import World

    w = World(0, name="t_map")
    town = w.map(MAPS / "fabriksgatan.xodr")
    w.ego(town.lane("3/0/-1"), s=10, speed=8, driver=_drift_to(-3.05, after=1.0))
    traj = w.run(9)
    assert traj.meta["lanes"]["3/0/-3"]["kind"] == "sidewalk"
    r_off = traj.lane_offset[0]  # the simulator's own offset from the lane's centre line
    assert set(traj.lane[0]) == {"3/0/-1"} and r_off.min() < -2.3
    walk = (r_off < -(1.75 + 0.3)) & (r_off >= -(1.75 + 0.3 + 2.0))
    r = on_sidewalk().evaluate(traj)
    assert r.t == pytest.approx(traj.t[np.argmax(walk)]) and walk.sum() >= 5
    assert r.rho == pytest.approx(-_metres(traj, walk))
    off = off_road().evaluate(traj)
    assert off.t == pytest.approx(traj.t[np.argmax(r_off < -1.75)]) and off.t < r.t
    assert outside_route_lanes().evaluate(traj).t == off.t
    assert wrong_way().evaluate(traj).rho == 0.0


def test_a_maps_shoulder_is_off_the_road_but_no_sidewalk():
    """straight_500m.xodr has a 1.68-m shoulder beside each driving lane and no sidewalk."""
    from pytest_avscenario.sim import World

    w = World(0, name="t_map")
    road = w.map(MAPS / "straight_500m.xodr")
    w.ego(road.lane("1/0/-1"), s=50, speed=10, driver=_swerve_to(-1.535 - 1.535 - 0.84))
    traj = w.run(6)
    assert traj.y[0].min() < -3.4 and not traj.on_road[0].all()
    assert off_road().evaluate(traj).rho < 0 and on_sidewalk().evaluate(traj).rho == 0.0


@pytest.mark.skipif(not (SHARED_MAPS / "highway_example_with_merge_and_split.xodr").is_file(),
                    reason=f"no shared maps at {SHARED_MAPS}")
def test_a_lead_past_a_lane_section_boundary_stays_ahead_and_traffic_rules_on_a_map():
    """highway_example_with_merge_and_split.xodr: road 0's lane -1 is 0/0/-1 for its first
    50 m, then 0/1/-1. A lead brakes to a stop past that boundary with the ego (IDM) behind
    it, still on 0/0/-1; a car beside keeps going."""
    from pytest_avscenario.sim import World
    from pytest_avscenario.sim import behaviors as b

    w = World(0, name="t_map")
    m = w.map(SHARED_MAPS / "highway_example_with_merge_and_split.xodr")
    w.ego(m.lane("0/0/-1"), s=5, speed=10, driver="idm")
    w.car(m.lane("0/0/-1"), s=30, speed=10, behavior=b.brake_at(1.0, decel=4.0), name="lead")
    w.car(m.lane("0/0/-2"), s=20, speed=12, name="beside")
    traj = w.run(9)
    past = (traj.lane[1] == "0/1/-1") & (traj.lane[0] == "0/0/-1")
    assert past.sum() > 20 and traj.meta["ego_route"][:2] == ["0/0/-1", "0/1/-1"]
    # the same run with the lead's lane named as the ego's: the measures see the same lead
    same = traj.lane.copy()
    same[1, past] = "0/0/-1"
    relabelled = dataclasses.replace(traj, lane=same)
    for mon in (ettc(2.0), required_deceleration(4.0), brake_threat_number(), time_to_brake(1.0),
                time_to_steer(0.5)):
        got = mon.series(traj)
        assert np.array_equal(got, mon.series(relabelled)), mon.name
        if mon.name in ("required_deceleration", "brake_threat_number"):
            assert np.isfinite(got[past]).all(), mon.name  # a value wherever a lead is ahead
        assert mon.evaluate(traj).agent == "lead"
    # blocked: standing (< 0.1 m/s) from its first slow sample to the end
    slow = int(np.argmax(traj.speed[0] < 0.1))
    assert (traj.speed[0, slow:] < 0.1).all()
    assert blocked(1.0).evaluate(traj).rho == pytest.approx(1.0 - (traj.t[-1] - traj.t[slow]))
    # min_speed_route: the ego's mean speed over the cars' mean speed
    ratio = traj.speed[0].mean() / traj.speed[1:].mean(axis=0).mean()
    assert min_speed_route(0.9).evaluate(traj).rho == pytest.approx(ratio - 0.9, rel=1e-9)
    # the route's length is its lanes' lengths; the ego drove its step lengths from s = 5
    length = sum(m.lane(i).length for i in traj.meta["ego_route"])
    driven = float(np.hypot(np.diff(traj.x[0]), np.diff(traj.y[0])).sum())
    assert route_completion(1.0).evaluate(traj).rho == pytest.approx(
        driven / (length - 5.0) - 1.0, abs=2e-3)
    for mon in (wrong_way(), outside_route_lanes(), on_sidewalk(), off_road()):
        assert mon.evaluate(traj).rho == 0.0



def test_post_encroachment_time_at_a_map_junction():
    """fabriksgatan.xodr's junction: the ego (IDM) crosses from the south arm to the north,
    a car from the west arm to the east after it; their paths cross inside the junction's
    connecting lanes (9/0/-1 and 12/0/-1)."""
    from pytest_avscenario.sim import World

    from test_monitors_criteria_shared import _pet_brute_force

    w = World(3, name="t_map", driver="idm")
    town = w.map(MAPS / "fabriksgatan.xodr")
    w.ego(town.lane("0/0/1"), s=60, speed=8, route=town.route("0/0/1", "2/0/1"))
    w.car(town.lane("3/0/-1"), s=60, speed=8, route=town.route("3/0/-1", "1/0/-1"), name="cross")
    traj = w.run(9)
    assert "9/0/-1" in traj.lane[0] and "12/0/-1" in traj.lane[1] and not traj.crashed.any()
    pet, t_left, t_reached = cr.pet_values(traj)
    # the smallest time apart of two samples whose footprints overlap, crossing
    assert np.array_equal(pet, _pet_brute_force(traj)) and 1.0 < pet[0] < 4.0
    r = post_encroachment_time(1.0).evaluate(traj)
    assert r.agent == "cross" and r.rho == pytest.approx(pet[0] - 1.0)
    assert r.t == t_reached[0] and t_reached[0] - t_left[0] == pytest.approx(pet[0])

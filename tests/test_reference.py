"""Reference drivers: the careful and competent driver of UN R157 and the RSS check.

Every number checked here is computed by hand in the test from the sources' formulas (R157
Annex 4 Appendix 3; Shalev-Shwartz et al. 2017, arXiv:1708.06374), not read back from the
code under test: a stopped vehicle inside / outside the C&C stopping distance, a cut-in the
C&C driver can / cannot absorb, and RSS safe distances at a few speeds. The scenarios run
through pytest as a user would write them (``world.ego(..., driver="careful")`` or an
``avs_driver`` fixture, ``monitors=[rss()]``).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from pytest_avscenario.monitors import (
    MonitorError,
    RSSParams,
    rss,
    rss_blame,
    safe_lateral_distance,
    safe_longitudinal_distance,
    safe_opposite_distance,
)
from pytest_avscenario.sim import SimError
from pytest_avscenario.sim.drivers import (
    CarefulDriver,
    CarefulDriverOptions,
    closing_distance,
    resolve,
    stopping_distance,
)
from pytest_avscenario.trajectory import Trajectory

G = 9.80665
A_MAX = 0.774 * G  # [m/s^2] R157 C&C maximum deceleration
T_UP = 0.6  # [s] R157 C&C time to reach it
DELAY = 0.4 + 0.75  # [s] R157 risk perception + reaction


def by_hand_stopping(v: float) -> float:
    """Constant speed through the delay, the linear ramp to A_MAX (integrated term by term),
    then constant braking: the textbook pieces, written out independently of the code."""
    during_delay = v * DELAY
    jerk = A_MAX / T_UP
    ramp = v * T_UP - jerk * T_UP ** 3 / 6  # s(t) = v t - j t^3 / 6
    v_after_ramp = v - jerk * T_UP ** 2 / 2
    return during_delay + ramp + v_after_ramp ** 2 / (2 * A_MAX)


# -- the closed forms ----------------------------------------------------------------------------

@pytest.mark.parametrize("v", [12.0, 20.0, 30.0])
def test_stopping_distance_is_delay_plus_ramp_plus_braking(v):
    assert stopping_distance(v) == pytest.approx(by_hand_stopping(v), abs=1e-9)
    # the build-up costs v T/2 - a T^2/24 over braking at once after the delay
    assert stopping_distance(v) == pytest.approx(
        v * DELAY + v * v / (2 * A_MAX) + v * T_UP / 2 - A_MAX * T_UP ** 2 / 24, abs=1e-9)
    assert stopping_distance(20.0) == pytest.approx(55.2354, abs=1e-4)


def test_a_slow_car_stops_during_the_brake_build_up():
    v = 1.0  # below a T / 2 = 2.28 m/s: the ramp alone stops it, after sqrt(2 v / j)
    jerk = A_MAX / T_UP
    t_stop = math.sqrt(2 * v / jerk)
    assert t_stop < T_UP
    assert stopping_distance(v) == pytest.approx(v * DELAY + v * t_stop - jerk * t_stop ** 3 / 6)
    assert stopping_distance(0.0) == 0.0 and closing_distance(-3.0) == 0.0


def test_options_are_checked_and_named():
    with pytest.raises(ValueError, match="reaction_time=-1"):
        CarefulDriver(reaction_time=-1)
    with pytest.raises(TypeError, match="Known CarefulDriver options: risk_perception_time"):
        CarefulDriver(reaction=0.5)
    slow = CarefulDriverOptions(reaction_time=1.5)
    assert stopping_distance(20.0, slow) == pytest.approx(stopping_distance(20.0) + 20.0 * 0.75)


def test_careful_is_a_built_in_driver_name():
    driver = resolve("careful")
    assert isinstance(driver.target, CarefulDriver)
    with pytest.raises(SimError, match="'careful'"):
        resolve("carefull")


@pytest.mark.parametrize("v_rear, v_front, by_hand", [
    # v_r rho + a rho^2/2 + (v_r + rho a)^2 / (2 b_min) - v_f^2 / (2 b_max); rho 1, a 3.5,
    # b_min 4, b_max 8
    (10.0, 10.0, 10 + 1.75 + 13.5 ** 2 / 8 - 100 / 16),  # 28.28125
    (20.0, 0.0, 20 + 1.75 + 23.5 ** 2 / 8),  # 90.78125
    (30.0, 30.0, 30 + 1.75 + 33.5 ** 2 / 8 - 900 / 16),  # 115.78125
    (0.0, 30.0, 0.0),  # the front car's braking distance exceeds the rear's: [.]_+ = 0
])
def test_rss_safe_longitudinal_distance_by_hand(v_rear, v_front, by_hand):
    assert safe_longitudinal_distance(v_rear, v_front) == pytest.approx(by_hand)
    # and vectorized over speeds, as the monitor uses it
    got = safe_longitudinal_distance(np.array([v_rear, v_rear]), np.array([v_front, v_front]))
    assert got.tolist() == pytest.approx([by_hand, by_hand])


def test_rss_other_distances_by_hand():
    # rho 0.5 s: 10*0.5 + 3.5*0.25/2 + (10 + 1.75)^2 / 8 - 100/16
    assert safe_longitudinal_distance(10.0, 10.0, response_time=0.5) == pytest.approx(
        5 + 0.4375 + 11.75 ** 2 / 8 - 6.25)
    # oncoming at 10 m/s each: (v + v_rho)/2 rho + v_rho^2 / (2 b), b = 3 (correct lane), 4
    assert safe_opposite_distance(10.0, 10.0) == pytest.approx(
        (10 + 13.5) / 2 + 13.5 ** 2 / 6 + (10 + 13.5) / 2 + 13.5 ** 2 / 8)
    # lateral: mu + sum of (u rho + a rho^2 / 2 + (u + rho a)^2 / (2 b)), a 0.2, b 0.8, mu 0.1
    assert safe_lateral_distance(0.0, 0.0) == pytest.approx(0.1 + 2 * (0.1 + 0.04 / 1.6))
    assert safe_lateral_distance(1.0, 0.0) == pytest.approx(
        0.1 + (1 + 0.1 + 1.2 ** 2 / 1.6) + (0.1 + 0.04 / 1.6))


def test_rss_parameters_are_checked_and_named():
    with pytest.raises(MonitorError, match=r"a_min_brake \[m/s\^2\] must be > 0"):
        rss(a_min_brake=0)
    with pytest.raises(MonitorError, match="unknown parameter.*rho.*known: response_time"):
        rss(rho=1.0)
    with pytest.raises(MonitorError, match="response_time must be a finite number"):
        RSSParams(response_time=float("nan"))


def test_a_bad_rss_parameter_is_a_collection_error_naming_the_test(pytester):
    pytester.makepyfile("""
from pytest_avscenario import scenario, Uniform
from pytest_avscenario.monitors import rss
@scenario(x=Uniform(0, 1), monitors=[rss(a_max_brake=-8)])
def test_bad(case):
    pass
""")
    result = pytester.runpytest()
    assert result.ret == pytest.ExitCode.INTERRUPTED
    out = result.stdout.str()
    # as for every monitor built with bad arguments: the test, the message, the decorator's line
    assert "::test_bad: rss: a_max_brake [m/s^2] must be > 0, got -8 (raised by its decorator at" in out
    assert "Traceback" not in out


# -- the RSS monitor and blame on hand-built trajectories -------------------------------------------

T = np.round(np.arange(0.0, 6.0 + 1e-9, 0.1), 10)


def straight(x0, v, a=0.0, t_brake=0.0, y=0.0, vy=0.0, lane="", offset=np.nan, heading=None):
    """Motion along x at speed v, braking at ``a`` from ``t_brake`` until standing; optional
    constant lateral velocity ``vy``; heading along the velocity unless given."""
    tb = np.maximum(T - t_brake, 0.0)
    t_stop = v / a if a > 0 else np.inf
    tau = np.minimum(tb, t_stop)
    x = x0 + v * np.minimum(T, t_brake) + v * tau - 0.5 * a * tau ** 2
    vx = np.where(tb < t_stop, v - a * tb, 0.0) if a > 0 else np.full_like(T, v)
    return {"x": x, "y": y + vy * T, "vx": vx, "vy": np.full_like(T, vy),
            "heading": (np.arctan2(vy, np.maximum(vx, 1e-9)) if heading is None
                        else np.full_like(T, heading)), "lane": lane,
            "lane_offset": offset if np.isscalar(offset) else offset}


def test_rss_monitor_reports_the_longitudinal_margin_in_line():
    traj = Trajectory.from_arrays(T, {"ego": straight(0.0, 10.0), "lead": straight(30.0, 10.0)})
    res = rss().evaluate(traj)
    # bumper gap 25 m against 28.28125 m, the same at every step: the first one is reported
    assert res.rho == pytest.approx(25.0 - 28.28125)
    assert res.agent == "lead" and res.t == 0.0 and not res.ok
    assert "longitudinal gap 25 m vs safe 28.3 m" in res.detail
    assert rss().evaluate(Trajectory.from_arrays(
        T, {"ego": straight(0.0, 10.0), "lead": straight(34.0, 10.0)})).rho == pytest.approx(
        29.0 - 28.28125)


def test_rss_monitor_reports_the_lateral_margin_side_by_side():
    # adjacent lanes 3.5 m apart, side by side: lateral gap 1.5 m against 0.35 m
    beside = Trajectory.from_arrays(T, {"ego": straight(0.0, 20.0),
                                        "car": straight(0.0, 20.0, y=3.5, heading=0.0)})
    assert rss().evaluate(beside).rho == pytest.approx(1.5 - 0.35)
    # drifting toward the ego at 0.2 m/s (pointing straight on); the worst step is the last
    # one (t = 6 s): lateral gap 1.5 - 1.2 m against 0.1 + (0.2 + 0.1 + 0.4^2/1.6) + 0.125
    drift = Trajectory.from_arrays(T, {"ego": straight(0.0, 20.0),
                                       "car": straight(0.0, 20.0, y=3.5, vy=-0.2, heading=0.0)})
    res = rss(axis=0.0).evaluate(drift)
    assert res.t == 6.0 and res.agent == "car"
    assert res.rho == pytest.approx(0.3 - (0.1 + 0.2 + 0.1 + 0.16 / 1.6 + 0.125), abs=1e-9)


def test_blame_a_cut_in_on_the_other_car():
    # it leaves its lane toward the ego at 1 m/s and never brakes laterally; it starts with
    # its centre 5.3 m to the left, its bumper 10 m ahead at 15 vs 20 m/s
    traj = Trajectory.from_arrays(T, {"ego": straight(0.0, 20.0),
                                      "cutter": straight(15.0, 15.0, y=5.3, vy=-1.0)})
    (blame,) = rss_blame(traj, axis=0.0)
    (ep,) = blame.episodes
    # it points along its velocity, atan(1/15) off the road: its half extent across the road
    # is 2.5 sin + 1 cos of that. Safe lateral distance 0.1 + (1 + 0.1 + 1.2^2/1.6) +
    # (0.1 + 0.2^2/1.6) = 2.225 m; longitudinally it was already unsafe, so the lateral
    # response was owed from the last sample the lateral gap was still safe
    phi = math.atan(1 / 15)
    t_lost = 5.3 - 1.0 - (2.5 * math.sin(phi) + math.cos(phi)) - 2.225  # 0.911 s
    t_start = math.ceil(t_lost * 10) / 10
    assert ep.start == pytest.approx(t_start) and ep.blame_time == pytest.approx(t_start - 0.1)
    assert ep.response == "lateral" and ep.ego_violation is None
    # it owed lateral braking from the blame time + rho and never gave it
    assert ep.other_violation == pytest.approx(t_start - 0.1 + 1.0)
    assert blame.other_unsafe_at == pytest.approx(t_start) and blame.ego_unsafe_at is None
    assert blame.first == "cutter"


def test_blame_nobody_for_a_situation_dangerous_from_the_start():
    # the same cut-in 1.8 m closer: unsafe at the first sample, nobody entered it
    traj = Trajectory.from_arrays(T, {"ego": straight(0.0, 20.0),
                                      "cutter": straight(15.0, 15.0, y=3.5, vy=-1.0)})
    (blame,) = rss_blame(traj, axis=0.0)
    (ep,) = blame.episodes
    assert ep.start == 0.0 and ep.blame_time is None and ep.response == "initial"
    assert blame.first is None
    assert rss(axis=0.0).evaluate(traj).rho < 0  # the monitor still reports it unsafe


def test_blame_the_ego_that_changes_lane_into_the_other_car():
    # the ego steers toward the car beside it; its lane offset says it moves across its lane,
    # so the estimated road axis stays along x although the ego's heading turns
    ego = straight(0.0, 20.0, vy=1.0, lane="L1", offset=T * 1.0)
    traj = Trajectory.from_arrays(T, {"ego": ego, "car": straight(10.0, 20.0, y=5.8)})
    (blame,) = rss_blame(traj)
    assert blame.first == "ego" and blame.other_unsafe_at is None
    assert blame.episodes[0].response == "lateral"
    # with the ego's own heading as the axis, it would not be seen moving sideways at all
    (no_lane,) = rss_blame(Trajectory.from_arrays(
        T, {"ego": straight(0.0, 20.0, vy=1.0), "car": straight(10.0, 20.0, y=5.8)}))
    assert no_lane.first != "ego"


def test_blame_rear_end_on_the_car_that_broke_its_longitudinal_response():
    # the ego runs up on a slower lead at 25 vs 10 m/s without braking: bumper gap 145 m,
    # RSS asks 25 + 1.75 + 28.5^2/8 - 10^2/16 = 122.03 m, lost after 1.53 s
    closing = Trajectory.from_arrays(T, {"ego": straight(0.0, 25.0),
                                         "lead": straight(150.0, 10.0)})
    (blame,) = rss_blame(closing)
    (ep,) = blame.episodes
    assert ep.response == "longitudinal" and blame.first == "ego"
    assert ep.start == pytest.approx(1.6) and ep.blame_time == pytest.approx(1.5)
    assert ep.ego_violation == pytest.approx(2.5)  # owed braking after rho, gave none
    # the lead brakes at 9 m/s^2 (> a_max_brake 8) from an RSS-safe 70 m (65.8 m asked) in
    # front of an ego that brakes at 6 m/s^2 after 0.5 s
    braking = Trajectory.from_arrays(T, {"ego": straight(0.0, 20.0, a=6.0, t_brake=0.5),
                                         "lead": straight(75.0, 20.0, a=9.0, t_brake=0.0)})
    (blame,) = rss_blame(braking)
    assert blame.first == "lead" and blame.ego_unsafe_at is None
    assert blame.episodes[0].response == "longitudinal"


# -- the C&C driver in scenarios, as a user runs them ------------------------------------------------

STOPPED = """
import numpy as np
from pytest_avscenario import scenario, Choice
from pytest_avscenario.monitors import collision
from pytest_avscenario.sim import behaviors as b
from pytest_avscenario.sim.drivers import stopping_distance

DT = 0.01

@scenario(margin=Choice([-3.0, 3.0]), samples=2, monitors=[collision()])
def test_stopped_vehicle(case, world):
    v = 20.0
    road = world.straight_road(lanes=1, length=400)
    world.ego(road.lane(0), s=10.0, speed=v, driver="careful", target_speed=v)
    # bumper gap: the C&C stopping distance plus the case's margin
    world.car(road.lane(0), s=10.0 + 5.0 + stopping_distance(v) + case.margin, speed=0.0,
              behavior=b.stopped(), name="stopped")
    traj = world.run(6, dt=DT)
    acc = traj.signals["ego.acceleration"]
    # nothing happens before the 1.15 s of perception and reaction have passed
    assert np.all(acc[traj.t <= 1.15 + 1e-9] == 0.0)
    if case.margin > 0:
        k = int(np.argmax(traj.speed[0] <= 0.0))
        # the closed form, plus the v dt / 2 of the simulator's explicit Euler positions
        expected = 10.0 + {by_hand} + v * DT / 2
        assert abs(traj.x[0, k] - expected) < 0.02, (traj.x[0, k], expected)
"""


def test_a_stopped_vehicle_inside_the_stopping_distance_is_hit_outside_it_is_not(pytester):
    pytester.makepyfile(test_stop=STOPPED.format(by_hand=repr(by_hand_stopping(20.0))))
    result = pytester.runpytest("-p", "no:randomly", "--avs-db=none", "--avs-seed=1",
                                "--avs-report=none")
    result.assert_outcomes(passed=1, failed=1)
    result.stdout.fnmatch_lines(["*scenario violated: collision*", "*parameters: margin=-3*"])
    assert "AssertionError" not in result.stdout.str()


CUT_IN = """
import numpy as np
from pytest_avscenario import scenario, Choice
from pytest_avscenario.monitors import collision, rss_blame
from pytest_avscenario.sim import behaviors as b

DT = 0.01

@scenario(gap=Choice([20.0, 30.0]), samples=2, monitors=[collision()])
def test_cut_in(case, world):
    v_ego, v_cut = 20.0, 10.0
    road = world.straight_road(lanes=2, length=600)
    world.ego(road.lane(1), s=10.0, speed=v_ego, driver="careful", target_speed=v_ego)
    world.car(road.lane(0), s=10.0 + 5.0 + case.gap, speed=v_cut, name="cutter",
              behavior=b.change_lane(to="right", at=0.5, duration=2.0))
    traj = world.run(6, dt=DT)
    # lane 0 is at y = 0, the ego's lane 1 at y = -3.5: the cut-in is perceivable once the
    # cutter is more than 0.375 m (the wandering distance) out of its lane toward the ego,
    # which happens between two samples (the driver interpolates, as here)
    k_e = int(np.argmax(traj.y[1] < -0.375))
    y0, y1 = traj.y[1, k_e - 1], traj.y[1, k_e]
    t_e = traj.t[k_e - 1] + DT * (-0.375 - y0) / (y1 - y0)
    # the brake acts 1.15 s later: the first braking command is the step that contains it
    first_brake = traj.t[int(np.argmax(traj.signals["ego.acceleration"] < 0.0)) - 1]
    assert first_brake < t_e + 1.15 <= first_brake + DT, (first_brake, t_e)
    (blame,) = rss_blame(traj)
    assert blame.first == "cutter", blame
    if not traj.meta["crashed"]:
        gap_e = traj.x[1, k_e] - traj.x[0, k_e] - 5.0
        gaps = traj.x[1] - traj.x[0] - 5.0
        # the gap shrinks by the closing distance of 10 m/s, {closing} m; the cutter's speed
        # along the road dips while it is turned, hence the tolerance
        assert abs(gaps.min() - (gap_e - {closing})) < 0.5, (gaps.min(), gap_e)
"""


def by_hand_closing(dv: float) -> float:
    return by_hand_stopping(dv)  # the cutter keeps its speed: the same physics, relative


def test_a_cut_in_the_careful_driver_can_absorb_and_one_it_cannot(pytester):
    # at the cut-in the bumper gap is about 24 m (gap 30) or 14 m (gap 20) and the closing
    # distance 21 m: the first leaves ~3 m, the second cannot be absorbed
    assert by_hand_closing(10.0) == pytest.approx(closing_distance(10.0))
    pytester.makepyfile(test_cut=CUT_IN.format(closing=repr(by_hand_closing(10.0))))
    result = pytester.runpytest("-p", "no:randomly", "--avs-db=none", "--avs-seed=1",
                                "--avs-report=none")
    result.assert_outcomes(passed=1, failed=1)
    result.stdout.fnmatch_lines(["*scenario violated: collision*", "*parameters: gap=20*"])
    assert "AssertionError" not in result.stdout.str()


FOLLOW = """
from pytest_avscenario import scenario, Choice
from pytest_avscenario.monitors import collision, rss

@scenario(gap=Choice([25.0, 32.0]), samples=2, monitors=[rss(), collision()])
def test_follow(case, world):
    road = world.straight_road(lanes=1, length=600)
    world.ego(road.lane(0), s=10.0, speed=10.0, target_speed=10.0)
    world.car(road.lane(0), s=15.0 + case.gap, speed=10.0, name="lead")
    world.run(8)
"""


def test_the_rss_monitor_judges_a_reference_driver_following_at_a_fixed_gap(pytester):
    pytester.makeconftest("""
import pytest

@pytest.fixture
def avs_driver():
    return "careful"
""")
    pytester.makepyfile(test_follow=FOLLOW)
    result = pytester.runpytest("-p", "no:randomly", "--avs-db=none", "--avs-seed=1",
                                "--avs-report=none")
    result.assert_outcomes(passed=1, failed=1)
    # 25 m of bumper gap at 10 m/s behind 10 m/s, RSS asks 28.28125 m: rho = -3.281 at the
    # start, where the careful driver has not yet reacted (it then drops back)
    result.stdout.fnmatch_lines([
        "*scenario violated: rss*",
        "*rss: rho -3.281, threshold 0*RSS margin -3.28 m to lead at t=0.00 s*",
        "*parameters: gap=25*",
    ])

"""World basics on a straight road: recording shapes and units, braking, drivers, bad input."""

from __future__ import annotations

import math

import numpy as np
import pytest

from pytest_avscenario.sim import DriverError, SimError, World
from pytest_avscenario.sim import behaviors as b
from pytest_avscenario.sim.observation import Observation


def first(mask) -> int:
    """Index of the first True (fails the test if none)."""
    mask = np.asarray(mask)
    assert mask.any(), "condition never held"
    return int(np.argmax(mask))


def following(driver="idm", gap=30.0, lead_speed=10.0, brake=3.0, decel=6.0, seconds=10.0,
              seed=1, name="test_follow"):
    w = World(seed=seed, driver=driver, name=name)
    road = w.straight_road(lanes=1, length=400)
    w.ego(road.lane(0), s=0.0, speed=12.0)
    w.car(road.lane(0), s=gap, speed=lead_speed, behavior=b.brake_at(brake, decel=decel))
    w.run(seconds=seconds)
    return w


def test_trajectory_shapes_units_and_meta():
    w = following()
    tr = w.trajectory
    assert tr.names == ("ego", "car1") and tr.kinds == ("ego", "car")
    assert tr.n_steps == 101 and tr.x.shape == (2, 101)
    for key in ("y", "vx", "vy", "speed", "heading", "lane", "lane_offset", "crashed",
                "present", "on_road"):
        assert getattr(tr, key).shape == (2, 101), key
    np.testing.assert_allclose(tr.t, np.arange(101) * 0.1)
    np.testing.assert_allclose(tr.length, [5.0, 5.0])
    np.testing.assert_allclose(tr.width, [2.0, 2.0])
    np.testing.assert_allclose(np.hypot(tr.vx, tr.vy), tr.speed, atol=1e-9)
    # Positions integrate velocities: x advances by about speed * dt per step [m].
    dx = np.diff(tr.x[1])
    np.testing.assert_allclose(dx, tr.speed[1, :-1] * 0.1, atol=1e-6)
    assert tr.x[0, 0] == 0.0 and tr.x[1, 0] == 30.0
    assert set(tr.lane.ravel()) == {"lane[0]"}
    assert np.nanmax(np.abs(tr.lane_offset)) < 0.05
    assert tr.on_road.all() and tr.present.all() and not tr.crashed.any()
    assert tr.meta["dt"] == 0.1 and tr.meta["seed"] == 1 and tr.meta["test"] == "test_follow"
    assert tr.meta["road"] == "straight" and tr.meta["ego_route"] == ["lane[0]"]
    assert tr.meta["ego_reached_route_end"] is False
    assert tr.signals["ego.acceleration"].shape == (101,)


def test_brake_at_time_drops_speed_at_that_time():
    tr = following(brake=2.0, decel=6.0).trajectory
    lead = tr.agent("car1")
    i = int(round(2.0 / 0.1))
    assert np.allclose(lead.speed[: i + 1], 10.0)
    assert lead.speed[i + 5] == pytest.approx(10.0 - 6.0 * 0.5, abs=1e-6)
    assert lead.speed[-1] == 0.0
    # The IDM ego brakes behind it and stops without touching it.
    assert tr.ego.speed[-1] < 0.1 and not tr.crashed.any()
    gap = lead.x - tr.ego.x - 5.0
    assert gap.min() > 0


def test_brake_at_place_starts_at_that_place():
    w = World(seed=2, driver="idm")
    road = w.straight_road()
    w.ego(road.lane(0), s=0.0, speed=5.0)
    w.car(road.lane(0), s=40.0, speed=10.0, behavior=b.brake_at(at=road.lane(0).at(70.0), decel=4.0))
    tr = w.run(8.0)
    lead = tr.agent("car1")
    first = int(np.argmax(lead.speed < 9.99))
    assert lead.x[first - 1] >= 70.0 - 1e-9 and lead.x[first - 2] < 70.0


def test_keep_lane_cruises_at_its_speed_and_change_lane_moves_over():
    w = World(seed=3, driver="idm")
    road = w.straight_road(lanes=3)
    w.ego(road.lane(2), s=0.0, speed=8.0)
    w.car(road.lane(0), s=30.0, speed=6.0, behavior=b.keep_lane(12.0))
    w.car(road.lane(1), s=60.0, speed=10.0, behavior=b.change_lane("right", at=1.0))
    w.car(road.lane(1), s=100.0, speed=10.0, behavior=b.change_lane(0, at=0.0))
    tr = w.run(10.0)
    assert tr.agent("car1").speed[-1] == pytest.approx(12.0, abs=0.3)
    c2 = tr.agent("car2")
    assert c2.lane[5] == "lane[1]" and c2.lane[-1] == "lane[2]"
    assert abs(c2.y[-1] - road.lane(2).position(0)[1]) < 0.3
    assert abs(c2.y[10] - road.lane(1).position(0)[1]) < 1e-6  # not before t = 1 s
    assert tr.agent("car3").lane[-1] == "lane[0]"


def test_dynamic_parameters_come_from_the_world_rng():
    def brake_speed_at_5s(rng):
        w = World(seed=0, rng=rng, driver="idm")
        road = w.straight_road()
        w.ego(road.lane(0), s=0.0, speed=5.0)
        w.car(road.lane(0), s=50.0, speed=10.0, behavior=b.brake_at(b.uniform(0.5, 4.5), decel=1.0))
        return w.run(6.0).agent("car1").speed

    a = brake_speed_at_5s(np.random.default_rng(11))
    again = brake_speed_at_5s(np.random.default_rng(11))
    other = brake_speed_at_5s(np.random.default_rng(12))
    assert np.array_equal(a, again)
    assert not np.array_equal(a, other)


# -- drivers --------------------------------------------------------------------------------------


def test_callable_policy_drives_and_sees_a_full_observation():
    seen: list[Observation] = []

    def policy(obs):
        seen.append(obs)
        return 1.0, 0.0

    w = World(seed=1, driver=policy, name="t_policy")
    road = w.straight_road(lanes=2)
    w.ego(road.lane(1), s=0.0, speed=5.0, target_speed=9.0, goal={"kind": "park"})
    w.car(road.lane(1), s=60.0, speed=10.0)
    w.car(road.lane(0), s=20.0, speed=10.0)
    tr = w.run(3.0)
    assert tr.ego.speed[-1] == pytest.approx(8.0, abs=1e-9)  # 5 m/s + 1 m/s^2 * 3 s
    assert len(seen) == 30 and seen[0].t == 0.0 and seen[-1].t == pytest.approx(2.9)
    o = seen[0]
    assert o.ego.kind == "ego" and o.ego.speed == 5.0 and o.dt == 0.1
    assert [a.name for a in o.agents] == ["car2", "car1"]  # nearest first
    assert o.route[0] is road.lane(1).geometry and o.route_index == 0
    assert o.s == pytest.approx(0.0) and o.r == pytest.approx(0.0)
    assert o.target_speed == 9.0 and o.goal == {"kind": "park"}
    assert seen[-1].s == pytest.approx(tr.ego.x[-2], abs=1e-9)
    np.testing.assert_allclose(tr.signals["ego.acceleration"][1:], 1.0)
    # Observations are complete, equal to ones built field by field, and immutable.
    import dataclasses

    for obj in (o, o.ego, o.agents[0]):
        again = type(obj)(**{f.name: getattr(obj, f.name) for f in dataclasses.fields(obj)})
        assert again == obj
    with pytest.raises(dataclasses.FrozenInstanceError):
        o.t = 1.0


class ActDriver:
    def __init__(self):
        self.calls = 0

    def act(self, obs):
        self.calls += 1
        return np.array([-1.0, 0.0])


class PredictDriver:
    def predict(self, observation, state=None, episode_start=None, deterministic=False):
        assert deterministic is True
        return np.array([[0.5, 0.0]], dtype=np.float32), None


@pytest.mark.parametrize("driver,expected", [(ActDriver(), 9.0), (PredictDriver(), 10.5)])
def test_act_and_predict_style_drivers(driver, expected):
    w = World(seed=1, driver=driver)
    road = w.straight_road()
    w.ego(road.lane(0), s=0.0, speed=10.0)
    tr = w.run(1.0)
    assert tr.ego.speed[-1] == pytest.approx(expected, abs=1e-6)


def test_per_ego_driver_overrides_world_default_and_steering_turns():
    w = World(seed=1, driver="idm")
    road = w.straight_road(lanes=2)
    w.ego(road.lane(0), s=0.0, speed=8.0, driver=lambda o: (0.0, -0.05))
    tr = w.run(2.0)
    assert tr.ego.heading[-1] < -0.05  # steering right turns clockwise
    assert tr.ego.y[-1] < -0.5
    assert tr.ego.lane_offset[-1] < -0.5


def test_actions_are_clipped_and_braking_never_reverses():
    w = World(seed=1, driver=lambda o: (100.0, 3.0))
    road = w.straight_road()
    w.ego(road.lane(0), s=0.0, speed=0.0)
    tr = w.run(1.0)
    assert tr.signals["ego.acceleration"].max() == 6.0
    assert abs(tr.signals["ego.steering"]).max() == pytest.approx(math.pi / 3)

    w = World(seed=1, driver=lambda o: (-5.0, 0.0))
    road = w.straight_road()
    w.ego(road.lane(0), s=50.0, speed=3.0)
    tr = w.run(2.0)
    assert tr.ego.speed.min() == 0.0 and tr.ego.x.min() >= 50.0

    w = World(seed=1, driver=lambda o: (-1.0, 0.0))
    road = w.straight_road()
    w.ego(road.lane(0), s=50.0, speed=0.0, allow_reverse=True)
    tr = w.run(2.0)
    assert tr.ego.speed[-1] == pytest.approx(-2.0) and tr.ego.x[-1] < 50.0

    # A parking goal allows reversing by default.
    w = World(seed=1, driver=lambda o: (-1.0, 0.0))
    road = w.two_way_road()
    w.ego(road.lane(0), s=50.0, speed=0.0, goal={"kind": "park", "x": 40.0, "y": -4.75})
    tr = w.run(2.0)
    assert tr.ego.speed[-1] == pytest.approx(-2.0)


def test_until_and_stop_on_collision_end_the_run_early():
    w = World(seed=1, driver="idm")
    road = w.straight_road()
    w.ego(road.lane(0), s=0.0, speed=10.0)
    tr = w.run(10.0, until=lambda world: world.agent("ego").position[0] > 20.0)
    assert tr.n_steps < 101 and tr.ego.x[-1] > 20.0 and tr.ego.x[-2] <= 20.0
    assert tr.meta["stopped_early"] == "until"

    w = World(seed=1, driver=lambda o: (3.0, 0.0))
    road = w.straight_road()
    w.ego(road.lane(0), s=0.0, speed=10.0)
    w.car(road.lane(0), s=20.0, speed=0.0, behavior=b.stopped())
    tr = w.run(10.0, stop_on_collision=True)
    assert tr.crashed[0, -1] and not tr.crashed[0, -2]
    assert tr.meta["stopped_early"] == "collision" and "ego" in tr.meta["crashed"]


def test_trajectory_is_none_before_run_and_a_world_runs_once():
    w = World(seed=1, driver="idm")
    assert w.trajectory is None
    road = w.straight_road()
    w.ego(road.lane(0))
    w.run(0.5)
    assert w.trajectory.n_steps == 6
    with pytest.raises(SimError, match="runs once"):
        w.run(1.0)
    with pytest.raises(SimError, match="runs once"):
        w.car(road.lane(0), s=50)


# -- bad input ------------------------------------------------------------------------------------


def test_driver_that_raises_becomes_driver_error_with_traceback():
    def broken_policy(obs):
        if obs.t > 0.25:
            raise RuntimeError("perception crashed")
        return 0.0, 0.0

    w = World(seed=1, driver=broken_policy, name="tests/x.py::test_av[3]")
    road = w.straight_road()
    w.ego(road.lane(0))
    with pytest.raises(DriverError) as info:
        w.run(1.0)
    err = info.value
    assert isinstance(err, SimError) and isinstance(err, ValueError)
    msg = str(err)
    assert "tests/x.py::test_av[3]" in msg and "'ego'" in msg
    assert "RuntimeError: perception crashed" in msg and "t=0.30 s" in msg
    assert "broken_policy" in err.driver_traceback and err.agent == "ego"


@pytest.mark.parametrize("answer,needle", [
    ((float("nan"), 0.0), "non-finite"),
    ((1.0, 2.0, 3.0), "shape (3,)"),
    ("fast", "expected (acceleration, steering)"),
    (None, "expected (acceleration, steering)"),
    ({"acceleration": 1.0}, "lacks 'steering'"),
])
def test_bad_driver_answers_are_sim_errors(answer, needle):
    w = World(seed=1, driver=lambda o: answer, name="t_bad")
    road = w.straight_road()
    w.ego(road.lane(0))
    with pytest.raises(SimError) as info:
        w.run(1.0)
    assert not isinstance(info.value, DriverError)
    assert needle in str(info.value) and "t_bad" in str(info.value) and "'ego'" in str(info.value)


def test_unknown_driver_names_and_objects():
    w = World(seed=1, driver="autopilotx", name="t_drv")
    road = w.straight_road()
    with pytest.raises(SimError, match="unknown driver 'autopilotx'"):
        w.ego(road.lane(0))
    with pytest.raises(SimError, match="cannot drive with 42"):
        w.ego(road.lane(0), driver=42)
    with pytest.raises(SimError, match="no module named .no_such_module_xyz."):
        w.ego(road.lane(0), driver="no_such_module_xyz:Policy")


@pytest.mark.parametrize("kwargs,needle", [
    (dict(s=-5.0), "s=-5.0 m is outside lane 'lane[0]'"),
    (dict(s=450.0), "s=450.0 m is outside lane 'lane[0]'"),
    (dict(s=10.0, r=3.0), "r=3.0 m is outside lane 'lane[0]'"),
    (dict(s=float("nan")), "s=nan"),
    (dict(s=10.0, speed=-1.0), "speed=-1.0"),
])
def test_placing_off_the_road_names_test_agent_and_value(kwargs, needle):
    w = World(seed=1, driver="idm", name="t_place")
    road = w.straight_road()
    with pytest.raises(SimError) as info:
        w.car(road.lane(0), **kwargs)
    msg = str(info.value)
    assert needle in msg and "t_place" in msg and "'car1'" in msg


def test_overlapping_agents_at_t0_are_rejected_naming_both():
    w = World(seed=1, driver="idm", name="t_overlap")
    road = w.straight_road()
    w.ego(road.lane(0), s=10.0)
    with pytest.raises(SimError) as info:
        w.car(road.lane(0), s=13.0, name="lead")
    msg = str(info.value)
    assert "'lead'" in msg and "overlaps 'ego'" in msg and "t_overlap" in msg
    w.car(road.lane(0), s=15.5, name="lead")  # 5.5 m apart: bumpers 0.5 m apart, fine


@pytest.mark.parametrize("kwargs,needle", [
    (dict(seconds=0), "run(seconds=0)"),
    (dict(seconds=-1.0), "run(seconds=-1.0)"),
    (dict(seconds=5.0, dt=0), "run(dt=0)"),
    (dict(seconds=5.0, dt=-0.1), "run(dt=-0.1)"),
    (dict(seconds=float("inf")), "run(seconds=inf)"),
    (dict(seconds=5.0, until=3), "until=3"),
])
def test_bad_run_arguments(kwargs, needle):
    w = World(seed=1, driver="idm", name="t_run")
    road = w.straight_road()
    w.ego(road.lane(0))
    with pytest.raises(SimError) as info:
        w.run(**kwargs)
    assert needle in str(info.value) and "t_run" in str(info.value)


def test_misuse_is_explained():
    w = World(seed=1, driver="idm", name="t_misuse")
    with pytest.raises(SimError, match="build a road first"):
        w.car(None)
    road = w.straight_road(lanes=2)
    with pytest.raises(SimError, match="already has a straight road"):
        w.two_way_road()
    with pytest.raises(SimError, match=r"lanes 0\.\.1"):
        road.lane(5)
    with pytest.raises(SimError, match="place the ego first"):
        w.run(1.0)
    with pytest.raises(SimError, match="not a behaviour"):
        w.car(road.lane(0), s=50, behavior="brake")
    with pytest.raises(SimError, match="cannot drive a car"):
        w.car(road.lane(0), s=50, behavior=b.cross())
    w.ego(road.lane(0))
    with pytest.raises(SimError, match="already has an ego"):
        w.ego(road.lane(1))
    with pytest.raises(SimError, match="duplicate agent name 'ego'"):
        w.car(road.lane(1), s=40, name="ego")
    w.car(road.lane(1), s=40, behavior=b.brake_at(decel=3.0))
    with pytest.raises(SimError, match="brake_at needs a time"):
        w.run(1.0)


def test_autopilot_is_resolved_lazily_by_name():
    auto = pytest.importorskip("pytest_avscenario.sim.drivers.autopilot")
    from pytest_avscenario.sim.drivers import resolve

    drv = resolve("autopilot")
    assert isinstance(drv.target, auto.Autopilot)
    w = following(driver="autopilot", seconds=3.0)
    assert w.trajectory.meta["ego_driver"].startswith("PolicyDriver(Autopilot")


def test_agents_appear_and_disappear_on_time_or_condition():
    w = World(seed=1, driver="idm", name="t_appear")
    road = w.straight_road()
    w.ego(road.lane(0), s=0.0, speed=10.0)
    spot = road.lane(0).at(60.0)
    w.car(road.lane(0), s=100.0, speed=10.0, appear=w.ego_within(spot, 20.0),
          disappear=w.ego_past(spot, 5.0), name="late")
    w.car(road.lane(0), s=8.0, speed=10.0, appear=2.0, disappear=4.0, name="timed")
    # Appears on top of the ego at t=0? It waits until its spot is free.
    w.car(road.lane(0), s=2.0, speed=0.0, behavior=b.stopped(), appear=0.0, name="blocked")
    tr = w.run(10.0)
    late, timed, blocked = tr.agent("late"), tr.agent("timed"), tr.agent("blocked")
    on = first(late.present)
    assert abs(tr.ego.x[on - 1] - 60.0) <= 20.0 + 1.0 and abs(tr.ego.x[on - 2] - 60.0) > 20.0
    off = first(~late.present[on:]) + on
    assert tr.ego.x[off] - 2.5 > 65.0 and tr.ego.x[off - 1] - 2.5 <= 65.0 + 1.0
    assert np.isnan(late.x[:on]).all() and late.x[on] == 100.0 and late.lane[0] == ""
    assert np.isnan(late.x[off:]).all() and not late.on_road[off:].any()
    assert timed.present[20:40].all() and not timed.present[:20].any() and not timed.present[40:].any()
    assert timed.x[20] == 8.0  # spawns in its placed state
    assert not blocked.present[0] and blocked.present[-1] and not tr.crashed.any()


def test_bad_appear_values():
    w = World(seed=1, driver="idm", name="t_appear")
    road = w.straight_road()
    with pytest.raises(SimError, match=r"t_appear.*'car1'.*appear=-1"):
        w.car(road.lane(0), s=10, appear=-1)
    with pytest.raises(SimError, match=r"disappear='soon'"):
        w.car(road.lane(0), s=10, disappear="soon", name="c2")


@pytest.mark.parametrize("seed", [-1, "x", None])
def test_bad_seeds(seed):
    with pytest.raises(SimError, match=r"World\(seed="):
        World(seed=seed, name="t_seed")


def test_custom_behaviour_drawing_during_the_run_replays_exactly():
    from dataclasses import dataclass

    @dataclass(frozen=True)
    class Jittery(b.Behavior):
        sigma: float = 1.0

        def control(self, agent, world):
            return float(world.rng.normal(0.0, self.sigma)), agent.follow()

    def run(rng):
        w = World(seed=3, rng=rng, driver="idm")
        road = w.straight_road()
        w.ego(road.lane(0), s=0.0, speed=5.0)
        w.car(road.lane(0), s=40.0, speed=8.0, behavior=Jittery(2.0))
        return w.run(5.0).agent("car1").speed

    a, again = run(np.random.default_rng(5)), run(np.random.default_rng(5))
    assert np.array_equal(a, again) and np.std(np.diff(a)) > 0.05
    assert not np.array_equal(a, run(np.random.default_rng(6)))

"""Behaviour times count from the agent's appearance (``agent.age``), not from t = 0."""

from __future__ import annotations

import numpy as np

from pytest_avscenario.sim import World
from pytest_avscenario.sim import behaviors as b


def first(mask) -> int:
    """Index of the first True (fails the test if none)."""
    mask = np.asarray(mask)
    assert mask.any(), "condition never held"
    return int(np.argmax(mask))


def braking_world(appear):
    w = World(seed=3, driver="idm", name="t_clock")
    road = w.straight_road(lanes=2, length=400)
    w.ego(road.lane(0), s=0.0, speed=0.0, target_speed=0.0)
    w.car(road.lane(1), s=50.0, speed=10.0, behavior=b.brake_at(1.0, decel=6.0), name="car",
          appear=appear)
    return w, w.run(seconds=8.0)


def test_late_car_brakes_one_second_after_it_appeared():
    w, tr = braking_world(appear=3.0)
    car = tr.agent("car")
    on = first(car.present)
    assert abs(tr.t[on] - 3.0) < 1e-9 and w.agent("car").appeared_at == tr.t[on]
    # cruising at 10 m/s for 1 s after appearing, then braking at 6 m/s^2
    np.testing.assert_allclose(car.speed[on:on + 11], 10.0, atol=0.05)
    braking = first(car.speed[on:] < 9.5) + on
    assert abs(tr.t[braking] - 4.1) < 1e-9  # the command applied from t = 4.0 on
    assert abs(car.speed[braking] - 9.4) < 0.05


def test_car_present_from_the_start_brakes_at_the_simulation_time():
    w, tr = braking_world(appear=None)
    car = tr.agent("car")
    assert car.present.all() and w.agent("car").appeared_at == 0.0
    braking = first(car.speed < 9.5)
    assert abs(tr.t[braking] - 1.1) < 1e-9
    assert abs(car.speed[braking] - 9.4) < 0.05


def test_late_pedestrian_waits_from_its_appearance():
    w = World(seed=3, driver="idm", name="t_clock_ped")
    road = w.straight_road(lanes=1, length=400)
    w.ego(road.lane(0), s=0.0, speed=0.0, target_speed=0.0)
    w.pedestrian(road.crosswalk(150.0), behavior=b.cross(wait=2.0, speed=1.4), appear=3.0,
                 name="ped")
    tr = w.run(seconds=8.0)
    ped = tr.agent("ped")
    on = first(ped.present)
    assert abs(tr.t[on] - 3.0) < 1e-9
    start_xy = (ped.x[on], ped.y[on])
    moved = np.hypot(ped.x[on:] - start_xy[0], ped.y[on:] - start_xy[1]) > 1e-6
    steps_off = first(moved) + on
    assert abs(tr.t[steps_off] - 5.1) < 1e-9  # walks from t = 5.0 (2 s after appearing)


def test_age_is_time_since_appearance():
    w = World(seed=3, driver="idm", name="t_age")
    road = w.straight_road(lanes=2, length=400)
    w.ego(road.lane(0), s=0.0, speed=0.0, target_speed=0.0)
    late = w.car(road.lane(1), s=50.0, speed=0.0, behavior=b.stopped(), appear=2.0)
    ages = []
    w.run(seconds=4.0, until=lambda world: ages.append((world.t, late.age, w._ego.age)) and False)
    by_t = {round(t, 6): (a, e) for t, a, e in ages}
    assert by_t[1.0] == (0.0, 1.0)  # not there yet: age 0
    assert abs(by_t[3.5][0] - 1.5) < 1e-9 and abs(by_t[3.5][1] - 3.5) < 1e-9


# -- the school bus stands still while its stop arm is out ----------------------------------------


def test_school_bus_stands_still_with_its_arm_out():
    w = World(seed=1, driver="idm", name="t_bus_still")
    road = w.two_way_road()
    w.ego(road.lane(0), s=0.0, speed=0.0)
    # 8.04 m/s at 2.5 m/s^2 in 0.1 s steps leaves 0.04 m/s, under the 0.05 m/s "stopped" bar
    w.bus(road.lane(0, "backward"), s=20.0, speed=8.04, behavior=b.bus_stop(t=1.0, duration=3.0),
          name="bus", appear=0.5)
    tr = w.run(12.0)
    bus = tr.agent("bus")
    arm = tr.signals["bus.stop_arm"] > 0.5
    start, n = first(arm), int(arm.sum())
    assert n == 30 and arm[start:start + n].all()
    # braking starts 1 s after the bus appeared (t = 1.5 s), 8 m/s at 2.5 m/s^2
    assert abs(tr.t[start] - (1.5 + 8.0 / 2.5)) < 0.25
    assert 0.0 < bus.speed[start - 1] < 0.05
    assert (bus.speed[start:start + n] == 0.0).all()
    assert (bus.x[start:start + n] == bus.x[start]).all()
    assert (bus.y[start:start + n] == bus.y[start]).all()
    assert bus.speed[-1] > 3.0

"""Right of way at all-way stops: first to stop, first to go (ties: the one on the right).

For traffic (``b.turn`` with a stop) and for the built-in autopilot, which infers the arrival
order from what it sees.
"""

from __future__ import annotations

import numpy as np
import pytest

from pytest_avscenario.sim import World
from pytest_avscenario.sim import behaviors as b


def first(mask) -> int:
    """Index of the first True (fails the test if none)."""
    mask = np.asarray(mask)
    assert mask.any(), "condition never held"
    return int(np.argmax(mask))


def stops_and_goes(tr, name):
    """(sample it first stands, sample it moves off again) of agent ``name``."""
    a = tr.agent(name)
    stop = first(a.speed < 0.5)
    go = stop + first(a.speed[stop:] > 0.6)
    return stop, go


def in_box(tr, name, half):
    """Per sample: the agent's centre lies within the box of half size ``half`` [m]."""
    a = tr.agent(name)
    return (np.abs(a.x) < half) & (np.abs(a.y) < half)


def traffic_pair(d_west, d_south, seconds=18.0):
    w = World(seed=1, driver="idm", name="t_allway")
    inter = w.intersection()
    w.ego(inter.exit("south"), s=80)  # out of the way
    w.car(inter.stop_line("west").before(d_west), speed=8.0, behavior=b.turn("straight"),
          name="w")
    w.car(inter.stop_line("south").before(d_south), speed=8.0, behavior=b.turn("straight"),
          name="s")
    return inter, w.run(seconds)


@pytest.mark.parametrize("d_west, d_south, leader", [(20.0, 28.0, "w"), (28.0, 20.0, "s")])
def test_traffic_at_perpendicular_arms_goes_in_the_order_it_stopped(d_west, d_south, leader):
    inter, tr = traffic_pair(d_west, d_south)
    other = "s" if leader == "w" else "w"
    stop_l, go_l = stops_and_goes(tr, leader)
    stop_o, go_o = stops_and_goes(tr, other)
    assert stop_l < stop_o  # it did stop first
    assert go_l < go_o
    # The second one waited, standing, until the first had crossed the box.
    box = in_box(tr, leader, inter.half)
    leaves = first(box) + first(~box[first(box):])
    assert go_o >= leaves
    assert tr.t[go_o] - tr.t[stop_o] > 2.0  # not just its own 1-s stop
    assert not tr.crashed.any()
    assert tr.agent("w").lane[-1] == "east.out[0]" and tr.agent("s").lane[-1] == "north.out[0]"


def test_a_tie_goes_to_the_car_on_the_right():
    # Same distance, same speed: they stop in the same step. For the car from the west the
    # one from the south is on its right.
    inter, tr = traffic_pair(20.0, 20.0)
    stop_w, go_w = stops_and_goes(tr, "w")
    stop_s, go_s = stops_and_goes(tr, "s")
    assert stop_w == stop_s
    assert go_s < go_w
    assert not tr.crashed.any()


def autopilot_world(arm, d_car, car_speed=6.0, behavior=None, seconds=20.0, **ego_kw):
    w = World(seed=1, driver="autopilot", name="t_allway_ap")
    inter = w.intersection(lane_width=5.5)
    w.ego(inter.stop_line("south").before(30.0), speed=6.0, target_speed=9.0,
          route=inter.route("south", "left"), **ego_kw)
    w.car(inter.stop_line(arm).before(d_car), speed=car_speed,
          behavior=behavior if behavior is not None else b.turn("straight", stop_time=3.0),
          name="car")
    return inter, w.run(seconds)


@pytest.mark.parametrize("arm", ["east", "north"])
def test_autopilot_waits_for_a_car_that_stopped_before_it_then_goes(arm):
    # The car stops ~1 s before the ego and stands 3 s: the ego, done with its own stop,
    # must not go while the car is still to go, nor while the car crosses the box.
    inter, tr = autopilot_world(arm, 12.0, seconds=30.0)
    stop_c, go_c = stops_and_goes(tr, "car")
    stop_e, go_e = stops_and_goes(tr, "ego")
    assert stop_c < stop_e and tr.t[go_c] - tr.t[stop_e] > 1.0
    assert go_e > go_c
    # the ego enters the box only once the car's centre has left it
    car_box = in_box(tr, "car", inter.half)
    ego_box = in_box(tr, "ego", inter.half)
    car_out = first(car_box) + first(~car_box[first(car_box):])
    assert first(ego_box) >= car_out
    assert not tr.crashed.any()
    assert tr.ego.lane[-1] == "west.out[0]"


def test_traffic_waits_for_the_autopilot_that_stopped_first():
    inter, tr = autopilot_world("east", 30.0, car_speed=6.0, behavior=b.turn("straight"))
    stop_e, go_e = stops_and_goes(tr, "ego")
    stop_c, go_c = stops_and_goes(tr, "car")
    assert stop_e < stop_c and go_e < go_c
    ego_box = in_box(tr, "ego", inter.half)
    ego_out = first(ego_box) + first(~ego_box[first(ego_box):])
    assert go_c >= ego_out
    assert not tr.crashed.any()


def test_autopilot_does_not_wait_for_a_car_standing_far_back():
    inter, tr = autopilot_world("east", 30.0, car_speed=0.0, behavior=b.stopped())
    stop_e, go_e = stops_and_goes(tr, "ego")
    assert tr.t[go_e] - tr.t[stop_e] < 1.5  # its own stop, nothing more
    assert tr.ego.lane[-1] == "west.out[0]"


def test_autopilot_gives_up_on_a_car_that_stopped_first_but_never_goes():
    # A broken-down car at the east stop line from t = 0: it stopped first, but after
    # allway_patience (8 s) the ego goes anyway.
    inter, tr = autopilot_world("east", 3.0, car_speed=0.0, behavior=b.stopped(), seconds=25.0)
    stop_e, go_e = stops_and_goes(tr, "ego")
    waited = tr.t[go_e] - tr.t[stop_e]
    assert 8.0 < waited < 10.5
    assert tr.ego.lane[-1] == "west.out[0]" and not tr.crashed.any()


def test_traffic_gives_up_on_a_car_that_stopped_first_but_never_goes():
    w = World(seed=1, driver="idm", name="t_allway_stuck")
    inter = w.intersection()
    w.ego(inter.exit("south"), s=80)
    w.car(inter.stop_line("east").before(3.0), speed=0.0, behavior=b.stopped(), name="stuck")
    w.car(inter.stop_line("west").before(20.0), speed=8.0, behavior=b.turn("straight"), name="w")
    tr = w.run(25.0)
    stop_w, go_w = stops_and_goes(tr, "w")
    assert 10.5 < tr.t[go_w] - tr.t[stop_w] < 12.5  # 1 s stop + 10 s patience
    assert tr.agent("w").lane[-1] == "east.out[0]"

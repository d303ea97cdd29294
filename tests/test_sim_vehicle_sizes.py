"""Vehicles of their own size (issue #33, item 7): a truck is as long as it is everywhere —
in highway-env's collision test, in the recording the monitors read, and in the pictures."""

import math

import numpy as np
import pytest

from pytest_avscenario.monitors import collision
from pytest_avscenario.monitors.metrics import footprint_gap
from pytest_avscenario.sim import SimError
from pytest_avscenario.sim.world import World


def _rear_end(length=None, kind="truck"):
    """An ego at 15 m/s driven by a plain policy that never brakes, into a standing vehicle
    whose centre is 40 m ahead of the ego's."""
    w = World(seed=1, driver=lambda obs: (0.0, 0.0), name="t_size")
    road = w.straight_road(lanes=1, length=300)
    w.ego(road.lane(0), s=20.0, speed=15.0)
    w.vehicle(road.lane(0), s=60.0, speed=0.0, kind=kind, length=length)
    w.run(seconds=4)
    return w


def _first_contact_s(w):
    tr = w.trajectory
    k = int(np.argmax(footprint_gap(tr)[0] <= 0.0))
    return tr.t[k]


def test_a_truck_is_hit_where_its_rear_is_not_where_a_car_s_would_be():
    truck = _rear_end(length=16.5)
    car = _rear_end(kind="car")
    tr = truck.trajectory
    assert tr.kinds[1] == "truck" and tr.names[1] == "truck1"
    assert (tr.length[1], tr.width[1]) == (16.5, 2.55)  # the recording carries its size
    # contact when the ego's front (centre + 2.5) meets the truck's rear (60 - 8.25): the ego
    # covers 40 - 8.25 - 2.5 = 29.25 m at 15 m/s, 1.95 s; behind a 5-m car 35 m, 2.33 s
    assert _first_contact_s(truck) == pytest.approx(29.25 / 15.0, abs=0.1)
    assert _first_contact_s(car) == pytest.approx(35.0 / 15.0, abs=0.1)
    result = collision().evaluate(tr)
    assert result.rho < 0 and result.agent == "truck1"
    assert result.t == pytest.approx(29.25 / 15.0, abs=0.1)
    # highway-env's own collision test used the truck's size too: it flagged the crash
    assert truck.agent("ego").crashed and truck.agent("truck1").crashed


def test_the_default_truck_is_a_12_m_rigid_lorry_and_a_car_keeps_its_size():
    w = World(seed=1, name="t_size")
    road = w.straight_road(lanes=2, length=300)
    w.ego(road.lane(1), s=10.0, speed=10.0)
    t = w.vehicle(road.lane(0), s=50.0, speed=10.0, kind="truck")
    c = w.vehicle(road.lane(1), s=80.0, speed=10.0)
    assert (t.LENGTH, t.WIDTH, c.LENGTH, c.WIDTH) == (12.0, 2.55, 5.0, 2.0)
    assert t.diagonal == pytest.approx(math.hypot(12.0, 2.55))
    view = w.view()
    assert {a.name: (a.kind, a.length) for a in view.agents}["truck1"] == ("truck", 12.0)


@pytest.mark.parametrize("kwargs, needle", [
    (dict(length=0), "vehicle length=0: must be a number of metres, 0 < length <= 30"),
    (dict(length=-3.0), "vehicle length=-3.0"),
    (dict(width=float("nan")), "vehicle width=nan: must be a number of metres, 0 < width <= 5"),
    (dict(length=16500), "vehicle length=16500"),  # millimetres
    (dict(width="wide"), "vehicle width='wide'"),
    (dict(length=True), "vehicle length=True"),
    (dict(kind="lorry"), "vehicle kind='lorry': use one of 'car', 'truck'"),
])
def test_a_bad_size_or_kind_names_the_parameter(kwargs, needle):
    w = World(seed=1, name="t_size")
    road = w.straight_road(lanes=1, length=300)
    with pytest.raises(SimError, match=None) as info:
        w.vehicle(road.lane(0), s=50.0, **kwargs)
    assert needle in str(info.value)


def test_the_replay_and_the_still_draw_the_truck_at_its_size(tmp_path):
    from PIL import Image

    from pytest_avscenario.sim.render import render_png
    from pytest_avscenario.sim.clip import clip_data

    w = _rear_end(length=16.5)
    agents = {a["name"]: a for a in clip_data(w)["agents"]}
    assert (agents["truck1"]["L"], agents["truck1"]["W"], agents["truck1"]["kind"]) == (16.5, 2.55, "truck")
    # the still: the truck's colour spans its length in pixels, about 3.3 times a car's 5 m
    path = render_png(w, str(tmp_path / "still.png"), step=0)
    pixels = np.asarray(Image.open(path).convert("RGB")).astype(int)
    truck = np.all(np.abs(pixels - (200, 110, 60)) < 8, axis=2)
    ego = np.all(np.abs(pixels - (60, 200, 80)) < 8, axis=2)
    truck_px = np.ptp(np.flatnonzero(truck.any(axis=0)))
    ego_px = np.ptp(np.flatnonzero(ego.any(axis=0)))
    assert truck_px / ego_px == pytest.approx(16.5 / 5.0, rel=0.1)

"""Offscreen rendering replays the recording: real pixels, every road type, no display."""

from __future__ import annotations

import numpy as np
import pytest
from PIL import Image

from pytest_avscenario.sim import SimError, World
from pytest_avscenario.sim import behaviors as b
from pytest_avscenario.sim.render import COLOURS, GRASS


def scene(kind: str) -> World:
    w = World(seed=1, driver="idm", name=f"render_{kind}")
    if kind == "straight":
        road = w.straight_road(lanes=2)
        w.ego(road.lane(1), s=10.0, speed=8.0)
        w.car(road.lane(1), s=35.0, speed=6.0, behavior=b.brake_at(1.0))
        w.pedestrian(road.crosswalk(60.0), behavior=b.cross(wait=0.5, wait_in_road=5.0))
    elif kind == "two_way":
        road = w.two_way_road()
        w.ego(road.lane(0), s=10.0, speed=8.0)
        w.bus(road.lane(0, "backward"), s=250.0, speed=6.0, behavior=b.bus_stop(t=0.5, duration=5.0))
        w.parked_car(road.parking_lane, s=40.0)
    else:
        inter = w.intersection()
        w.ego(inter.stop_line("south").before(15), speed=6.0, route=inter.route("south", "left"))
        w.car(inter.stop_line("east").before(10), speed=6.0, behavior=b.turn("right", stop=False))
        w.pedestrian(inter.crosswalk("north"), behavior=b.cross(wait_in_road=5.0))
    w.run(4.0)
    return w


def colours(path) -> set[tuple[int, int, int]]:
    arr = np.asarray(Image.open(path).convert("RGB"))
    return {tuple(int(c) for c in px) for px in arr.reshape(-1, 3)}


@pytest.mark.parametrize("kind", ["straight", "two_way", "intersection"])
def test_png_frame_shows_road_and_agents(kind, tmp_path):
    w = scene(kind)
    out = w.render_png(tmp_path / "f.png", step=20)
    im = Image.open(out)
    assert im.size in ((800, 320), (640, 640))
    seen = colours(out)
    assert GRASS in seen and (240, 240, 240) in seen  # grass and lane markings / crosswalks
    assert COLOURS["ego"] in seen
    expected = {"straight": ["car", "pedestrian"], "two_way": ["parked"],
                "intersection": ["car", "pedestrian"]}[kind]
    for k in expected:
        assert COLOURS[k] in seen, k


def test_bus_with_stop_arm_is_drawn(tmp_path):
    w = World(seed=1, driver="idm")
    road = w.two_way_road()
    w.ego(road.lane(0), s=10.0, speed=0.0)
    w.bus(road.lane(0, "backward"), s=250.0, speed=4.0, behavior=b.bus_stop(t=0.2, duration=5.0))
    w.run(3.0)
    seen = colours(w.render_png(tmp_path / "bus.png", step=-1))
    assert COLOURS["bus"] in seen and (255, 40, 40) in seen  # the red stop arm


def test_png_strip_and_gif(tmp_path):
    w = scene("intersection")
    strip = Image.open(w.render_png(tmp_path / "s.png"))
    assert strip.size == (3 * 640, 2 * 640)
    gif = Image.open(w.render_gif(tmp_path / "a.gif", every=5))
    assert gif.n_frames == 9  # 41 samples, every 5th
    assert gif.info["duration"] == 500


def test_render_before_run_is_an_error(tmp_path):
    w = World(seed=1, driver="idm", name="t_render")
    road = w.straight_road()
    w.ego(road.lane(0))
    with pytest.raises(SimError, match="t_render.*call world.run"):
        w.render_png(tmp_path / "x.png")


def test_view_can_be_centred_on_an_agent_or_place(tmp_path):
    w = World(seed=1, driver="idm")
    road = w.two_way_road()
    w.ego(road.lane(0), s=10.0)
    w.bus(road.lane(0, "backward"), s=100.0)  # at x = 200 m
    w.run(0.5)
    far = colours(w.render_png(tmp_path / "ego.png", step=0))
    assert COLOURS["bus"] not in far  # 190 m ahead: outside the window following the ego
    near = colours(w.render_png(tmp_path / "bus.png", step=0, centre="bus1", width=60.0))
    assert COLOURS["bus"] in near
    inter = scene("intersection")
    zoom = colours(inter.render_png(tmp_path / "z.png", step=0, centre=inter.road.centre, width=8))
    assert GRASS not in zoom  # 8 m around the centre: all asphalt

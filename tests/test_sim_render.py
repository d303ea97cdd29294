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


# -- the annotated still's labels (issue #26 item 6) ----------------------------------------------


def dense_scene() -> World:
    """Eight cars within 20 m on three lanes: the ego in the middle, boxed in on every side."""
    w = World(seed=2, driver=lambda obs: (0.0, 0.0), name="dense")
    road = w.straight_road(lanes=3, length=300)
    w.ego(road.lane(1), s=31.0, speed=12.0)
    for i, (lane, s, v) in enumerate([(1, 24.0, 12.5), (1, 38.0, 11.5), (0, 26.0, 12.0), (0, 33.0, 12.2),
                                      (0, 40.0, 11.8), (2, 28.0, 12.1), (2, 36.0, 12.0)]):
        w.car(road.lane(lane), s=s, speed=v, name=f"car{i + 1}")
    w.run(1.0)
    return w


def _box_of(tr, i, step, view):
    """Agent i's footprint at ``step`` as a pixel box of the PNG, from the recording alone."""
    (ox, oy), scale, top = view["origin"], view["scale"], view["top"]
    x, y, h = tr.x[i, step], tr.y[i, step], tr.heading[i, step]
    L, W = tr.length[i] / 2, tr.width[i] / 2
    xs, ys = [], []
    for a, b in ((L, W), (L, -W), (-L, -W), (-L, W)):
        xs.append((x + np.cos(h) * a - np.sin(h) * b - ox) * scale)
        ys.append((oy - (y + np.sin(h) * a + np.cos(h) * b)) * scale + top)
    return min(xs), min(ys), max(xs) - min(xs), max(ys) - min(ys)


def _overlaps(a, b) -> bool:
    return a[0] < b[0] + b[2] and b[0] < a[0] + a[2] and a[1] < b[1] + b[3] and b[1] < a[1] + a[3]


def _gap(a, b) -> float:
    dx = max(b[0] - (a[0] + a[2]), a[0] - (b[0] + b[2]), 0)
    dy = max(b[1] - (a[1] + a[3]), a[1] - (b[1] + b[3]), 0)
    return float(np.hypot(dx, dy))


#: how far [px] a label may sit from its own car's footprint: 40 px is under 7 m at the
#: straight road's 6 px/m, nearer its car than a car length beyond the next lane
NEAR_PX = 40


def test_in_a_dense_scene_every_label_sits_by_its_own_car_and_covers_no_other(tmp_path):
    from pytest_avscenario.monitors import distance
    from pytest_avscenario.sim.render import render_moment
    from pytest_avscenario.report.recording import recording_data

    w = dense_scene()
    tr = w.trajectory
    step = 5
    assert np.ptp(tr.x[:, step]) < 20 and np.ptp(tr.y[:, step]) < 20  # eight cars within 20 m
    rho = distance(5.0, kind="centre").evaluate(tr)
    data = recording_data(w, violations={"distance": {"t": float(tr.t[step]), "agent": "car4", "threshold": 5.0,
                                                   "rho": rho.rho}}, monitors=[distance(5.0, kind="centre")])
    drawn = render_moment(w, str(tmp_path / "dense.png"), data)
    assert drawn["step"] == step
    placed = drawn["placed"]
    assert sorted(placed) == sorted(tr.names)
    cars = {name: _box_of(tr, i, step, drawn["view"]) for i, name in enumerate(tr.names)}
    image = np.asarray(Image.open(drawn["path"]).convert("RGB")).astype(int)
    for name, label in placed.items():
        box = label["box"]
        assert _gap(box, cars[name]) <= NEAR_PX, (name, box, cars[name])
        others = [n for n in cars if n != name and _overlaps(box, cars[n])]
        assert not others, f"{name}'s label {box} covers {others}"
        covered = [n for n, o in placed.items() if n != name and _overlaps(box, o["box"])]
        assert not covered, f"{name}'s label {box} covers the labels of {covered}"
        # the label is drawn where the renderer says: its background fills that box
        x, y, bw, bh = box
        patch = image[y:y + bh, x:x + bw].reshape(-1, 3)
        ground = (255, 150, 0) if name == drawn["critical"] else (35, 35, 40)
        assert (np.abs(patch - ground).sum(axis=1) < 30).mean() > 0.5, name
        # its leader line starts on its own car
        ax, ay = label["anchor"]
        cx, cy, cw, ch = cars[name]
        assert cx <= ax <= cx + cw and cy <= ay <= cy + ch, name

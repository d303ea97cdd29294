"""Road networks: several intersections joined by links, routes across them, medians."""

from __future__ import annotations

import math

import numpy as np
import pytest

from pytest_avscenario.sim import SimError, World
from pytest_avscenario.sim import behaviors as b


def two_intersections(seed: int = 0, driver: str = "autopilot", spacing: float = 200.0,
                      **kw):
    w = World(seed=seed, driver=driver, name="test_net")
    net = w.road_network()
    a = net.intersection("A", at=(0, 0), approach_length=60, **kw)
    c = net.intersection("B", at=(0, spacing), approach_length=60, **kw)
    link = net.connect(a, "north", c, "south")
    return w, net, a, c, link


def lanes_driven(tr, i: int = 0) -> list[str]:
    """The distinct lane ids agent ``i`` was recorded on, in order."""
    out: list[str] = []
    for lane in tr.lane[i]:
        if lane and (not out or out[-1] != lane):
            out.append(lane)
    return out


def test_network_geometry_link_fills_the_gap_between_facing_arms():
    w, net, a, c, link = two_intersections(lane_width=3.5)
    # The link continues A's north exit into B's south approach, and back.
    fwd, back = link.lane(0), link.lane(0, "backward")
    assert np.allclose(fwd.start.position, a.exit("north").end.position)
    assert np.allclose(fwd.end.position, c.approach("south").start.position)
    assert np.allclose(back.start.position, c.exit("south").end.position)
    assert np.allclose(back.end.position, a.approach("north").start.position)
    assert link.length == pytest.approx(200 - 2 * (a.half + 60))
    assert c.centre.x == 0 and c.centre.y == 200
    # Names carry the intersection, so a recorded lane says where the car was.
    assert c.approach("south").id == "B.south.in[0]" and c.crosswalk("west").name == "B.west"
    assert fwd.id == "A.north~B.south[0]"
    with pytest.raises(SimError, match="'forward' or 'backward' \\(forward drives from 'A' to 'B'\\)"):
        link.lane(0, "up")
    assert net["B"] is c and [x.name for x in net.crosswalks[:4]] == [
        "A.north", "A.east", "A.south", "A.west"]
    assert len(net.stop_lines) == 8


def test_route_across_two_intersections_joins_parts_along_the_network():
    w, net, a, c, link = two_intersections()
    r = net.route(a.route("south"), c.route("south", "left"))
    assert [l.id for l in r.lanes] == [
        "A.south.in[0]", "A.south>north[0]", "A.north.out[0]", "A.north~B.south[0]",
        "B.south.in[0]", "B.south>west[0]", "B.west.out[0]"]
    # Bare lanes are joined the same way; the default route goes straight through both.
    assert net.route(a.approach("south"), c.exit("north")).lanes[-2].id == "B.south>north[0]"
    assert [l.id for l in net.default_route(a.approach("south")).lanes][-1] == "B.north.out[0]"
    with pytest.raises(SimError, match="no way from 'A.east.out\\[0\\]' to 'B.south.in\\[0\\]'"):
        net.route(a.exit("east"), c.approach("south"))


@pytest.mark.parametrize("driver", ["autopilot", "idm"])
def test_ego_drives_through_both_intersections_to_the_end_of_its_route(driver):
    w, net, a, c, link = two_intersections(driver=driver, lane_width=5.5)
    w.ego(a.approach("south"), s=5, speed=10, route=net.route(a.route("south"),
                                                             c.route("south", "left")))
    tr = w.run(45)
    assert tr.meta["ego_reached_route_end"] and not tr.meta["crashed"]
    assert lanes_driven(tr) == list(tr.meta["ego_route"])
    assert tr.meta["road"] == "network" and tr.meta["intersections"] == ["A", "B"]
    if driver == "autopilot":
        # It stops at each all-way stop line on the way.
        near_b = np.hypot(tr.x[0], tr.y[0] - 200) < 25
        near_a = np.hypot(tr.x[0], tr.y[0]) < 25
        assert tr.speed[0][near_a].min() < 0.1 and tr.speed[0][near_b].min() < 0.1


def test_traffic_turns_at_the_intersection_it_drives_toward():
    w, net, a, c, link = two_intersections(driver="idm")
    w.ego(a.approach("west"), s=5, speed=0.0, route=a.route("west", "straight"))
    # A car on A's north exit lane turns at B, the next intersection on its way.
    w.car(a.exit("north"), s=10, speed=8, behavior=b.turn("right"))
    tr = w.run(40)
    driven = lanes_driven(tr, 1)
    assert driven[-2:] == ["B.south>east[0]", "B.east.out[0]"] and "A.north~B.south[0]" in driven


def test_yield_queries_refer_to_the_agents_own_intersection():
    w, net, a, c, link = two_intersections()
    w.ego(c.approach("south"), s=45, speed=0.0, route=c.route("south"))
    at_a = w.car(a.approach("east"), s=40)
    at_b = w.car(c.approach("east"), s=40)
    w.run(0.1)
    # The ego stands near B's stop line: in B's conflict zone, 200 m from A's centre.
    assert w.ego_in_conflict(at_b) and not w.ego_in_conflict(at_a)
    assert w.ego_distance_to_centre(at_b) < 30 < 150 < w.ego_distance_to_centre(at_a)
    assert w.ego_distance_to_centre() == w.ego_distance_to_centre(at_b)  # the ego's own


def test_same_seed_same_bits_on_a_network():
    def run():
        w, net, a, c, link = two_intersections(seed=7, lane_width=5.5)
        w.ego(a.approach("south"), s=5, speed=11, route=net.route(a.route("south"),
                                                                 c.route("south")))
        w.car(c.approach("west"), s=30, speed=9, behavior=b.turn("straight", stop=False))
        w.pedestrian(c.crosswalk("south"), behavior=b.cross(wait=1.0),
                     appear=w.ego_within(c.centre, 50))
        return w.run(30)

    t1, t2 = run(), run()
    for field in ("x", "y", "speed", "heading", "present"):
        assert np.array_equal(getattr(t1, field), getattr(t2, field), equal_nan=True)
    assert t1.present[2].any() and not t1.present[2, 0]


@pytest.mark.parametrize("call, match", [
    (lambda net, a, c: net.connect(a, "north", c, "east"), "must face each other"),
    (lambda net, a, c: net.connect(a, "up", c, "south"), "unknown arm 'up'"),
    (lambda net, a, c: net.connect(a, "north", a, "south"), "two different intersections"),
    (lambda net, a, c: net.connect(a, "south", c, "north"), "not in line|apart"),
])
def test_bad_connections_are_refused_with_the_reason(call, match):
    w = World(seed=0, name="test_net")
    net = w.road_network()
    a = net.intersection("A", at=(0, 0), approach_length=60)
    c = net.intersection("B", at=(0, 200), approach_length=60)
    with pytest.raises(SimError, match=match) as err:
        call(net, a, c)
    assert "test_net" in str(err.value)


def test_network_building_errors():
    w = World(seed=0, name="test_net")
    net = w.road_network()
    a = net.intersection("A", at=(0, 0), approach_length=60)
    with pytest.raises(SimError, match="'B'.* overlaps 'A'"):
        net.intersection("B", at=(100, 0), approach_length=60)
    with pytest.raises(SimError, match="name is taken"):
        net.intersection("A", at=(0, 500))
    c = net.intersection("B", at=(0, a.half * 2 + 120.2), approach_length=60)
    # The refused "B" left nothing behind: one lane per node pair in highway-env's network.
    assert len(w._road.network.graph["B.south.start"]["B.south.stop"]) == 1
    with pytest.raises(SimError, match="0.20 m apart; need at least 0.5 m"):
        net.connect(a, "north", c, "south")
    d = net.intersection("C", at=(3.0, -300), approach_length=60)
    with pytest.raises(SimError, match="not in line .*3.00 m to the side"):
        net.connect(d, "north", a, "south")
    e = net.intersection(at=(300, 0), approach_length=60, lanes=2)
    assert e.name == "D"
    with pytest.raises(SimError, match="the arms differ"):
        net.connect(a, "east", e, "west")
    w.ego(a.approach("south"))
    with pytest.raises(SimError, match="build the whole network before placing agents"):
        net.intersection("E", at=(0, 900))
    empty = World(seed=0, name="test_net")
    empty.road_network()
    with pytest.raises(SimError, match="build a road first"):
        empty.ego(None)
    with pytest.raises(SimError, match="already has a network road"):
        empty.intersection()


def test_median_separates_the_directions():
    w = World(seed=0)
    road = w.two_way_road(lanes=1, median=2.0, parking=False)
    fwd, back = road.lane(0), road.lane(0, "backward")
    assert back.position(10)[1] - fwd.position(10)[1] == pytest.approx(3.5 + 2.0)
    w2 = World(seed=0)
    inter = w2.intersection(median=2.0)
    assert inter.half == pytest.approx(3.5 + 1.0 + 6.0)
    # Every turn connects seamlessly from its approach to its exit.
    for arm in ("north", "east", "south", "west"):
        for turn in ("left", "right", "straight"):
            r = inter.route(arm, turn)
            for p, q in zip(r.lanes, r.lanes[1:]):
                assert np.allclose(p.end.position, q.start.position, atol=1e-9)
    # The crosswalk spans both directions and the median.
    cw = inter.crosswalk("south").path.array
    assert abs(cw[0, 0] - cw[-1, 0]) == pytest.approx(2 * (3.5 + 1.0 + 2.0))
    with pytest.raises(SimError, match="median=-1"):
        World(seed=0).two_way_road(median=-1)


def test_network_frame_follows_the_ego(tmp_path):
    from PIL import Image

    w, net, a, c, link = two_intersections()
    w.ego(a.approach("south"), s=5, speed=10, route=net.route(a.route("south"), c.route("south")))
    w.run(2)
    out = w.render_png(str(tmp_path / "f.png"), step=0)
    im = np.asarray(Image.open(out).convert("RGB"))
    assert im.shape == (640, 640, 3)
    # The ego (green) is drawn at the centre of the frame.
    mid = im[300:340, 300:340].reshape(-1, 3)
    assert any(tuple(p) == (60, 200, 80) for p in mid)
    assert not math.isnan(w.trajectory.x[0, 0])


@pytest.mark.parametrize("driver", ["autopilot", "idm"])
def test_ego_placed_beside_its_route_merges_onto_it(driver):
    w = World(seed=0, driver=driver, name="test_merge")
    inter = w.intersection(lanes=2, approach_length=100)
    w.ego(inter.approach("south", 1), s=40, speed=3, route=inter.route("south", "left"))
    w.car(inter.approach("south", 0), s=70, speed=0, behavior=b.turn("left"))
    tr = w.run(25)
    driven = lanes_driven(tr)
    assert driven[:2] == ["south.in[1]", "south.in[0]"] and "south>west[0]" in driven
    assert not tr.meta["crashed"]
    # It is in its new lane well before the stop line, not at the box.
    k = first(tr.lane[0] == "south.in[0]")
    assert tr.y[0, k] < -50
    w2 = World(seed=0)
    inter2 = w2.intersection(lanes=2)
    with pytest.raises(SimError, match="not on its route .* nor beside its first lane"):
        w2.ego(inter2.approach("south", 1), route=inter2.route("north"))


def first(mask) -> int:
    mask = np.asarray(mask)
    assert mask.any(), "condition never held"
    return int(np.argmax(mask))

"""Road types, places, agent kinds and behaviours: each does what its name says."""

from __future__ import annotations

import math

import numpy as np
import pytest

from pytest_avscenario.sim import SimError, World
from pytest_avscenario.sim import behaviors as b
from pytest_avscenario.sim.places import Crosswalk, Route, StopLine


def first(mask) -> int:
    """Index of the first True (fails the test if none)."""
    mask = np.asarray(mask)
    assert mask.any(), "condition never held"
    return int(np.argmax(mask))


# -- geometry and places --------------------------------------------------------------------------


def test_two_way_road_lanes_and_parking():
    w = World(seed=1, driver="idm")
    road = w.two_way_road(lanes=2, length=300)
    f0, f1 = road.lane(0), road.lane(1)
    k0 = road.lane(0, direction="backward")
    assert f0.heading_at(0) == 0.0 and abs(k0.heading_at(0)) == pytest.approx(math.pi)
    # Right-hand traffic: forward lanes south of the centre line, lane 0 next to it.
    assert f0.position(10)[1] == pytest.approx(-1.75) and f1.position(10)[1] == pytest.approx(-5.25)
    assert k0.position(10)[1] == pytest.approx(1.75) and k0.position(0)[0] == pytest.approx(300)
    p = road.parking_lane
    assert p.kind == "parking" and p.position(0)[1] == pytest.approx(-(7.0 + 1.25))
    assert road.parking("backward").position(0)[1] == pytest.approx(8.25)
    with pytest.raises(SimError, match="'forward' or 'backward'"):
        road.lane(0, direction="up")
    w2 = World(seed=1, driver="idm")
    with pytest.raises(SimError, match="no parking lanes"):
        w2.two_way_road(parking=False).parking_lane


def test_intersection_places():
    w = World(seed=1, driver="idm")
    inter = w.intersection(lanes=2, approach_length=80)
    south = inter.approach("south")
    assert south.id == "south.in[0]" and south.length == pytest.approx(80)
    assert south.heading_at(0) == pytest.approx(math.pi / 2)  # northbound
    assert south.position(0)[0] > 0  # right-hand traffic: east of the centre line
    sl = inter.stop_line("south")
    assert isinstance(sl, StopLine) and sl.s == pytest.approx(80 - 3.0 - 1.0)
    spot = sl.before(20)
    assert spot.lane is south and sl.distance_to(spot) == pytest.approx(20)
    assert inter.centre.distance_to(inter.exit("north").start) == pytest.approx(
        math.hypot(inter.half, 1.75))
    r = inter.route("south", "left")
    assert isinstance(r, Route) and [l.id for l in r] == ["south.in[0]", "south>west[0]", "west.out[0]"]
    assert [l.id for l in inter.route("south", "right")] == ["south.in[1]", "south>east[1]", "east.out[1]"]
    assert [l.id for l in inter.route("east", "straight", lane=1)] == ["east.in[1]", "east>west[1]", "west.out[1]"]
    cw = inter.crosswalk("north")
    assert isinstance(cw, Crosswalk) and cw.sides == ("west", "east")
    assert cw.walk("west").position[0] < 0 < cw.walk("east").position[0]
    with pytest.raises(SimError, match="no right turn from lane 0"):
        inter.route("south", "right", lane=0)
    with pytest.raises(SimError, match="unknown arm 'up'"):
        inter.approach("up")
    with pytest.raises(SimError, match="unknown turn 'u-turn'"):
        inter.route("south", "u-turn")
    with pytest.raises(SimError, match="one or two lanes"):
        World(seed=1).intersection(lanes=3)


# -- intersection behaviours -----------------------------------------------------------------------


@pytest.mark.parametrize("lanes", [1, 2])
@pytest.mark.parametrize("turn", ["left", "straight", "right"])
@pytest.mark.parametrize("arm", ["north", "east", "south", "west"])
def test_turning_cars_end_on_the_exit_their_turn_names(arm, turn, lanes):
    w = World(seed=1, driver="idm")
    inter = w.intersection(lanes=lanes)
    w.ego(inter.exit(arm), s=70, speed=0.0)  # out of the way
    lane = lanes - 1 if turn == "right" else 0
    w.car(inter.stop_line(arm, lane).before(10), speed=6.0, behavior=b.turn(turn, stop=False))
    tr = w.run(8.0)
    car = tr.agent("car1")
    target = inter.turn_target(arm, turn)
    assert list(dict.fromkeys(car.lane)) == [
        f"{arm}.in[{lane}]", f"{arm}>{target}[{lane}]", f"{target}.out[{lane}]"]
    assert np.nanmax(np.abs(car.lane_offset)) < 0.8
    assert not car.crashed.any() and car.on_road.all()
    end_heading = {"north": 90, "east": 0, "south": -90, "west": 180}[target]
    assert abs(((np.degrees(car.heading[-1]) - end_heading) + 180) % 360 - 180) < 3


def test_turn_stops_at_the_stop_line_then_goes():
    w = World(seed=1, driver="idm")
    inter = w.intersection()
    w.ego(inter.exit("south"), s=60)
    w.car(inter.stop_line("west").before(25), speed=8.0, behavior=b.turn("straight", stop_time=2.0))
    tr = w.run(16.0)
    car = tr.agent("car1")
    front = car.x + 2.5  # heading east
    line_x = inter.stop_line("west").position[0]
    stopped = first(car.speed < 0.5)
    assert line_x - 3.0 < front[stopped] <= line_x
    assert (car.speed[stopped: stopped + 15] < 0.6).all()  # stands for ~2 s
    assert car.lane[-1] == "east.out[0]"


def test_turn_across_waits_for_the_ego_then_goes_without_yielding():
    w = World(seed=1, driver="idm")
    inter = w.intersection()
    w.ego(inter.stop_line("south").before(60), speed=10.0, route=inter.route("south", "straight"))
    w.car(inter.stop_line("north").before(3.0), speed=0.0,
          behavior=b.turn_across("left", go_when_ego_within=25.0, speed=8.0))
    tr = w.run(10.0)
    car = tr.agent("car1")
    go = first(car.speed > 0.3)
    d_ego = np.hypot(tr.ego.x, tr.ego.y)
    assert d_ego[go - 1] <= 25.0 + 1.5 and d_ego[go - 5] > 25.0
    assert "north>east[0]" in set(car.lane)
    # IDM cannot see crossing traffic and the turner does not yield: they come within 4 m.
    assert np.hypot(tr.ego.x - car.x, tr.ego.y - car.y).min() < 4.0


def test_cut_across_runs_the_stop_line_at_constant_speed():
    w = World(seed=1, driver="idm")
    inter = w.intersection()
    w.ego(inter.exit("south"), s=60)
    w.car(inter.stop_line("east").before(30), speed=9.0, behavior=b.cut_across())
    w.car(inter.stop_line("west").before(20), speed=0.0, behavior=b.cut_across(7.0, start_at=2.0))
    tr = w.run(8.0)
    a, c = tr.agent("car1"), tr.agent("car2")
    assert a.speed.min() == pytest.approx(9.0) and a.lane[-1] == "west.out[0]"
    assert (c.speed[:20] == 0).all() and c.speed[-1] == pytest.approx(7.0, abs=0.2)
    assert "west>east[0]" in set(c.lane)


def test_idm_ego_follows_its_route_through_a_left_turn():
    w = World(seed=1, driver="idm")
    inter = w.intersection(lanes=2)
    w.ego(inter.stop_line("south").before(30), speed=6.0, route=inter.route("south", "left"))
    tr = w.run(12.0)
    assert list(dict.fromkeys(tr.ego.lane)) == ["south.in[0]", "south>west[0]", "west.out[0]"]
    assert tr.meta["ego_route"] == ["south.in[0]", "south>west[0]", "west.out[0]"]
    assert tr.meta["ego_route_index"] == 2


def test_observation_lists_the_stop_line_and_crosswalks_on_the_route():
    seen = []

    def creep(obs):
        seen.append(obs)
        return (1.0 if obs.ego.speed < 5 else 0.0), 0.0

    w = World(seed=1, driver=creep)
    inter = w.intersection()
    w.ego(inter.stop_line("south").before(40), speed=3.0, route=inter.route("south", "straight"))
    w.pedestrian(inter.crosswalk("south"), behavior=b.cross(wait=100))
    w.run(1.0)
    o = seen[0]
    kinds = [(sl.route_index, sl.kind) for sl in o.stop_lines]
    assert kinds[:2] == [(0, "stop"), (0, "crosswalk")] and (2, "crosswalk") in kinds
    assert o.stop_lines[0].s == pytest.approx(inter.stop_line("south").s)
    assert o.s == pytest.approx(inter.stop_line("south").s - 40)
    assert len(o.route) == 3 and o.agents[0].kind == "pedestrian"


# -- two-way road behaviours ------------------------------------------------------------------------


def test_encroaching_car_crosses_the_centre_line_by_its_offset():
    w = World(seed=1, driver="idm")
    road = w.two_way_road()
    w.ego(road.lane(0), s=0.0, speed=0.0)
    w.car(road.lane(0, "backward"), s=0.0, speed=10.0, behavior=b.encroach(1.5, at=2.0, duration=4.0))
    tr = w.run(10.0)
    car = tr.agent("car1")
    assert np.abs(car.lane_offset[:20]).max() < 1e-6
    assert car.lane_offset[50:61].min() == pytest.approx(1.5, abs=0.1)
    # Its left side (y - 1 m, heading west) is over the centre line, in the ego's lane.
    assert (car.y[50:61] - 1.0).max() < -0.6
    assert np.abs(car.lane_offset[-5:]).max() < 0.2  # back after 4 s
    assert set(car.lane) == {"backward[0]"} and car.on_road.all()


def test_parked_car_pulls_out_into_the_travel_lane():
    w = World(seed=1, driver="idm")
    road = w.two_way_road()
    w.ego(road.lane(0), s=0.0, speed=0.0)
    w.parked_car(road.parking_lane, s=40.0)
    w.parked_car(road.parking_lane, s=60.0, behavior=b.pull_out(at=2.0, speed=8.0))
    tr = w.run(10.0)
    still, mover = tr.agent("parked1"), tr.agent("parked2")
    assert tr.kinds == ("ego", "parked", "parked")
    assert (still.speed == 0).all() and set(still.lane) == {"parking.forward"}
    assert (mover.speed[:21] == 0).all() and mover.speed[-1] > 5.0
    assert mover.lane[-1] == "forward[0]" and abs(mover.lane_offset[-1]) < 0.3


def test_school_bus_stops_and_shows_its_stop_arm():
    w = World(seed=1, driver="idm")
    road = w.two_way_road()
    w.ego(road.lane(0), s=0.0, speed=0.0)
    w.bus(road.lane(0, "backward"), s=20.0, speed=8.0, behavior=b.bus_stop(t=1.0, duration=3.0),
          name="school_bus")
    tr = w.run(12.0)
    bus = tr.agent("school_bus")
    arm = tr.signals["school_bus.stop_arm"]
    assert tr.kinds[1] == "bus" and bus.length == 12.0 and bus.width == 2.55
    out = arm > 0.5
    start, n = first(out), int(out.sum())
    assert n == pytest.approx(30, abs=1)  # 3 s at 0.1 s
    assert (bus.speed[start:start + n] < 0.05).all() and bus.speed[-1] > 3.0
    assert (bus.speed[:10] == 8.0).all() and arm[:start].max() == 0.0
    assert start == pytest.approx(10 + 8.0 / 2.5 / 0.1, abs=2)


def test_bus_stops_at_a_place():
    w = World(seed=1, driver="idm")
    road = w.two_way_road()
    w.ego(road.lane(0), s=0.0, speed=0.0)
    stop = road.lane(0, "backward").at(120.0)
    w.bus(road.lane(0, "backward"), s=50.0, speed=10.0, behavior=b.bus_stop(at=stop, duration=2.0))
    tr = w.run(15.0)
    arm = tr.signals["bus1.stop_arm"]
    i = first(arm > 0.5)
    s_bus = 300.0 - tr.agent("bus1").x[i]
    assert s_bus == pytest.approx(120.0, abs=2.0)


# -- pedestrians ---------------------------------------------------------------------------------------


def test_pedestrian_waits_enters_the_road_pauses_and_crosses():
    w = World(seed=1, driver="idm")
    road = w.two_way_road()
    w.ego(road.lane(0), s=0.0, speed=0.0)
    cw = road.crosswalk(100.0)
    w.pedestrian(cw, speed=1.5, behavior=b.cross(wait=2.0, wait_in_road=3.0))
    tr = w.run(20.0)
    p = tr.agent("pedestrian1")
    assert tr.kinds[1] == "pedestrian" and p.length == pytest.approx(0.6)
    assert (p.speed[:21] == 0).all() and p.y[20] == p.y[0]
    assert not p.on_road[0]  # starts on the sidewalk
    enter = first(p.on_road)
    # kerb at y = -(3.5 + 2.5) m, sidewalk start 2 m further: 2 m at 1.5 m/s after the wait.
    assert tr.t[enter] == pytest.approx(2.0 + 2.0 / 1.5, abs=0.15)
    assert p.lane[enter] == "parking.forward"
    moving = p.speed > 0
    pause = first((~moving) & (np.arange(tr.n_steps) > enter))
    assert p.lane[pause] == "forward[0]" and p.y[pause] == pytest.approx(-1.75, abs=0.1)
    assert int((~moving[pause:pause + 40]).sum()) == pytest.approx(30, abs=1)
    assert p.y[-1] == pytest.approx(6.0 + 2.0) and not p.on_road[-1]


def test_pedestrian_collides_like_a_vehicle():
    w = World(seed=1, driver=lambda o: (0.0, 0.0))
    road = w.straight_road()
    w.ego(road.lane(0), s=0.0, speed=10.0)
    cw = road.crosswalk(40.0)
    w.pedestrian(cw, speed=1.4, behavior=b.cross(wait=0.5, wait_in_road=10.0))
    tr = w.run(6.0)
    assert tr.crashed[0].any() and tr.crashed[1].any()
    assert first(tr.crashed[0]) == first(tr.crashed[1])


def test_pedestrian_on_explicit_path_and_bad_paths():
    w = World(seed=1, driver="idm", name="t_ped")
    road = w.straight_road()
    w.ego(road.lane(0))
    w.pedestrian([(50, -10), (50, 5), (60, 5)], speed=2.0)
    tr = w.run(14.0)
    p = tr.agent("pedestrian1")
    assert p.x[-1] == pytest.approx(60.0) and p.y[-1] == pytest.approx(5.0)
    assert p.heading[-1] == pytest.approx(0.0) and p.heading[10] == pytest.approx(math.pi / 2)
    w = World(seed=1, driver="idm", name="t_ped")
    w.straight_road()
    with pytest.raises(SimError, match=r"t_ped.*'pedestrian1'.*at least 2 points"):
        w.pedestrian([(0, 0)])
    with pytest.raises(SimError, match="non-finite"):
        w.pedestrian([(0, 0), (float("nan"), 1)], name="p2")
    inter_world = World(seed=1, driver="idm")
    inter = inter_world.intersection()
    with pytest.raises(SimError, match="has sides"):
        inter_world.pedestrian(inter.crosswalk("north"), side="north")


def test_vehicles_stop_for_a_pedestrian_in_their_path():
    w = World(seed=1, driver="idm")
    road = w.straight_road()
    w.ego(road.lane(0), s=0.0, speed=0.0)
    w.car(road.lane(0), s=10.0, speed=10.0)
    w.pedestrian(road.crosswalk(60.0), behavior=b.cross(wait_in_road=30.0))
    tr = w.run(12.0)
    assert not tr.crashed.any() and tr.agent("car1").speed[-1] < 0.1


# -- lane tracking -----------------------------------------------------------------------------------------


def test_tracked_lane_agrees_with_highway_envs_full_scan():
    w = World(seed=1, driver="idm")
    inter = w.intersection(lanes=2)
    w.ego(inter.stop_line("south").before(20), speed=8.0, route=inter.route("south", "left"))
    w.car(inter.stop_line("north", 1).before(15), speed=8.0, behavior=b.turn("right", stop=False))
    w.car(inter.stop_line("east").before(15), speed=8.0, behavior=b.turn("straight", stop=False))
    tr = w.run(8.0)
    net = w._road.network
    ids = {l.index: l.id for l in w.lane_index.order}
    agree = total = 0
    for i in range(tr.n_agents):
        for k in range(tr.n_steps):
            p = np.array([tr.x[i, k], tr.y[i, k]])
            mine = w.lane_index.lanes[next(ix for ix, v in ids.items() if v == tr.lane[i, k])]
            theirs = net.get_lane(net.get_closest_lane_index(p, tr.heading[i, k]))
            total += 1
            # Overlapping connectors tie at their shared start; count a tie as agreement.
            s1, r1 = mine.geometry.local_coordinates(p)
            s2, r2 = theirs.local_coordinates(p)
            agree += mine.geometry is theirs or abs(abs(r1) - abs(r2)) < 0.05
    assert agree / total > 0.97


def test_turn_yielding_to_the_ego_goes_after_it_passed():
    w = World(seed=1, driver="idm")
    inter = w.intersection()
    w.ego(inter.stop_line("south").before(10), speed=10.0, route=inter.route("south", "straight"))
    w.car(inter.stop_line("north").before(3.0), speed=0.0,
          behavior=b.turn("left", yield_to_ego=True, stop_time=0.5))
    tr = w.run(12.0)
    car = tr.agent("car1")
    go = first(car.speed > 0.3)
    assert tr.ego.y[go] > 0.0  # the ego is through the centre before the turner moves
    assert not tr.crashed.any() and car.lane[-1] == "east.out[0]"


def test_a_car_placed_standing_turns_at_the_speed_limit():
    w = World(seed=1, driver="idm")
    inter = w.intersection(speed_limit=9.0)
    w.ego(inter.exit("south"), s=60)
    w.car(inter.stop_line("west").before(40), speed=0.0, behavior=b.turn("straight", stop=False))
    tr = w.run(12.0)
    assert tr.agent("car1").speed.max() == pytest.approx(9.0, abs=0.3)


def test_lanes_of_another_world_are_rejected():
    w1, w2 = World(seed=1, driver="idm"), World(seed=1, driver="idm", name="t_other")
    r1, _ = w1.straight_road(), w2.straight_road()
    with pytest.raises(SimError, match="another world's road"):
        w2.ego(r1.lane(0))


def test_ego_placed_on_a_route_and_broken_routes():
    w = World(seed=1, driver="idm", name="t_route")
    inter = w.intersection()
    w.ego(inter.route("west", "right"), s=50.0, speed=5.0)
    assert w.agent("ego").plan[-1].id == "south.out[0]"
    w2 = World(seed=1, driver="idm", name="t_route")
    inter2 = w2.intersection()
    with pytest.raises(SimError, match=r"route is broken: 'north.out\[0\]' starts"):
        w2.ego(inter2.approach("south"), route=[inter2.approach("south"), inter2.exit("north")])
    with pytest.raises(SimError, match=r"not on its route"):
        w2.ego(inter2.approach("east"), route=inter2.route("south", "left"))

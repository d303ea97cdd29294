"""Traffic signals: parsed from OpenDRIVE files (Town06's CARLA lights, a straight road with
lights of its own), switched by a fixed-time plan, obeyed by the drivers, judged by
``ran_red_light`` against closed forms and charged 0.7 in the driving score."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from pytest_avscenario.monitors import MonitorError, driving_score, ran_red_light
from pytest_avscenario.sim.errors import SimError
from pytest_avscenario.sim.opendrive import MapError, load
from pytest_avscenario.sim.signals import TrafficLights, map_signals, must_stop
from pytest_avscenario.sim.world import World
from pytest_avscenario.trajectory import Trajectory

ROOT = Path(__file__).resolve().parents[1]
TOWN06 = ROOT / "example_tests" / "maps" / "Town06.xodr"
STRAIGHT = ROOT / "tests" / "data" / "maps" / "straight_500m.xodr"

# a light at s=200 for the eastbound lane (no validity: its orientation's lanes) and one at
# s=300 for the westbound lane (validity lane 1), on two controllers of one junction's plan
SIGNALS = """<signals>
  <signal id="5" name="east" s="200" t="-5" orientation="+" dynamic="yes" country="OpenDRIVE"
          type="1000001" subtype="-1" hOffset="0"/>
  <signal id="6" name="west" s="300" t="5" orientation="-" dynamic="yes" country="OpenDRIVE"
          type="1000001" subtype="-1">
    <validity fromLane="1" toLane="1"/>
  </signal>
  <signal id="7" name="stop" s="400" t="-5" orientation="+" dynamic="no" type="206"/>
</signals>
"""
CONTROLLERS = """<controller id="10" name="c10" sequence="0"><control signalId="5" type=""/></controller>
<controller id="11" name="c11" sequence="1"><control signalId="6" type=""/></controller>
"""


def signalled_road(tmp_path: Path, signals: str = SIGNALS, controllers: str = CONTROLLERS) -> Path:
    text = STRAIGHT.read_text()
    text = text.replace("</road>", signals + "</road>", 1)
    text = text.replace("</OpenDRIVE>", controllers + "</OpenDRIVE>", 1)
    path = tmp_path / "signalled.xodr"
    path.write_text(text)
    return path


def test_town06_lights_with_their_stop_positions_and_junction_controllers():
    found = map_signals(load(TOWN06))
    lights = found.of_kind("traffic_light")
    assert len(lights) == 19 and len(found.signals) == 19
    assert len([c for c in found.controllers.values() if not c.id.startswith("signal:")]) == 19
    # junction 72 lists controller 1241 (sequence 1) and 1243 (sequence 3): that order
    assert found.groups["72"] == ("1241", "1243")
    light = found.signals["1238"]
    stops = {p.lane: p for p in light.stops}
    # its references sit at the start of the junction's connecting lanes 1164/0/-3..-6
    assert set(stops) == {"1164/0/-3", "1164/0/-4", "1164/0/-5", "1164/0/-6"}
    for p in stops.values():
        assert p.s == pytest.approx(0.0, abs=1e-9) and math.isfinite(p.x) and math.isfinite(p.y)
    assert all(s.stops for s in lights)


def test_orientation_and_validity_choose_the_lanes_and_the_stop_position(tmp_path):
    data = load(signalled_road(tmp_path))
    found = map_signals(data)
    east, west, stop = found.signals["5"], found.signals["6"], found.signals["7"]
    assert east.kind == "traffic_light" and stop.kind == "stop_sign"
    assert [(p.lane, round(p.s, 6)) for p in east.stops] == [("1/0/-1", 200.0)]
    # the westbound lane runs against the reference line: s=300 is 200 m along it
    assert [(p.lane, round(p.s, 6)) for p in west.stops] == [("1/0/1", 200.0)]
    assert (east.x, east.y) == pytest.approx((200.0, -5.0))
    assert east.heading == pytest.approx(0.0) and abs(west.heading) == pytest.approx(math.pi)
    assert found.groups == {"controller:10": ("10",), "controller:11": ("11",)}


@pytest.mark.parametrize("bad, match", [
    ('<signals><signal id="5" s="abc" type="1000001"/></signals>', r"road 1 <signal id='5'> has s='abc'"),
    ('<signals><signalReference id="99" s="10" orientation="+"/></signals>',
     r"<signalReference id='99'> refers to no <signal>"),
    ('<signals><signal id="5" s="10" type="1000001"><validity fromLane="x" toLane="1"/></signal></signals>',
     r"<signal id='5'> <validity> has fromLane='x'"),
])
def test_a_malformed_signal_names_the_file_and_the_element(tmp_path, bad, match):
    path = signalled_road(tmp_path, bad, "")
    with pytest.raises(MapError, match=match) as err:
        map_signals(load(path))
    assert str(path) in str(err.value)


def test_a_controller_of_an_unknown_signal_is_an_error(tmp_path):
    path = signalled_road(tmp_path, controllers='<controller id="3"><control signalId="42"/></controller>')
    with pytest.raises(MapError, match=r"<controller id='3'> controls signal '42'"):
        map_signals(load(path))


def test_the_phase_plan_takes_turns_and_shifts_with_the_offset(tmp_path):
    lights = TrafficLights(map_signals(load(signalled_road(tmp_path))))
    t = np.arange(0.0, 60.0, 0.1)
    a = lights.codes("5", t)
    # lone controllers alternate with an all-red turn: green 10 s, amber 3 s, red 17 s
    assert lights.cycle_of("controller:10") == 30.0
    assert (a[t < 10 - 1e-9] == 0).all() and (a[(t >= 10) & (t < 13 - 1e-9)] == 1).all()
    assert (a[(t >= 13) & (t < 30 - 1e-9)] == 2).all() and a[300] == 0
    lights.configure(green=20, amber=4, all_red=1, offset=5.0)
    assert lights.state("5", 0.0) == "green" and lights.state("5", 15.0) == "amber"
    assert lights.state("5", 19.0) == "red" and lights.state("5", 50.0) == "green"
    assert [lights.state("5", x) for x in t[::7]] == [lights.state("5", x + 50.0) for x in t[::7]]
    with pytest.raises(SimError, match=r"world.signals\(green=-1\)"):
        lights.configure(green=-1)
    with pytest.raises(SimError, match=r"cycle=5.*needs more than"):
        lights.configure(cycle=5)


def test_a_plan_field_set_anew_changes_the_states_at_once_even_at_the_same_time(tmp_path):
    """States are kept per time and the plan's numbers per light; assigning a field of the
    plan (as configure and amber_at do) drops both."""
    lights = TrafficLights(map_signals(load(signalled_road(tmp_path))))
    assert lights.state("5", 11.0) == "amber"
    lights.green = 12.0
    assert lights.state("5", 11.0) == "green"
    lights.offset = 2.0
    assert lights.state("5", 11.0) == "amber"
    lights.amber_at("5", 20.0)
    assert lights.state("5", 19.9) == "green" and lights.state("5", 20.0) == "amber"
    assert [lights.state("5", x) for x in np.arange(0, 60, 0.1)] == \
        [("green", "amber", "red")[c] for c in lights.codes("5", np.arange(0, 60, 0.1))]


def test_states_asked_step_by_step_are_the_codes_and_hold_until_the_time_given():
    """A state is computed again only once it may have changed (the time ``states`` gives);
    stepping through two cycles in 0.1-s and odd steps, every state is the codes' one."""
    lights = TrafficLights(map_signals(load(TOWN06))).configure(offset=3.3)
    sids = sorted(lights.controller_of)[:6]
    for dt in (0.1, 0.037):
        t = np.arange(0.0, 70.0, dt)
        want = {sid: [("green", "amber", "red")[c] for c in lights.codes(sid, t)] for sid in sids}
        for i, x in enumerate(t):
            got, until = lights.states(sids, float(x))
            assert got == [want[sid][i] for sid in sids], (dt, x)
            assert until > x or until == x  # (x itself when a cycle's wrap is next)
            later = t[(t > x) & (t < until)]
            assert all(want[sid][j] == got[k] for k, sid in enumerate(sids)
                       for j in np.flatnonzero(np.isin(t, later)))


def test_worlds_on_one_map_share_its_light_tables_and_recorded_stops():
    """What follows from the map's signals alone (the lights, their controllers and stops,
    and each light's recorded stop list) is made once per map and process."""
    tr, lights = [], []
    for seed in (0, 1):
        w = World(seed, name="t", driver="autopilot")
        town = w.map(TOWN06)
        w.ego(town.lanes(min_length=100)[5].at(10.0), speed=10.0)
        lights.append(w.traffic_lights)
        tr.append(w.run(3.0))
    a, b = lights
    assert a is not b and a.stops is b.stops and a.controller_of is b.controller_of
    first, second = tr[0].meta["lights"], tr[1].meta["lights"]
    assert first and [e["id"] for e in first] == [e["id"] for e in second]
    assert first[0] is not second[0] and first[0]["stops"] is second[0]["stops"]
    assert first[0]["stops"][0] == {"lane": first[0]["stops"][0]["lane"],
                                    **{k: first[0]["stops"][0][k]
                                       for k in ("s", "x", "y", "heading", "width")}}


def test_controllers_of_one_junction_are_never_green_together():
    lights = TrafficLights(map_signals(load(TOWN06))).configure(offset=7.0)
    t = np.arange(0.0, 120.0, 0.1)
    for group, cids in lights.map.groups.items():
        green = np.array([lights.codes(lights.map.controllers[c].signals[0], t) == 0 for c in cids])
        assert green.sum(axis=0).max() == 1, group


def test_when_a_driver_stops_for_a_light():
    assert not must_stop("green", 30.0, 15.0, 3.0, 8.0, False)
    assert must_stop("amber", 40.0, 15.0, 3.0, 8.0, False)  # 2.8 m/s^2 does it
    assert not must_stop("amber", 30.0, 15.0, 3.0, 8.0, False)  # 3.75: goes on
    assert must_stop("red", 20.0, 15.0, 3.0, 8.0, False)  # 5.6 <= 8
    assert not must_stop("red", 20.0, 15.0, 3.0, 8.0, True)  # went on at amber
    assert not must_stop("red", 10.0, 15.0, 3.0, 8.0, False)  # 11.25: cannot stop


# -- the monitor, closed forms ---------------------------------------------------------------

def light_run(x, red_from, amber_from, dt=0.1):
    """The ego (5 m) along lane "a" (x east) with ``x(t)``; light 7's stop position at s=50,
    amber from ``amber_from``, red from ``red_from`` [s]."""
    t = np.arange(len(x)) * dt
    codes = np.where(t >= red_from - 1e-9, 2, np.where(t >= amber_from - 1e-9, 1, 0))
    meta = {"lanes": {"a": {"xy": [[0, 0], [200, 0]], "width": 3.5, "kind": "travel"}},
            "ego_route": ["a"],
            "lights": [{"id": "7", "controller": "c", "x": 50, "y": 3, "heading": math.pi,
                        "stops": [{"lane": "a", "s": 50.0, "x": 50, "y": 0, "heading": 0,
                                   "width": 3.5}]}]}
    return Trajectory.from_arrays(
        t, {"ego": {"x": np.asarray(x, float), "y": np.zeros(len(x)), "lane": "a"}},
        signals={"light.7": codes.astype(float)}, meta=meta)


T = np.arange(0.0, 10.0 + 1e-9, 0.1)


def test_a_car_running_the_red_at_a_known_speed():
    # 10 m/s from x=0, 5 m long: CARLA's tail point (x - 0.8 x 2.5 = x - 2) crosses s=50 at
    # t=5.2 s; red from 4 s, when it was at 38 m: 12 m before the line
    res = ran_red_light().evaluate(light_run(10.0 * T, red_from=4.0, amber_from=3.0))
    assert res.rho == pytest.approx(-12.0, abs=1e-9)
    assert res.t == pytest.approx(5.2, abs=1e-9) and res.agent == "ego"
    assert "ran the red light 7" in res.detail
    # judged at the front bumper (x + 2.5): it crosses at 4.75 s, 7.5 m before the line at red
    front = ran_red_light("front").evaluate(light_run(10.0 * T, red_from=4.0, amber_from=3.0))
    assert front.rho == pytest.approx(-7.5, abs=1e-9) and front.t == pytest.approx(4.75, abs=1e-9)


def test_caught_over_the_line_by_the_change_is_charged_by_the_tail_only():
    # red from 5 s: the front crossed at 4.75 s (amber), the tail crosses at 5.2 s (red)
    run = light_run(10.0 * T, red_from=5.0, amber_from=3.0)
    assert ran_red_light().evaluate(run).rho == pytest.approx(-2.0, abs=1e-9)
    assert ran_red_light("front").evaluate(run).rho == pytest.approx(2.5, abs=1e-9)
    with pytest.raises(MonitorError, match=r"point='rear'"):
        ran_red_light("rear")


def test_a_car_crossing_on_amber_has_the_distance_past_the_line_at_red():
    res = ran_red_light().evaluate(light_run(10.0 * T, red_from=6.0, amber_from=4.5))
    assert res.rho == pytest.approx(8.0, abs=1e-9)  # the tail point at 58 m at t=6 s
    assert "on amber" in res.detail
    front = ran_red_light("front").evaluate(light_run(10.0 * T, red_from=6.0, amber_from=4.5))
    assert front.rho == pytest.approx(12.5, abs=1e-9)  # the front at 62.5 m


def test_a_car_stopping_at_the_red_keeps_a_positive_margin():
    # braking at a constant rate from 10 m/s to stand with its front 1 m before the line
    a = 10.0 ** 2 / (2 * 46.5)
    x = np.where(T < 10.0 / a, 10.0 * T - 0.5 * a * T ** 2, 46.5)
    res = ran_red_light("front").evaluate(light_run(x, red_from=4.0, amber_from=3.0))
    assert res.rho == pytest.approx(1.0, abs=1e-9) and res.ok
    assert res.t is None
    # its tail point stands 1 + 4.5 m before the line
    assert ran_red_light().evaluate(light_run(x, 4.0, 3.0)).rho == pytest.approx(5.5, abs=1e-9)


def test_no_light_on_the_route_holds_with_infinite_margin():
    tr = light_run(10.0 * T, 4.0, 3.0)
    bare = Trajectory.from_arrays(tr.t, {"ego": {"x": tr.x[0], "y": tr.y[0], "lane": "a"}},
                                  meta={k: v for k, v in tr.meta.items() if k != "lights"})
    assert ran_red_light().evaluate(bare).rho == math.inf


def test_the_driving_score_charges_a_red_light_0_7():
    ran = driving_score(light_run(10.0 * T, red_from=4.0, amber_from=3.0))
    kept = driving_score(light_run(10.0 * T, red_from=6.0, amber_from=4.5))
    assert [i["kind"] for i in ran.infractions] == ["red_light"]
    assert ran.infractions[0]["factor"] == 0.7 and ran.infractions[0]["t"] == pytest.approx(5.2)
    assert ran.penalty == pytest.approx(0.7) and kept.penalty == 1.0


# -- drivers in the simulator ------------------------------------------------------------------

def _run(path, driver, offset, speed=12.0, s=120.0, seconds=14.0):
    w = World(3, driver=driver, name="signals")
    road = w.map(str(path))
    w.signals(offset=offset)
    w.ego(road.lane("1/0/-1"), s=s, speed=speed)
    return w.run(seconds)


@pytest.mark.parametrize("driver", ["autopilot", "idm", "careful"])
def test_drivers_stop_on_red_and_go_on_green(tmp_path, driver):
    path = signalled_road(tmp_path)
    # offset 13 s: red from t=0 to 17 s, then green; the line is 77.5 m ahead of the front
    red = _run(path, driver, offset=13.0)
    res = ran_red_light("front").evaluate(red)
    assert 0.0 < res.rho < 3.0, res.detail
    k = int(np.searchsorted(red.t, 13.0))
    assert red.speed[0, k] < 0.5  # standing at the line while red
    green = _run(path, driver, offset=0.0, seconds=6.0)  # green 10 s: drives through
    assert ran_red_light().evaluate(green).rho > 0 and green.speed[0].min() > 10.0


def test_a_driver_that_ignores_the_light_runs_it_by_a_known_distance(tmp_path):
    # a policy that holds 12 m/s: its tail point at 120 - 2 + 12 t; red from t=0 (offset
    # 13 s), so it had all of the 82 m to stop and crosses at t = 82 / 12
    tr = _run(signalled_road(tmp_path), lambda obs: (0.0, 0.0), offset=13.0, seconds=8.0)
    res = ran_red_light().evaluate(tr)
    assert res.rho == pytest.approx(-82.0, abs=0.05)
    assert res.t == pytest.approx(82.0 / 12.0, abs=0.01)
    assert driving_score(tr).penalty == pytest.approx(0.7)
    lights = tr.meta["lights"]
    assert [l["id"] for l in lights] == ["5"] and set(tr.signals) >= {"light.5"}


def test_other_cars_stop_at_the_red_too(tmp_path):
    w = World(3, driver="idm", name="signals")
    road = w.map(str(signalled_road(tmp_path)))
    w.signals(offset=13.0)  # red until t = 17 s
    lane = road.lane("1/0/-1")
    w.ego(lane, s=20.0, speed=5.0)
    car = w.car(lane, s=150.0, speed=12.0)
    tr = w.run(10.0)
    i = tr.names.index(car.name)
    front = tr.x[i, -1] + 2.5
    assert 196.0 < front < 200.0 and tr.speed[i, -1] < 0.3


def test_light_stops_are_what_lights_ahead_reads(tmp_path):
    w = World(3, driver="idm", name="signals")
    road = w.map(str(signalled_road(tmp_path)))
    w.signals(offset=8.0)
    lane = road.lane("1/0/-1")
    w.ego(lane, s=20.0, speed=5.0)
    car = w.car(lane, s=150.0, speed=12.0)
    w.run(3.0)
    lights, ahead = w.light_stops(car)
    assert lights is w.traffic_lights and ahead
    assert w.lights_ahead(car) == [(acc - car.route_s, lights.state(sid, w.t), sid)
                                   for _, _, acc, sid in ahead]
    plain = World(0, name="t")
    ego = plain.ego(plain.straight_road(lanes=1, length=200).lane(0), s=10.0)
    assert plain.light_stops(ego) == (None, [])


def test_signals_need_a_road_with_lights(tmp_path):
    w = World(0, name="signals")
    w.straight_road()
    with pytest.raises(SimError, match=r"in signals: world.signals\(\): the straight road has no traffic lights"):
        w.signals()
    w2 = World(0, name="signals")
    w2.map(str(signalled_road(tmp_path)))
    with pytest.raises(SimError, match=r"world.signals\(offset=...\): no signalled junction '9'"):
        w2.signals(offset={"9": 1.0})


def test_the_ego_sees_the_lights_on_its_route(tmp_path):
    seen = []

    def policy(obs):
        seen.append(obs.traffic_lights)
        return 0.0, 0.0

    w = World(0, driver=policy, name="signals")
    road = w.map(str(signalled_road(tmp_path)))
    w.signals(offset=9.0)  # green for 1 s more, then amber
    w.ego(road.lane("1/0/-1"), s=100.0, speed=10.0)
    w.run(2.0, dt=0.5)
    first, last = seen[0], seen[-1]
    assert [(l.route_index, l.s, l.signal) for l in first] == [(0, pytest.approx(200.0), "5")]
    assert first[0].state == "green" and last[0].state == "amber"


def test_a_built_intersection_with_signals_takes_turns_and_is_obeyed():
    from pytest_avscenario.monitors import ran_stop
    from pytest_avscenario.sim import behaviors as b

    w = World(0, driver="autopilot", name="signals")
    inter = w.intersection(control="signals")
    lights = w.signals(offset=10.0)  # north-south amber at t=0, red from 3 s; east-west green from 5 s
    assert lights.state("south", 4.0) == "red" and lights.state("west", 6.0) == "green"
    w.ego(inter.stop_line("south").before(60), speed=10.0, route=inter.route("south"))
    w.car(inter.approach("west"), s=40, speed=10.0, behavior=b.turn("straight"))
    tr = w.run(15.0)
    res = ran_red_light("front").evaluate(tr)
    assert 0.0 < res.rho < 3.0 and tr.speed[0, -1] < 0.3  # it waits at the red
    assert tr.x[1, -1] > 20.0  # the car from the west crossed on its green
    assert ran_stop().evaluate(tr).rho == math.inf  # no stop signs at a signalled junction
    assert {l["id"] for l in tr.meta["lights"]} == {"north", "east", "south", "west"}
    with pytest.raises(SimError, match=r"control='yield'"):
        World(0, name="signals").intersection(control="yield")


def test_a_served_stack_sees_the_lights_through_osi_and_drives_as_in_process(tmp_path):
    """The lights ride the OSI SensorView (``traffic_light``, its colour and assigned lanes)
    and their stop positions the Reset: the autopilot served out of process stops at the red
    exactly as in process."""
    pytest.importorskip("zmq")
    pytest.importorskip("osi3")
    import os
    import subprocess
    import sys

    from osi3 import osi_sensorview_pb2

    from pytest_avscenario.stack import OSIStack, client, frame

    root = Path(__file__).resolve().parents[1]

    def drive(driver):
        w = World(4, driver=driver, name="signals::osi")
        inter = w.intersection(control="signals")
        w.signals(offset=10.0)
        w.ego(inter.stop_line("south").before(60), speed=10.0, route=inter.route("south"))
        return w, w.run(8.0)

    address = f"ipc://{tmp_path}/autopilot.sock"
    proc = subprocess.Popen([sys.executable, "-m", "pytest_avscenario.stack.autopilot", address],
                            env={**os.environ, "PYTHONPATH": str(root)},
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        w, here = drive("autopilot")
        _, remote = drive(OSIStack(address, timeout_s=30))
    finally:
        proc.kill()
        proc.wait(timeout=10)
        client.stop_all()
    assert np.nanmax(np.abs(here.x - remote.x)) <= 1e-9
    assert np.nanmax(np.abs(here.y - remote.y)) <= 1e-9
    assert here.speed[0, -1] < 0.3 and 0 < ran_red_light("front").evaluate(remote).rho < 3.0
    sv = osi_sensorview_pb2.SensorView.FromString(frame.sensor_view(w, 0, b"", {a: i + 1 for i, a in enumerate(w.agents)}))
    lights = {tl.source_reference[0].identifier[0]: tl for tl in sv.global_ground_truth.traffic_light}
    assert set(lights) == {"north", "east", "south", "west"}
    assert lights["south"].classification.color == lights["south"].classification.COLOR_RED
    assert len(lights["south"].classification.assigned_lane_id) == 1


SIGNAL_CAMPAIGN = """
from pytest_avscenario import Uniform, scenario
from pytest_avscenario.monitors import ran_red_light

def ignore_lights(obs):
    return 0.0, 0.0  # holds its speed: a driver that never looks at the lights

@scenario(phase=Uniform(0.0, 1.0), samples=6, sampler="halton", monitors=[ran_red_light()])
def test_light(case, world):
    inter = world.intersection(control="signals")
    world.signals(phase=case.phase)
    world.ego(inter.stop_line("south").before(40), speed=10.0, route=inter.route("south"),
              driver=ignore_lights)
    world.run(seconds=8)
"""


def test_a_campaign_over_the_phase_judges_ran_red_light_and_charges_the_score(pytester):
    import json

    pytester.makepyfile(test_signal=SIGNAL_CAMPAIGN)
    result = pytester.runpytest("--avs-db=none", "--avs-seed=1", "--avs-shrink-budget=0",
                                "--avs-reference-max=0", "--avs-case-pictures=0",
                                "--avs-export=none", "--avs-gifs=0", "--junitxml=out.xml")
    # crossing 4.2 s in (its tail 42 m from the line at 10 m/s): a red then in the 30-s
    # cycle (green 10, amber 3, red 17) is run in the phases that put it there
    outcomes = result.parseoutcomes()
    assert outcomes.get("failed", 0) >= 1 and outcomes.get("passed", 0) >= 1
    result.stdout.fnmatch_lines(["*ran_red_light: rho -*ego ran the red light south on south.in[[]0[]]*"])
    summary = json.loads((pytester.path / "avs-report" / "summary.json").read_text())
    (test,) = summary["tests"]
    assert test["violations"] == {"ran_red_light": outcomes["failed"]}
    xml = (pytester.path / "out.xml").read_text()
    assert xml.count('name="avs.infractions" value="red_light"') == outcomes["failed"]


def test_a_maps_stop_sign_is_a_stop_line_drivers_stop_at_and_ran_stop_judges(tmp_path):
    from pytest_avscenario.monitors import ran_stop

    path = signalled_road(tmp_path)  # signal 7, type 206, at s=400 for the eastbound lane

    def drive(driver):
        w = World(0, driver=driver, name="signals")
        road = w.map(str(path))
        w.ego(road.lane("1/0/-1"), s=300.0, speed=10.0)
        assert [(sl.lane.id, sl.s) for sl in road.stop_lines] == [("1/0/-1", pytest.approx(400.0))]
        return w.run(16.0)

    stopped = ran_stop().evaluate(drive("autopilot"))
    assert stopped.ok and "stopped at the stop line of 1/0/-1" in stopped.detail
    ran = ran_stop().evaluate(drive(lambda obs: (0.0, 0.0)))
    assert ran.rho == pytest.approx(0.5 - 10.0, abs=1e-6)

"""Scenarios over a map: MapLane is a categorical parameter over a map's lanes, read at
collection; cases place agents by lane id and drive them on the map; a bad map is a
collection error naming the test and the parameter; a Town06 campaign has stable case ids
under xdist."""

import json
import shutil
from pathlib import Path

import numpy as np
import pytest

from pytest_avscenario.space import Choice, FeatureSpace
from pytest_avscenario.sim import opendrive as od

DATA = Path(__file__).parent / "data" / "maps"
TOWN06 = Path(__file__).parents[1] / "example_tests" / "maps" / "Town06.xodr"

FOLLOW = """
from pytest_avscenario import MapLane, Uniform, scenario
from pytest_avscenario.monitors import collision, distance

@scenario(lane=MapLane("maps/{map}", kind="driving", min_length={min_length}),
          gap=Uniform(8.0, 30.0, unit="m"), samples={samples}, sampler="halton",
          monitors=[distance({threshold}), collision()])
def test_follow(case, world):
    town = world.map("maps/{map}")
    start = town.lane(case.lane).at(5.0)
    world.ego(start, speed=10.0, driver="idm")
    world.car(town.ahead(start, case.gap), speed=4.0)
    world.run(seconds={seconds})
"""


def _rows(pytester):
    rows = [json.loads(l) for l in
            (pytester.path / "avs-report" / "errors.jsonl").read_text().splitlines()]
    return {r["item"]: (r["params"], r["seed"], r["rho"], r["verdict"]) for r in rows}


def _with_map(pytester, source: Path) -> None:
    (pytester.path / "maps").mkdir(exist_ok=True)
    shutil.copy(source, pytester.path / "maps" / source.name)


def test_maplane_is_a_categorical_choice_over_the_map_lanes():
    lanes = od.MapLane(DATA / "fabriksgatan.xodr", kind="driving", min_length=10)
    space = FeatureSpace({"lane": lanes})
    assert space.dims[0].kind == "categorical"
    data = od.load(DATA / "fabriksgatan.xodr")
    expected = [l.id for l in data.of_kind("driving", 10) if not l.junction]
    assert list(lanes.options) == expected and len(expected) >= 4
    # stored as a plain Choice: a replay needs no map file
    again = FeatureSpace.from_description(json.loads(json.dumps(space.describe())))
    assert isinstance(again.parameters["lane"], Choice)
    assert again.parameters["lane"].options == lanes.options
    space.check_description()
    assert {space.from_unit([u])["lane"] for u in (0.01, 0.5, 0.99)} <= set(expected)
    with_junctions = od.MapLane(DATA / "fabriksgatan.xodr", kind="driving", junctions=True)
    assert set(with_junctions.options) > set(expected)


def test_a_campaign_over_map_lanes_runs_and_places_the_ego_on_the_drawn_lane(pytester):
    _with_map(pytester, DATA / "fabriksgatan.xodr")
    pytester.makepyfile(test_m=FOLLOW.format(map="fabriksgatan.xodr", min_length=40,
                                             samples=6, threshold=8.0, seconds=3))
    res = pytester.runpytest("--avs-db=none", "--avs-seed=3", "--avs-shrink-budget=0",
                             "-p", "no:randomly", "-p", "no:cacheprovider")
    rows = _rows(pytester)
    assert len(rows) == 6, res.stdout.str()[-3000:]
    lanes = {p["lane"] for p, *_ in rows.values()}
    assert len(lanes) >= 3
    # the drawn lane is where the ego drove: informative verdicts both ways
    verdicts = {v for *_, v in rows.values()}
    assert verdicts == {"pass", "fail"}, rows


def _collection_error(pytester, decl: str, match: str, traceback_free: bool = False) -> None:
    """A test whose ``lane`` parameter is ``decl`` fails collection with ``match`` in the
    output (lines joined), naming the test or its file."""
    import re

    pytester.makepyfile(test_bad=f"""
from pytest_avscenario import MapLane, scenario

@scenario(lane={decl}, samples=2)
def test_on_map(case, world):
    pass
""")
    res = pytester.runpytest("--avs-db=none", "-p", "no:cacheprovider", "--collect-only")
    out = res.stdout.str()
    assert res.ret != 0
    assert "test_on_map" in out or "test_bad.py" in out
    if traceback_free:
        assert "Traceback" not in out and "lxml" not in out
    assert re.search(match, out.replace("\n", " ")), out[-3000:]


@pytest.mark.parametrize("decl, match", [
    ('MapLane("maps/nowhere.xodr")', r"parameter 'lane'.*nowhere\.xodr.*not found"),
    ('MapLane("maps/fabriksgatan.xodr", kind="tram")', r"parameter 'lane'.*no lane of the map matches"),
])
def test_a_bad_map_is_a_collection_error_naming_test_and_parameter(pytester, decl, match):
    _with_map(pytester, DATA / "fabriksgatan.xodr")
    _collection_error(pytester, decl, match)


_ROAD = ("<road id='{rid}' length='50' junction='-1'>{link}<planView><geometry s='0' x='{x}' "
         "y='0' hdg='0' length='50'><{geom}/></geometry></planView><lanes><laneSection s='0'>"
         "<right><lane id='-1' type='{kind}'><width sOffset='0' a='3.5' b='0' c='0' d='0'/>"
         "</lane></right></laneSection></lanes></road>")


def _odr(*roads: str) -> str:
    return "<?xml version='1.0'?><OpenDRIVE><header/>" + "".join(roads) + "</OpenDRIVE>"


_BAD_MAPS = {
    "not-xml": ("<OpenDRIVE><road", "MapLane(\"maps/bad.xodr\")",
                r"parameter 'lane'.*bad\.xodr is not XML"),
    "unknown-geometry": (_odr(_ROAD.format(rid=1, link="", x=0, geom="clothoid", kind="driving")),
                         "MapLane(\"maps/bad.xodr\")",
                         r"parameter 'lane'.*bad\.xodr.*road 1 geometry at s=0 is <clothoid>"),
    "no-driving-lane": (_odr(_ROAD.format(rid=1, link="", x=0, geom="line", kind="sidewalk")),
                        "MapLane(\"maps/bad.xodr\")",
                        r"parameter 'lane'.*bad\.xodr: no driving lane in it"),
    # the map's edge where the scenario needs 100 m of road ahead
    "dead-end": (_odr(_ROAD.format(rid=1, link="", x=0, geom="line", kind="driving")),
                 "MapLane(\"maps/bad.xodr\", ahead=100)",
                 r"parameter 'lane'.*bad\.xodr.*route runs 100 m.*at lane 1/0/-1, which has no "
                 r"successor \(road 1's <link> has no <successor>"),
    # the road names a successor the file does not have
    "dangling-link": (_odr(_ROAD.format(
        rid=1, link="<link><successor elementType='road' elementId='9' contactPoint='start'/>"
                    "</link>", x=0, geom="line", kind="driving")),
        "MapLane(\"maps/bad.xodr\", ahead=80)",
        r"parameter 'lane'.*bad\.xodr.*lane 1/0/-1, which has no successor \(road 1's "
        r"<link><successor elementType='road' elementId='9'> names a road the file lacks"),
    # the lane's own link names a lane the next road lacks
    "missing-lane-link": (_odr(
        _ROAD.format(rid=1, link="<link><successor elementType='road' elementId='2' "
                                 "contactPoint='start'/></link>", x=0, geom="line",
                     kind="driving").replace(
            "d='0'/></lane>", "d='0'/><link><successor id='-4'/></link></lane>"),
        _ROAD.format(rid=2, link="", x=50, geom="line", kind="driving")),
        "MapLane(\"maps/bad.xodr\", ahead=80)",
        r"lane 1/0/-1, which has no successor \(road 1 lane -1's <link><successor id='-4'> "
        r"into road 2 names a lane the file lacks there"),
}


@pytest.mark.parametrize("name", list(_BAD_MAPS))
def test_a_bad_map_file_is_a_collection_error_naming_the_file_and_element(pytester, name):
    """Every kind of bad map is reported at collection by the MapLane parameter that reads
    it: the test, the parameter, the file and the element, never the parser's traceback."""
    text, decl, match = _BAD_MAPS[name]
    (pytester.path / "maps").mkdir()
    (pytester.path / "maps" / "bad.xodr").write_text(text)
    _collection_error(pytester, decl, match, traceback_free=True)


def test_lanes_whose_route_ends_too_soon_are_left_out_and_named_at_run_time():
    """MapLane(ahead=) keeps only lanes from which the default route runs that far (Town06's
    lane 48/0/-3 ends after 184 m: its file link to road 49 is missing); a route that runs
    past such an end at run time names the lane and the missing element too."""
    every = od.MapLane(TOWN06, kind="driving", min_length=100)
    kept = od.MapLane(TOWN06, kind="driving", min_length=100, ahead=250)
    assert every.error is None and kept.error is None
    assert set(every.options) - set(kept.options) == {"48/0/-3"}
    data = od.load(TOWN06)
    run, last = od.route_end(data, "48/0/-3", 250)
    assert last == "48/0/-3" and 180 < run < 190
    assert od.route_end(data, kept.options[0], 250) is None
    assert "road 48 lane -3 has no <link><successor> into road 49" in od.why_no_successor(data, last)
    bad = od.MapLane(TOWN06, ahead=-1)
    assert bad.error is not None and "ahead" in bad.error
    from pytest_avscenario.sim import World
    from pytest_avscenario.sim.errors import SimError

    town = World(0, name="test_x").map(TOWN06)
    with pytest.raises(SimError, match=r"48/0/-3.*no successor \(road 48 lane -3 has no "
                                       r"<link><successor> into road 49\).*ahead="):
        town.ahead(town.lane("48/0/-3").at(10.0), 200.0)


@pytest.mark.slow
def test_town06_lane_campaign_has_stable_case_ids_under_xdist(pytester):
    """Every Town06 driving lane of 100 m or more is a possible ego lane; serial and -n 2
    runs give every case id the same lane, seed and robustness."""
    pytest.importorskip("xdist")
    _with_map(pytester, TOWN06)
    pytester.makepyfile(test_town=FOLLOW.format(map="Town06.xodr", min_length=100,
                                                samples=8, threshold=10.0, seconds=2))
    base = ["--avs-db=none", "--avs-seed=11", "--avs-shrink-budget=0", "-p", "no:randomly",
            "-p", "no:cacheprovider"]
    pytester.runpytest_subprocess(*base)
    serial = _rows(pytester)
    assert len(serial) == 8
    shutil.rmtree(pytester.path / "avs-report")
    res = pytester.runpytest_subprocess(*base, "-n", "2")
    parallel = _rows(pytester)
    assert parallel == serial, res.stdout.str()[-2000:]
    all_lanes = od.MapLane(TOWN06, kind="driving", min_length=100).options
    assert {p["lane"] for p, *_ in serial.values()} <= set(all_lanes)
    assert len({p["lane"] for p, *_ in serial.values()}) >= 6


def test_failures_over_map_lanes_shrink_to_a_lane_of_the_map(pytester):
    """Hypothesis shrinking works over a map-lane parameter: a categorical value either stays
    as found or goes back to the nominal lane (the first), the continuous one moves toward its
    nominal value; the minimized case names a failing lane of the map in its @example line."""
    _with_map(pytester, DATA / "fabriksgatan.xodr")
    pytester.makepyfile(test_s="""
from pytest_avscenario import MapLane, Uniform, scenario
from pytest_avscenario.monitors import distance
from pytest_avscenario.trajectory import Trajectory

LANES = MapLane("maps/fabriksgatan.xodr", kind="driving")

@scenario(lane=LANES, x=Uniform(0, 1), samples=12, sampler="halton", monitors=[distance(5.0)])
def test_lanes(case):
    # fails on every lane but the first two, more so for larger x
    gap = 10.0 if case.lane in LANES.options[:2] else 4.0 - case.x
    return Trajectory.from_arrays([0.0, 0.1], {
        "ego": {"x": [0.0, 0.0], "y": [0.0, 0.0]},
        "other": {"x": [gap, gap], "y": [0.0, 0.0]}})
""")
    res = pytester.runpytest("--avs-db=none", "--avs-seed=2", "--avs-shrink-budget=30",
                             "--avs-shrink-max=1", "-p", "no:randomly", "-p", "no:cacheprovider")
    out = res.stdout.str()
    import re

    from pytest_avscenario.sim.opendrive import MapLane

    options = MapLane(DATA / "fabriksgatan.xodr", kind="driving").options
    found = re.findall(r"@example\(lane='([^']+)', x=([0-9.]+)\)", out)
    assert found, out[-3000:]
    assert all(lane in options[2:] for lane, _ in found)
    assert all(float(x) == 0.5 for _, x in found)  # x back at its nominal value


# -- the autopilot's route path on a map's long routes, built piece by piece -------------------

def _town06_long_route_case(seconds: float, driver=None, seed: int = 3):
    """A case on the Town06 lane whose default route is the longest of those of >= 100 m; the
    ego at 20 m/s wanting 30 m/s (the curve-speed cap at work), a car ahead."""
    from pytest_avscenario.sim import World
    from pytest_avscenario.sim.drivers.autopilot import Autopilot

    world = World(seed, name="long-route", driver=driver or Autopilot())
    town = world.map(TOWN06)
    lanes = [town.lane(i) for i in od.MapLane(TOWN06, kind="driving", min_length=100).options]
    lane = max(lanes, key=lambda l: sum(x.length for x in town.default_route(l).lanes))
    start = lane.at(10.0)
    world.ego(start, speed=20.0, target_speed=30.0)
    world.car(town.ahead(start, 40.0), speed=15.0)
    traj = world.run(seconds=seconds)
    return traj, town.default_route(lane)


def test_a_long_route_is_built_only_as_far_as_the_case_drives():
    from pytest_avscenario.sim.drivers.autopilot import Autopilot

    pilot = Autopilot()
    traj, route = _town06_long_route_case(5.0, driver=pilot)
    path = pilot._path
    driven = float(np.hypot(traj.x[0, -1] - traj.x[0, 0], traj.y[0, -1] - traj.y[0, 0]))
    assert len(route.lanes) >= 30 and path.route_length > 2000.0  # kilometres of route
    assert driven < 150.0
    # what was built: the look-ahead past the distance driven, not the whole route
    built_m = len(path.S) * path.ds
    assert built_m < 0.2 * path.route_length
    assert len(path.x) == len(path.tx) == len(path.curvature) == len(path.S)


def test_a_route_lanes_offset_is_planned_when_asked_and_none_off_the_route():
    from pytest_avscenario.sim import World
    from pytest_avscenario.sim.drivers.route_path import RoutePath

    town = World(0, name="t").map(TOWN06)
    route = town.default_route(town.lanes(min_length=100)[3])
    geoms = tuple(l.geometry for l in route.lanes)
    path, whole = RoutePath(geoms), RoutePath(geoms)
    assert len(geoms) > 10 and len(path._offsets) < len(geoms)  # planned as far as built
    k = len(geoms) - 2
    assert path.offset(k) == whole.offsets[k] and len(path._offsets) == k + 1
    assert [path.offset(i) for i in range(len(geoms))] == list(whole.offsets)
    assert path.offset(-1) is None and path.offset(len(geoms)) is None


@pytest.mark.parametrize("options", [{}, {"lateral_accel": 1e-4}])
def test_a_case_built_piece_by_piece_drives_as_with_the_whole_route_built_up_front(
        monkeypatch, options):
    # (a lateral acceleration of 1e-4 m/s² caps the speed at 10 m/s even on a straight
    # window, whose curvature bound is under 1e-3 [1/m]: there the autopilot asks the whole
    # path's maximum, which builds it all)
    from pytest_avscenario.sim.drivers import route_path
    from pytest_avscenario.sim.drivers.autopilot import Autopilot

    pieces = []
    derive = route_path.RoutePath._derive

    def counted(self):
        pieces.append(self._ready)
        derive(self)

    monkeypatch.setattr(route_path.RoutePath, "_derive", counted)
    monkeypatch.setattr(route_path, "_PIECE_M", 1e12)  # the whole route at the first look-up
    whole, _ = _town06_long_route_case(25.0, driver=Autopilot(**options))
    assert len(pieces) == 1
    pieces.clear()
    monkeypatch.setattr(route_path, "_PIECE_M", 3.0)  # a piece every few metres
    pilot = Autopilot(**options)
    parts, _ = _town06_long_route_case(25.0, driver=pilot)
    assert len(pieces) >= (4 if not options else 1)  # (pieces end at lane ends: ~100 m)
    assert pilot._path.complete == bool(options)  # the whole path's maximum was asked for
    assert whole.meta == parts.meta
    for f in ("x", "y", "vx", "vy", "speed", "heading", "lane", "lane_offset", "crashed"):
        assert np.array_equal(getattr(whole, f), getattr(parts, f)), f
    assert whole.signals.keys() == parts.signals.keys()
    for k in whole.signals:
        assert np.array_equal(whole.signals[k], parts.signals[k]), k


def test_a_route_path_built_piece_by_piece_has_the_numbers_of_the_whole_route(monkeypatch):
    from pytest_avscenario.sim import World
    from pytest_avscenario.sim.drivers import route_path

    town = World(0).map(TOWN06)
    names = od.MapLane(TOWN06, kind="driving", min_length=100).options
    for name in list(names)[::8]:
        route = tuple(l.geometry for l in town.default_route(town.lane(name)).lanes)
        monkeypatch.setattr(route_path, "_PIECE_M", 2.0)
        parts = route_path.RoutePath(route)
        for s in np.arange(0.0, 600.0, 3.0):  # look-ups along the route, as a drive makes them
            w = parts.window(s, s + 40.0)
            parts.max_curvature_bound(w)
            parts.curve_speed_min(w, s, 2.5, 2.45)
        monkeypatch.setattr(route_path, "_PIECE_M", 1e12)
        whole = route_path.RoutePath(route)
        assert whole.complete and parts.n == whole.n and parts.complete
        for f in ("S", "x", "y", "tx", "ty", "curvature"):
            assert np.array_equal(getattr(parts, f), getattr(whole, f)), (name, f)
        assert tuple(parts.offsets) == tuple(whole.offsets)
        assert parts._kmax == whole._kmax
        # and the heading's curvature is numpy's own unwrap, gradient and moving average
        dx, dy = np.gradient(whole.x), np.gradient(whole.y)
        norm = np.hypot(dx, dy)
        norm[norm == 0.0] = 1.0
        heading = np.unwrap(np.arctan2(dy / norm, dx / norm))
        curv = np.convolve(np.gradient(heading) / whole.ds, np.ones(5) / 5, mode="same")
        assert np.array_equal(curv, whole.curvature), name

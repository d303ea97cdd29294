"""Counterexamples exported as OpenSCENARIO + OpenDRIVE and an OSI trace: valid against the
XSDs scenariogeneration ships, parsed back to the same scenario, replayed in the plugin's own
simulator to the same collision, and the trace read back."""

import pathlib
import re
import xml.etree.ElementTree as ET

import numpy as np
import pytest

pytest.importorskip("scenariogeneration")
xmlschema = pytest.importorskip("xmlschema")

from pytest_avscenario.export import export_case, schema_path  # noqa: E402
from pytest_avscenario.export.openscenario import rear_axle  # noqa: E402
from pytest_avscenario.export.replay import replay, replay_world  # noqa: E402
from pytest_avscenario.sim import behaviors as b  # noqa: E402
from pytest_avscenario.sim.highway import arc, straight  # noqa: E402
from pytest_avscenario.sim.world import World  # noqa: E402


@pytest.fixture(scope="module")
def schemas():
    return {"xosc": xmlschema.XMLSchema(str(schema_path("OpenSCENARIO_1_3_1.xsd"))),
            "xosc_1_0": xmlschema.XMLSchema(str(schema_path("OpenSCENARIO_1_0.xsd"))),
            "xodr": xmlschema.XMLSchema(str(schema_path("opendrive_17_core.xsd")))}


def blind(observation):
    """An ego that never brakes: it hits whatever stops in front of it."""
    return 0.0, 0.0


def braking_lead(seconds=6.0):
    w = World(7, driver=blind)
    road = w.straight_road(lanes=2, length=300)
    w.ego(road.lane(0), s=20, speed=15)
    w.car(road.lane(0), s=50, speed=10, behavior=b.brake_at(1.0, decel=6))
    w.car(road.lane(1), s=30, speed=8)
    w.run(seconds=seconds)
    return w


def assert_valid(schemas, res):
    assert not res.errors, res.errors
    for kind in ("xosc", "xosc_1_0", "xodr")[:3 if "xodr" in res.files else 2]:
        errors = [str(e)[:300] for e in schemas[kind].iter_errors(res.files[kind])]
        assert errors == [], f"{kind}: {errors}"


def test_braking_lead_exports_valid_files_that_parse_back_to_the_case(tmp_path, schemas):
    from scenariogeneration import xosc

    w = braking_lead()
    res = export_case(w, {"gap": 30.0, "lanes": 2}, tmp_path, "following", units={"gap": "m"})
    assert_valid(schemas, res)
    assert set(res.files) == {"xosc", "xosc_1_0", "xodr", "osi"}
    old = ET.parse(res.files["xosc_1_0"]).getroot()  # CARLA's ScenarioRunner: 1.0, a hero
    assert old.find("FileHeader").get("revMinor") == "0"
    assert old.find("Entities/ScenarioObject[@name='ego']//Property").attrib == {
        "name": "type", "value": "ego_vehicle"}
    assert set(res.trajectories) == {"ego"}  # the lead brakes and car2 cruises: actions
    assert "SpeedAction" in res.actions["car1"]
    sce = xosc.ParseOpenScenario(res.files["xosc"])  # scenariogeneration reads it back
    assert {p.name: p.value for p in sce.parameters.parameters} == {"gap": "30.0", "lanes": "2"}
    assert [o.name for o in sce.entities.scenario_objects] == ["ego", "car1", "car2"]
    root = ET.parse(res.files["xosc"]).getroot()
    text = ET.tostring(root, encoding="unicode")
    assert "gap [m]" in open(res.files["xosc"]).read()  # the unit travels as a comment
    assert "replace that action with your own controller" in open(res.files["xosc"]).read()
    # Init: the rear axle of each agent as recorded at t = 0, by road and lane (lane i of the
    # world is OpenDRIVE lane -(i + 1) of road 1; s along it from x = 0), its speed
    tr = w.trajectory
    for i, name in enumerate(tr.names):
        priv = root.find(f"Storyboard/Init/Actions/Private[@entityRef='{name}']")
        pos = priv.find(".//LanePosition")
        x, y = rear_axle(tr.x[i, 0], tr.y[i, 0], tr.heading[i, 0], tr.length[i])
        lane = int(str(tr.lane[i, 0]).strip("lane[]"))
        assert (pos.get("roadId"), int(pos.get("laneId"))) == ("1", -(lane + 1))
        assert (float(pos.get("s")), float(pos.get("offset"))) == pytest.approx((x, y + 3.5 * lane))
        assert float(pos.find("Orientation").get("h")) == tr.heading[i, 0]
        assert float(priv.find(".//AbsoluteTargetSpeed").get("value")) == tr.speed[i, 0]
    brake = root.find(".//Event[@name='car1_brake']")
    assert float(brake.find(".//SpeedActionDynamics").get("value")) == 6.0
    assert float(brake.find(".//SimulationTimeCondition").get("value")) == 1.0
    assert float(root.find("Storyboard/StopTrigger//SimulationTimeCondition").get("value")) == 6.0
    assert len(root.findall(".//Trajectory[@name='ego_recorded']//Vertex")) == tr.n_steps
    assert "LogicFile" in text and root.find("RoadNetwork/LogicFile").get("filepath") == "following.xodr"


def test_replayed_export_collides_within_one_step_of_the_original(tmp_path):
    w = braking_lead()
    first = np.flatnonzero(w.trajectory.crashed[0])
    assert first.size, "the braking-lead case must collide for this test to mean anything"
    res = export_case(w, {}, tmp_path, "following", osi=False)
    again = replay(res.files["xosc"])  # from the files alone
    second = np.flatnonzero(again.crashed[0])
    assert second.size and abs(int(second[0]) - int(first[0])) <= 1
    k = int(first[0])
    assert np.abs(again.x[:, :k] - w.trajectory.x[:, :k]).max() < 1e-6


@pytest.mark.parametrize("build", ["two_way", "highway", "intersection", "cut_in", "network"])
def test_every_road_kind_and_manoeuvre_exports_valid(tmp_path, schemas, build):
    w = World(3, driver=blind)
    if build == "two_way":
        road = w.two_way_road(lanes=1, length=200, median=1.0)
        w.ego(road.lane(0), s=10, speed=8)
        w.car(road.lane(0, "backward"), s=60, speed=8, behavior=b.encroach(1.5, at=1.0))
        w.parked_car(road.parking_lane, s=40)
    elif build == "highway":
        road = w.highway(lanes=3, segments=[straight(100), arc(500, 20), straight(100),
                                            straight(100, lanes=2)])
        w.ego(road.lane(1), s=10, speed=20)
        w.car(road.lane(0), s=40, speed=20, behavior=b.change_lane("right", at=1.0))
        w.car(road.lane(2), s=60, speed=15, behavior=b.speed_profile([(0, 15), (2, 10)]))
    elif build == "intersection":
        inter = w.intersection(lanes=1)
        w.ego(inter.stop_line("south").before(20), speed=8, route=inter.route("south", "left"))
        w.car(inter.stop_line("north").before(15), speed=8, behavior=b.turn_across("left"))
    elif build == "network":  # two intersections joined: no road file is written
        net = w.road_network()
        a = net.intersection("A", at=(0.0, 0.0), approach_length=60.0)
        c = net.intersection("B", at=(0.0, 160.0), approach_length=60.0)
        net.connect(a, "north", c, "south")
        w.ego(a.approach("south"), s=5.0, speed=8.0, route=net.route(a.route("south"),
                                                                      c.route("south")))
    else:
        road = w.straight_road(lanes=2, length=300)
        w.ego(road.lane(0), s=10, speed=20)
        w.car(road.lane(1), s=40, speed=15, behavior=b.cut_in(time_gap=1.5))
        w.car(road.lane(0), s=80, speed=15, behavior=b.brake_at(when=b.gap_below(20)))
    w.run(seconds=3)
    res = export_case(w, {"x": 1.5, "side": "left", "on": False}, tmp_path, build, osi=False)
    assert_valid(schemas, res)
    text = open(res.files["xosc"]).read()
    if build == "two_way":  # no equivalent for encroaching: its recorded trajectory, said so
        assert "Encroach has no OpenSCENARIO equivalent" in res.trajectories["car1"]
        assert "car1: behaviour Encroach has no OpenSCENARIO equivalent" in text
    elif build == "highway":
        assert "LaneChangeAction" in text and "SpeedProfileAction" in text
        # OpenSCENARIO 1.0 has no SpeedProfileAction: that car follows its trajectory there
        assert "in the 1.0 file only" in res.trajectories["car2"]
        assert "SpeedProfileAction" not in open(res.files["xosc_1_0"]).read()
        road = ET.parse(res.files["xodr"]).getroot()
        assert len(road.findall(".//laneSection")) == 4  # one per segment: the lane drop
        # two straights in a row are one line (ASAM's checker calls two redundant)
        kinds = [g[0].tag for g in road.findall(".//planView/geometry")]
        assert kinds == ["line", "arc", "line"]
    elif build == "intersection":  # the junction with its 12 connecting roads, one per turn
        road = ET.parse(res.files["xodr"]).getroot()
        conns = road.findall("junction/connection")
        assert len(conns) == 12 and len(road.findall("road[@junction='100']")) == 12
        assert "notes" not in res.to_json()
        # the turning car has no equivalent: its trajectory, but placed by road and lane, with
        # its route through the junction: south arm (3) -> its left-turn connector -> west arm (4)
        assert set(res.trajectories) == {"ego", "car1"}
        sce = ET.parse(res.files["xosc"]).getroot()
        ego = sce.find("Storyboard/Init/Actions/Private[@entityRef='ego']")
        assert ego.find(".//TeleportAction//LanePosition").get("roadId") == "3"
        way = [(p.get("roadId"), p.get("laneId")) for p in ego.findall(".//Waypoint//LanePosition")]
        conn = next(c.get("connectingRoad") for c in conns
                    if road.find(f"road[@id='{c.get('connectingRoad')}']").get("name")
                    == "south to west (left)")
        assert way == [("3", "1"), (conn, "-1"), ("4", "-1")]
        # the plugin's own OpenDRIVE reader drives the file: the south approach continues into
        # its three connecting roads, each starting where the approach ends
        town = World(1).map(res.files["xodr"])
        south = town.lane("3/0/1")
        nxt = town.successors(south)
        assert len(nxt) == 3 and f"{conn}/0/-1" in [l.id for l in nxt]
        for lane in nxt:
            assert np.abs(lane.data.xy[0] - south.data.xy[-1]).max() < 1e-6
        assert [l.id for l in town.route(south, town.lane("4/0/-1")).lanes] == [
            "3/0/1", f"{conn}/0/-1", "4/0/-1"]
    elif build == "network":  # an OpenDRIVE file needs a road: none rather than an invalid one
        assert "xodr" not in res.files and not list(tmp_path.glob("*.xodr"))
        assert ET.parse(res.files["xosc"]).getroot().find("RoadNetwork/LogicFile") is None
        assert "no road file" in res.to_json()["notes"][0] and "no road file" in text
        assert set(res.trajectories) == {"ego"}
    else:
        assert "TimeHeadwayCondition" in text and "RelativeDistanceCondition" in text


@pytest.mark.parametrize("build", ["straight", "two_way", "highway", "intersection"])
def test_lane_positions_name_the_same_points_as_the_world(build):
    # every written lane: a point 0.3 m left of its centre (in its direction of travel) at any
    # s is (road, lane, s, +-0.3 along the road's t axis) and back
    from pytest_avscenario.export.opendrive import lane_position, road_xodr, world_xy

    w = World(3)
    road = {"straight": lambda: w.straight_road(lanes=3, length=200),
            "two_way": lambda: w.two_way_road(lanes=2, length=200, median=1.0, parking=True),
            "highway": lambda: w.highway(lanes=3, segments=[straight(100), arc(300, -30),
                                                            straight(50), straight(80, lanes=2)]),
            "intersection": lambda: w.intersection(lanes=2, median=2.0)}[build]()
    _, rmap = road_xodr(road)
    written = [lane for lane in road.all_lanes if lane.id in rmap.lanes]
    assert len(written) == len(rmap.lanes) > 2
    for lane in written:
        for s in np.linspace(0.0, lane.length, 5):
            p = np.asarray(lane.geometry.position(s, 0.3), dtype=float)
            rid, lid, s_road, offset = lane_position(rmap, lane.id, *p)
            # 0.3 m left of travel: +0.3 on the t axis in a right lane, -0.3 in a left lane
            side = 1.0 if lid < 0 else -1.0
            assert (rid, lid) == rmap.lanes[lane.id]
            assert offset == pytest.approx(0.3 * side, abs=1e-9)
            assert np.hypot(*(np.array(world_xy(rmap, rid, lid, s_road, offset)) - p)) < 1e-9


def test_osi_trace_is_named_by_convention_and_reads_back(tmp_path):
    from pytest_avscenario.export.osi import read_trace

    w = braking_lead(seconds=2.0)
    res = export_case(w, {}, tmp_path, "following")
    name = res.files["osi"].rsplit("/", 1)[1]
    m = re.fullmatch(r"\d{8}T\d{6}Z_sv_(\d+)_(\d+)_(\d+)_following\.osi", name)
    assert m and int(m.group(3)) == w.trajectory.n_steps
    frames = list(read_trace(open(res.files["osi"], "rb").read()))
    tr = w.trajectory
    assert len(frames) == tr.n_steps
    for k in (0, tr.n_steps - 1):
        gt = frames[k].global_ground_truth
        assert gt.host_vehicle_id.value == 1
        assert len(gt.lane) == (2 if k == 0 else 0)  # static: in the first message only
        assert gt.timestamp.seconds * 10**9 + gt.timestamp.nanos == round(tr.t[k] * 1e9)
        for i, obj in enumerate(gt.moving_object):
            assert obj.id.value == i + 1
            assert (obj.base.position.x, obj.base.position.y) == (tr.x[i, k], tr.y[i, k])


def test_osi_trace_of_a_map_case_holds_only_the_lanes_near_the_ego_path():
    # Town06 has 467 drivable lanes over kilometres; the trace keeps those within 50 m of the
    # ego's recorded path (and every lane an agent was on), so it stays small
    from pathlib import Path

    from shapely import LineString

    from pytest_avscenario.export.osi import LANE_RADIUS, read_trace, trace_bytes
    from pytest_avscenario.stack import frame

    town06 = Path(__file__).resolve().parent.parent / "example_tests" / "maps" / "Town06.xodr"
    w = World(5)
    town = w.map(str(town06))
    start = town.lane("11/0/4").at(10.0)
    w.ego(start, speed=12.0)
    w.car(town.ahead(start, 25.0), speed=8.0, behavior=b.brake_at(1.0, decel=4.0))
    w.run(seconds=3)
    data, n = trace_bytes(w)
    frames = list(read_trace(data))
    assert len(frames) == n == w.trajectory.n_steps
    lanes = {l.source_reference[0].identifier[0]: l for l in frames[0].global_ground_truth.lane}
    every = w.view().lanes
    assert 0 < len(lanes) < len(every) / 10
    assert {str(v) for v in w.trajectory.lane.ravel()} <= set(lanes)  # every lane driven on
    path = LineString(np.stack([w.trajectory.x[0], w.trajectory.y[0]], axis=1))
    for lane in every:  # in the trace exactly when within the radius of the path (or driven on)
        near = LineString(lane.centre_line).distance(path) <= LANE_RADIUS
        assert (lane.id in lanes) == (near or lane.id in {str(v) for v in w.trajectory.lane.ravel()})
    assert len(frames[0].global_ground_truth.lane_boundary) == 2 * len(lanes)
    ids = {l.id.value for l in lanes.values()}
    for obj in frames[-1].global_ground_truth.moving_object:  # objects name their lanes
        assert obj.assigned_lane_id[0].value in ids
    assert len(data) < len(frame.lane_ground_truth(w.view())) / 5  # all lanes: 5x the trace


def test_the_writers_load_without_scipy_integrate_or_xmlschema_which_still_work_later():
    # a process that exports does not pay for scipy.integrate and xmlschema (0.9 s of CPU)
    # until something calls them; afterwards both are the real modules
    import subprocess
    import sys

    code = (
        "import sys\n"
        "from pytest_avscenario.export._writers import load\n"
        "xodr, xosc = load()\n"
        "print(sorted(m for m in ('scipy.integrate', 'xmlschema') if m in sys.modules))\n"
        "from scenariogeneration.xodr import geometry\n"
        "print(round(geometry.quad(lambda x: x, 0, 2)[0], 9))\n"
        "import scipy.integrate, xmlschema\n"
        "print(type(sys.modules['scipy.integrate']).__name__, callable(xmlschema.XMLSchema))\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True,
                         cwd=str(__import__("pathlib").Path(__file__).resolve().parent.parent))
    assert out.stdout.split("\n")[:3] == ["[]", "2.0", "module True"], out.stdout + out.stderr


def test_an_export_that_fails_says_why_and_raises_nothing(tmp_path):
    w = World(1, driver=blind)
    road = w.straight_road()
    w.ego(road.lane(0), speed=5)
    res = export_case(w, {}, tmp_path, "unrun")  # never run: no recording
    assert "xosc" not in res.files and "osi" not in res.files
    assert "has not run" in res.errors["xosc"] and "has not run" in res.errors["osi"]


# --------------------------------------------------------------------------- the plugin

BRAKING_LEAD = """
from pytest_avscenario import scenario, Uniform
from pytest_avscenario.monitors import collision
from pytest_avscenario.sim import behaviors as b

def blind(observation):
    return 0.0, 0.0

@scenario(gap=Uniform(20.0, 60.0, unit="m"), samples=3, monitors=[collision()],
          reference_driver=None)
def test_lead(case, world):
    road = world.straight_road(lanes=1, length=400)
    world.ego(road.lane(0), s=20.0, speed=15.0, driver=blind)
    world.car(road.lane(0), s=20.0 + case.gap, speed=10.0, behavior=b.brake_at(1.0, decel=6.0))
    world.run(seconds=8)
"""


FAST = ("--avs-seed=1", "--avs-db=none", "--avs-shrink-budget=0", "--avs-gifs=0",
        "--avs-case-pictures=0", "-p", "no:cacheprovider")


def _rows(pytester):
    import json

    lines = (pytester.path / "avs-report" / "errors.jsonl").read_text().splitlines()
    return [json.loads(line) for line in lines if line.strip()]


def test_plugin_exports_counterexamples_beside_their_cards(pytester, schemas):
    pytester.makepyfile(test_lead=BRAKING_LEAD)
    result = pytester.runpytest(*FAST, "--avs-export=1")
    result.assert_outcomes(failed=3)  # a blind ego hits every braking lead
    cases = pytester.path / "avs-report" / "cases"
    rows = [r for r in _rows(pytester) if r["verdict"] == "fail"]
    exported = [r for r in rows if r.get("exports")]
    assert len(exported) == 1  # --avs-export=1: one per test and sampler (none minimized)
    ex = exported[0]["exports"]
    assert set(ex) == {"xosc", "xosc_1_0", "xodr", "osi", "trajectories"}
    assert set(ex["trajectories"]) == {"ego"}  # the lead brakes: an action, not a trajectory
    for kind in ("xosc", "xodr"):
        assert list(schemas[kind].iter_errors(str(cases / ex[kind]))) == []
    assert (cases / ex["osi"]).stat().st_size > 0
    card = next(c for c in cases.glob("*.html")
                if ex["xosc"] in c.read_text())  # the card links its files
    page = card.read_text()
    assert all(f"href='{ex[k]}'" in page for k in ("xosc", "xosc_1_0", "xodr", "osi"))
    root = ET.parse(cases / ex["xosc"]).getroot()
    gap = root.find("ParameterDeclarations/ParameterDeclaration[@name='gap']")
    assert float(gap.get("value")) == exported[0]["params"]["gap"]
    assert "gap [m]" in (cases / ex["xosc"]).read_text()


def test_export_none_writes_nothing_and_a_failing_export_keeps_the_case(pytester, monkeypatch):
    import pytest_avscenario.export.opendrive as odr

    pytester.makepyfile(test_lead=BRAKING_LEAD)
    result = pytester.runpytest(*FAST, "--avs-export=none")
    result.assert_outcomes(failed=3)
    assert not any(r.get("exports") for r in _rows(pytester))
    assert not list((pytester.path / "avs-report" / "cases").glob("*.xosc"))
    # an export that breaks (here: the road writer) is said in the row; the case stays failed
    def broken(road, name="road"):
        raise RuntimeError("cannot write this road")

    monkeypatch.setattr(odr, "road_xodr", broken)
    result = pytester.runpytest(*FAST, "--avs-export=all")
    result.assert_outcomes(failed=3)
    rows = [r for r in _rows(pytester) if r["verdict"] == "fail"]
    assert len(rows) == 3
    for r in rows:
        assert r["exports"]["errors"]["xosc"] == "RuntimeError: cannot write this road"
        assert "osi" in r["exports"]  # the trace does not need the road writer
    card = next((pytester.path / "avs-report" / "cases").glob("*.html")).read_text()
    assert "Not exported (xosc): RuntimeError: cannot write this road" in card


def test_without_the_option_every_pictured_counterexample_is_exported(pytester):
    # the default exports what the report pictures: here 2 of the 3 failing cases (none is
    # minimized with a budget of 0), each file set beside the card that shows its picture
    pytester.makepyfile(test_lead=BRAKING_LEAD)
    args = [a for a in FAST if a != "--avs-case-pictures=0"]
    result = pytester.runpytest(*args, "--avs-case-pictures=2")
    result.assert_outcomes(failed=3)
    exported = [r for r in _rows(pytester) if r.get("exports")]
    assert len(exported) == 2
    cases = pytester.path / "avs-report" / "cases"
    assert len(list(cases.glob("*.v1_0.xosc"))) == 2
    pictured = {p.name.split(".")[0] for p in cases.glob("*.png")}
    assert {pathlib.Path(r["exports"]["xosc"]).name.split(".")[0] for r in exported} <= pictured
    # a recorded trajectory's vertex is one line of the file (the files stay ~0.2 MB a case)
    text = (cases / exported[0]["exports"]["xosc"]).read_text()
    assert "<Vertex time=\"0.1\"><Position><WorldPosition " in text


def test_bad_export_option_is_a_usage_error(pytester):
    pytester.makepyfile(test_lead=BRAKING_LEAD)
    result = pytester.runpytest("--avs-export=some", "-p", "no:cacheprovider")
    assert result.ret == pytest.ExitCode.USAGE_ERROR
    result.stderr.fnmatch_lines(["*--avs-export*must be a number N, 'all' or 'none'*"])


def test_the_example_vehicle_following_export_replays_to_the_same_collision(tmp_path, monkeypatch):
    # the example suite's scenario 2: its lead's imprecise braking (drawn during the run) has
    # no OpenSCENARIO equivalent, so the lead follows its recorded trajectory in the file
    from pathlib import Path

    from pytest_avscenario.case import Case

    examples = Path(__file__).resolve().parent.parent / "example_tests"
    monkeypatch.syspath_prepend(str(examples))
    from test_02_vehicle_following import test_vehicle_following as scenario

    case = Case(dict(gap=14.0, lead_speed=6.0, brake_at=1.0, lead_decel=8.0,
                     lead_final_speed=0.0), 0, 5, "halton")
    w = World(5, rng=case.rng, driver=blind)
    scenario(case, w)
    first = np.flatnonzero(w.trajectory.crashed[0])
    assert first.size
    res = export_case(w, dict(case.params), tmp_path, "vehicle_following", osi=False)
    assert "Wobble has no OpenSCENARIO equivalent" in res.trajectories["car1"]
    again = replay(res.files["xosc"])
    second = np.flatnonzero(again.crashed[0])
    assert second.size and abs(int(second[0]) - int(first[0])) <= 1


def test_an_intersection_export_replays_to_the_same_collision(tmp_path, monkeypatch):
    # the example suite's scenario 7: the oncoming car's left turn (it waits until the ego is
    # 30 m from the centre) has no OpenSCENARIO equivalent, so it follows its recorded
    # trajectory; both start by road and lane on the junction's arms and keep their routes
    from pathlib import Path

    from pytest_avscenario.case import Case

    examples = Path(__file__).resolve().parent.parent / "example_tests"
    monkeypatch.syspath_prepend(str(examples))
    from test_07_oncoming_left_turn import test_oncoming_left_turn as scenario

    case = Case(dict(d_ego=20.0, ego_speed=8.0, d_adv=20.0, adv_speed=7.0, adv_go_within=30.0),
                0, 5, "halton")
    w = World(5, rng=case.rng, driver=blind)
    scenario(case, w)
    first = np.flatnonzero(w.trajectory.crashed[0])
    assert first.size, "this case must collide for the test to mean anything"
    res = export_case(w, dict(case.params), tmp_path, "oncoming_left_turn", osi=False)
    assert "Turn has no OpenSCENARIO equivalent" in res.trajectories["car1"]
    world, _, _ = replay_world(res.files["xosc"])  # from the files alone
    assert world.road.kind == "intersection"
    assert [l.id for l in world.agent("car1").plan] == [l.id for l in w.agent("car1").plan]
    again = replay(res.files["xosc"])
    second = np.flatnonzero(again.crashed[0])
    assert second.size and abs(int(second[0]) - int(first[0])) <= 1
    k = int(first[0])
    assert np.abs(again.x[:, :k] - w.trajectory.x[:, :k]).max() < 1e-6
    assert np.abs(again.y[:, :k] - w.trajectory.y[:, :k]).max() < 1e-6


def test_a_map_export_references_its_map_and_replays_to_the_same_collision(tmp_path, monkeypatch,
                                                                          schemas):
    # the example suite's fabriksgatan left turn: the map file is copied once beside the
    # exports (content-named) and referenced by the .xosc; agents start by road and lane on
    # it; the oncoming car keeps its lane along its route through the junction (an action)
    from pathlib import Path

    from scenariogeneration import xosc

    from pytest_avscenario.case import Case

    examples = Path(__file__).resolve().parent.parent / "example_tests"
    monkeypatch.syspath_prepend(str(examples))
    from test_maps_fabriksgatan_left_turn import test_fabriksgatan_left_turn as scenario

    case = Case(dict(d_ego=5.0, ego_speed=8.0, d_adv=20.0, adv_speed=12.0), 0, 5, "halton")
    w = World(5, rng=case.rng)
    scenario(case, w)
    first = np.flatnonzero(w.trajectory.crashed[0])
    assert first.size, "this case must collide for the test to mean anything"
    res = export_case(w, dict(case.params), tmp_path, "left_turn", osi=False)
    again_res = export_case(w, dict(case.params), tmp_path, "left_turn_again", osi=False)
    assert not res.errors, res.errors
    for kind in ("xosc", "xosc_1_0"):
        assert list(schemas[kind].iter_errors(res.files[kind])) == []
    m = re.fullmatch(r"fabriksgatan-[0-9a-f]{8}\.xodr", Path(res.files["xodr"]).name)
    assert m and again_res.files["xodr"] == res.files["xodr"]  # one copy for every case
    assert Path(res.files["xodr"]).read_bytes() == (examples / "maps/fabriksgatan.xodr").read_bytes()
    assert res.to_json()["xodr"] == Path(res.files["xodr"]).name
    sce = xosc.ParseOpenScenario(res.files["xosc"])  # scenariogeneration reads it back
    assert sce.roadnetwork.road_file == Path(res.files["xodr"]).name
    root = ET.parse(res.files["xosc"]).getroot()
    ego = root.find("Storyboard/Init/Actions/Private[@entityRef='ego']")
    start = ego.find(".//TeleportAction//LanePosition")
    assert (start.get("roadId"), start.get("laneId")) == ("0", "1")  # lane 0/0/1, as built
    assert abs(float(start.get("offset"))) < 0.01
    way = [(p.get("roadId"), p.get("laneId")) for p in ego.findall(".//Waypoint//LanePosition")]
    assert way == [("0", "1"), ("10", "-1"), ("3", "1")]  # the scenario's route, as written
    assert set(res.trajectories) == {"ego"} and "oncoming" in res.actions
    again = replay(res.files["xosc"])  # the map, the agents and their routes from the files
    second = np.flatnonzero(again.crashed[0])
    assert second.size and abs(int(second[0]) - int(first[0])) <= 1
    k = int(first[0])
    assert np.abs(again.x[:, :k] - w.trajectory.x[:, :k]).max() < 1e-6


def test_export_ini_value_is_checked_and_named(pytester):
    pytester.makeini("[pytest]\navs_export = lots\n")
    pytester.makepyfile(test_lead=BRAKING_LEAD)
    result = pytester.runpytest("-p", "no:cacheprovider")
    assert result.ret == pytest.ExitCode.USAGE_ERROR
    result.stderr.fnmatch_lines(["*ini avs_export*must be a number N, 'all' or 'none'*"])

"""Which failures matter: every counterexample simulated again with the reference driver (UN
R157's careful and competent driver by default) — avoidable or not, per violated metric, and
who entered an RSS-unsafe state first — in the table, the failure text, JUnit, the summary
and the acceptance criteria."""

from __future__ import annotations

import json

import numpy as np

import pytest

from pytest_avscenario.sim.drivers import stopping_distance

# A stopped car ahead of an ego at 20 m/s whose driver never brakes: every case collides.
# The careful driver stops within stopping_distance(20) ≈ 55 m: a gap of 10 m is unavoidable,
# one of 120 m avoidable (the closed forms are checked in test_reference.py).
BLIND = """
import pytest

@pytest.fixture
def avs_driver():
    def blind(observation):  # never brakes
        return (0.0, 0.0)
    return blind
"""

STOPPED = """
from pytest_avscenario import scenario, Choice
from pytest_avscenario.monitors import collision
from pytest_avscenario.sim import behaviors as b

@scenario(gap=Choice([10.0, 120.0]), samples=2, monitors=[collision()], shrink_budget=0{extra})
def test_stopped(case, world):
    road = world.straight_road(lanes=1, length=400)
    world.ego(road.lane(0), s=20.0, speed=20.0)
    world.car(road.lane(0), s=20.0 + case.gap, speed=0.0, behavior=b.stopped(), name="stopped")
    world.run(seconds=10)
"""


def rows_of(pytester) -> list[dict]:
    table = pytester.path / "avs-report" / "errors.jsonl"
    return [json.loads(line) for line in table.read_text().splitlines()]


def by_gap(pytester) -> dict[float, dict]:
    return {r["params"]["gap"]: r for r in rows_of(pytester)}


def test_the_sanity_of_the_fixture_scene():
    assert 10.0 < stopping_distance(20.0) < 120.0


def test_each_counterexample_is_judged_against_the_careful_driver(pytester):
    pytester.makeconftest(BLIND)
    pytester.makepyfile(test_stopped=STOPPED.format(extra=""))
    result = pytester.runpytest("--avs-db=none", "-p", "no:xdist", "--junitxml=out.xml")
    result.assert_outcomes(failed=2)
    rows = by_gap(pytester)
    assert rows[120.0]["avoidable"] == {"collision": True}
    assert rows[10.0]["avoidable"] == {"collision": False}
    # far away the ego became RSS-unsafe by its own fault; at 10 m the scene starts unsafe,
    # which is nobody's doing
    assert rows[120.0]["unsafe_first"]["agent"] == "ego"
    assert "unsafe_first" not in rows[10.0]
    out = result.stdout.str()
    # each judgement names the conflict: the other agent and the time of the first violation
    assert "collision with stopped at t = " in out
    assert ": avoidable — the careful reference driver keeps it: keeps " in out
    assert ": UNAVOIDABLE — the careful reference driver violates it too: hits stopped too" in out
    assert "RSS: ego entered an unsafe state first" in out
    result.stdout.fnmatch_lines(["*cex  min  unavoid*", "test_stopped *2    0        1*",
                                 "*unavoid: counterexamples the reference driver fails too*"])
    xml = (pytester.path / "out.xml").read_text()
    assert xml.count('name="avs.avoidable.collision" value="true"') == 1
    assert xml.count('name="avs.avoidable.collision" value="false"') == 1
    summary = json.loads((pytester.path / "avs-report" / "summary.json").read_text())["tests"][0]
    assert (summary["judged"], summary["unavoidable"]) == (2, 1)


def test_accept_avoidable_lets_only_avoidable_counterexamples_reject(pytester):
    pytester.makeconftest(BLIND)
    pytester.makepyfile(test_stopped=STOPPED.format(extra=", accept='avoidable'"))
    result = pytester.runpytest("--avs-db=none", "-p", "no:xdist", "-rx")
    result.assert_outcomes(failed=1, xfailed=1)
    assert result.ret == pytest.ExitCode.TESTS_FAILED
    result.stdout.fnmatch_lines(["*XFAIL*violated collision, unavoidable: the reference driver violates it too*"])


def test_the_check_can_be_turned_off_or_capped(pytester):
    pytester.makeconftest(BLIND)
    pytester.makepyfile(test_stopped=STOPPED.format(extra=""))
    pytester.runpytest("--avs-db=none", "-p", "no:xdist", "--avs-reference-driver=none")
    assert all("avoidable" not in r for r in rows_of(pytester))
    pytester.runpytest("--avs-db=none", "-p", "no:xdist", "--avs-reference-max=1")
    assert sum("avoidable" in r for r in rows_of(pytester)) == 1


@pytest.mark.parametrize("how", ["marker", "option"])
def test_the_margin_is_configurable(pytester, how):
    # the careful driver stops 27.6 m short of the car 120 m ahead: avoided with the default
    # margin of 0.2 m, unknown with a margin of 40 m
    pytester.makeconftest(BLIND)
    extra = ", reference_margin={'collision': 40.0}" if how == "marker" else ""
    pytester.makepyfile(test_stopped=STOPPED.format(extra=extra))
    args = ["--avs-reference-margin=collision=40"] if how == "option" else []
    pytester.runpytest("--avs-db=none", "-p", "no:xdist", *args)
    rows = by_gap(pytester)
    assert rows[120.0]["avoidable"] == {"collision": None}
    assert rows[10.0]["avoidable"] == {"collision": False}  # a real impact either way


def test_the_marker_names_another_reference_driver(pytester):
    pytester.makeconftest(BLIND)
    pytester.makepyfile(test_stopped=STOPPED.format(extra=", reference_driver='idm'"))
    result = pytester.runpytest("--avs-db=none", "-p", "no:xdist")
    result.assert_outcomes(failed=2)
    assert "the idm reference driver" in result.stdout.str()
    assert all("avoidable" in r for r in rows_of(pytester))


@pytest.mark.parametrize("declaration, message", [
    ("reference_driver='nobody'", "reference_driver must be a built-in driver"),
    ("accept='avoidable', monitors=[collision()]", "accept='avoidable' counts only counterexamples a reference driver avoids"),
    ("reference_margin={'colision': 0.5}, monitors=[collision()]", "reference_margin names 'colision'"),
    ("reference_margin={'collision': -1}, monitors=[collision()]", "margin of 'collision' must be a number >= 0"),
])
def test_bad_avoidability_settings_are_collection_errors(pytester, declaration, message):
    pytester.makepyfile(f"""
from pytest_avscenario import scenario, Uniform
from pytest_avscenario.monitors import collision

@scenario(x=Uniform(0, 1), samples=2, {declaration})
def test_no_world(case):
    pass
""")
    result = pytester.runpytest("--avs-db=none", "-p", "no:xdist")
    assert result.ret == pytest.ExitCode.INTERRUPTED
    assert "test_no_world" in result.stdout.str() and message in result.stdout.str()
    assert "Traceback" not in result.stdout.str()


RECORDING = BLIND + """
import json

import numpy as np
import numpy as np
from pytest_avscenario.samplers import Sampler, register

@register("alternate")
class Alternate(Sampler):
    # asks the two ends of the space in turn and writes down what it is told
    name = "alternate"
    active = True

    def __init__(self, space, seed=0, metrics=None):
        super().__init__(space, seed=seed)
        self.k = 0

    def ask_unit(self):
        self.k += 1
        return np.full(self.d, 0.0 if self.k % 2 else 1.0)

    def tell_unit(self, u, rho):
        with open("told.jsonl", "a") as f:
            f.write(json.dumps(None if rho is None else "told") + "\\n")
"""


@pytest.mark.parametrize("mode, told", [("keep", ["told", "told"]), ("discard", [None, "told"])])
def test_discard_tells_an_active_sampler_nothing_of_an_unavoidable_case(pytester, mode, told):
    # the first case starts 10 m behind a stopped car at 20 m/s (RSS-unsafe from t = 0, and
    # unavoidable); the second 120 m behind (avoidable): both are counterexamples
    pytester.makeconftest(RECORDING)
    pytester.makepyfile(test_stopped=STOPPED.format(extra=f", sampler='alternate', unavoidable='{mode}'"))
    result = pytester.runpytest("--avs-db=none", "-p", "no:xdist")
    result.assert_outcomes(failed=2)  # still run and reported either way
    assert [json.loads(line) for line in (pytester.path / "told.jsonl").read_text().splitlines()] == told
    assert [r["avoidable"] for r in rows_of(pytester)] == [{"collision": False}, {"collision": True}]


def test_avoidable_reads_as_a_qualifier_of_the_other_criteria():
    from pytest_avscenario.acceptance import parse_accept, rate

    assert parse_accept("avoidable").any and parse_accept("avoidable").avoidable
    both = parse_accept(["collision", "avoidable"])
    assert not both.any and both.metrics == ("collision",) and both.avoidable
    assert parse_accept(both.text()) == both
    with pytest.raises(ValueError, match="'avoidable' qualifies"):
        parse_accept(["avoidable", rate("collision", at_most=0.01)])


# -- the same conflict ------------------------------------------------------------------------
# The SUT steers into the car beside it ("side") in its first 0.6 s; the careful reference
# keeps its lane, never touches "side", and hits a car that appears stopped in its lane at
# t = 6 s ("late"), long after the SUT crashed. Judged per metric, the reference's collision
# made the SUT's unavoidable; judged per conflict it is avoidable.
SWERVE = """
import pytest

@pytest.fixture
def avs_driver():
    def swerve(observation):  # into the lane on its right, at once
        return (0.0, -0.1 if observation.t < 0.6 else 0.0)
    return swerve
"""

SIDESWIPE = """
from pytest_avscenario import scenario, Choice
from pytest_avscenario.monitors import collision
from pytest_avscenario.sim import behaviors as b

@scenario(late_at=Choice([6.0]), samples=1, monitors=[collision()], shrink_budget=0{extra})
def test_sideswipe(case, world):
    road = world.straight_road(lanes=2, length=600)
    world.ego(road.lane(0), s=20.0, speed=20.0)
    world.car(road.lane(1), s=19.0, speed=20.0, name="side")
    world.car(road.lane(0), s=150.0, speed=0.0, behavior=b.stopped(), name="late",
              appear=case.late_at)
    world.run(seconds=9)
"""


def test_a_reference_crash_with_another_car_does_not_make_a_collision_unavoidable(pytester):
    pytester.makeconftest(SWERVE)
    pytester.makepyfile(test_sideswipe=SIDESWIPE.format(extra=", accept='avoidable'"))
    result = pytester.runpytest("--avs-db=none", "-p", "no:xdist", "--junitxml=out.xml")
    # the campaign is rejected: the reference avoids the SUT's conflict with "side"
    result.assert_outcomes(failed=1)
    assert result.ret == pytest.ExitCode.TESTS_FAILED
    (row,) = rows_of(pytester)
    assert row["violations"]["collision"]["agent"] == "side"
    assert row["avoidable"] == {"collision": True}
    assert row["conflicts"]["collision"]["agent"] == "side"
    assert row["conflicts"]["collision"]["rho"] >= 0.2  # metres it kept from "side"
    out = result.stdout.str()
    assert "collision with side at t = " in out and "keeps it: keeps " in out
    xml = (pytester.path / "out.xml").read_text()
    assert 'name="avs.avoidable.collision" value="true"' in xml
    assert 'name="avs.conflict.collision" value="side@' in xml


def conflict_traj(ego_x, other_x, t, *, other_y=0.0, other_vx=None, name="lead"):
    from pytest_avscenario.trajectory import Trajectory

    t = np.asarray(t, dtype=float)
    return Trajectory.from_arrays(t, agents={
        "ego": {"x": np.asarray(ego_x, dtype=float), "y": np.zeros_like(t), "heading": 0.0},
        name: {"x": np.asarray(other_x, dtype=float), "y": np.full_like(t, other_y),
               "heading": 0.0, **({} if other_vx is None else {"vx": other_vx})},
    })


def test_a_collision_is_judged_with_a_margin_and_an_impact_speed():
    from pytest_avscenario.monitors import collision
    from pytest_avscenario.monitors.conflict import COLLISION_MARGIN_M, judge_conflict

    t = np.arange(0.0, 4.0, 0.1)
    ego = 10.0 * np.minimum(t, 2.0)  # drives 20 m and stops; the other car's rear at 25 m + gap
    for gap, expected in ((0.05, None), (COLLISION_MARGIN_M + 0.05, True), (3.0, True)):
        ref = conflict_traj(ego, np.full_like(t, 25.0 + gap), t)
        verdict = judge_conflict(collision(), ref, "lead", 1.0)
        assert verdict.avoided is expected, (gap, verdict)
    # a real impact: it runs into it at 10 m/s; a touch at a standstill is not one
    hit = conflict_traj(10.0 * t, np.full_like(t, 30.0), t)
    assert judge_conflict(collision(), hit, "lead", 1.0).avoided is False
    touch = conflict_traj(np.full_like(t, 20.0), np.full_like(t, 25.0), t, other_vx=0.0)
    assert judge_conflict(collision(), touch, "lead", 1.0).avoided is None


def test_a_reference_contact_between_two_samples_is_a_hit_too():
    # at 0.5 s steps a car crossing the ego's path at 20 m/s is on one side at one sample and
    # past it at the next: no recorded overlap, no crash flag, but the footprints met
    from pytest_avscenario.monitors import collision
    from pytest_avscenario.monitors.conflict import judge_conflict
    from pytest_avscenario.trajectory import Trajectory

    t = np.arange(0.0, 4.0, 0.5)
    cross_y = 20.0 * (t - 1.25)  # at y = 0 (the ego's line) at t = 1.25 s, between samples
    ref = Trajectory.from_arrays(t, agents={
        "ego": {"x": 10.0 * t, "y": np.zeros_like(t), "heading": 0.0},
        "crossing": {"x": np.full_like(t, 12.5), "y": cross_y, "heading": np.pi / 2},
    })
    assert (ref.crashed == 0).all()
    verdict = judge_conflict(collision(), ref, "crossing", 1.0)
    assert verdict.avoided is False and "hits crossing too" in verdict.why, verdict
    # much later than the SUT's violation it is a later conflict, never "avoids it"
    later = judge_conflict(collision(), ref, "crossing", -3.0)
    assert later.avoided is None and "crashes into it" in later.why, later


def test_the_same_conflict_is_the_same_agent_around_the_same_time():
    from pytest_avscenario.monitors import collision, distance
    from pytest_avscenario.monitors.conflict import CONFLICT_WINDOW_S, judge_conflict

    t = np.arange(0.0, 10.0, 0.1)
    ref = conflict_traj(10.0 * t, np.full_like(t, 85.0), t, name="late")  # hits "late" at 8 s
    # another agent than the reference's: not found there, so unknown, never unavoidable
    assert judge_conflict(collision(), ref, "side", 1.0).avoided is None
    # the same agent, within the window: unavoidable; earlier counts too
    assert judge_conflict(collision(), ref, "late", 8.0 - CONFLICT_WINDOW_S / 2).avoided is False
    assert judge_conflict(collision(), ref, "late", 9.5).avoided is False
    # the same agent much later than the SUT's violation: maybe another conflict, unknown
    late = judge_conflict(collision(), ref, "late", 1.0)
    assert late.avoided is None and "later conflict" in late.why
    # a violation that names no agent cannot be placed
    assert judge_conflict(collision(), ref, None, 1.0).avoided is None
    # other metrics: their rho toward that agent, in the same window
    assert judge_conflict(distance(5.0, kind="centre"), ref, "late", 7.0).avoided is False
    assert judge_conflict(distance(5.0, kind="centre"), ref, "late", 1.0).avoided is None


def test_a_metric_of_the_ego_alone_is_judged_on_the_reference_ego():
    from pytest_avscenario.monitors import progress
    from pytest_avscenario.monitors.conflict import judge_conflict

    t = np.arange(0.0, 5.0, 0.1)
    moving = conflict_traj(5.0 * t, np.full_like(t, 500.0), t)
    standing = conflict_traj(np.zeros_like(t), np.full_like(t, 500.0), t)
    kept = judge_conflict(progress(11.0), moving, "ego", 4.9)
    assert kept.avoided is True and kept.ego_alone
    assert judge_conflict(progress(11.0), standing, "ego", 4.9).avoided is False


def test_a_minimized_case_is_judged_too_and_the_card_says_which_case_is_which(pytester):
    # gap 10 m is unavoidable; minimizing moves it to the nominal 120 m, still a collision for
    # the blind driver but one the careful driver avoids: the two judgements differ
    pytester.makeconftest(BLIND)
    pytester.makepyfile(test_stopped=STOPPED.replace("Choice([10.0, 120.0])", "Choice([120.0, 10.0])")
                        .format(extra="").replace("shrink_budget=0", "shrink_budget=2"))
    result = pytester.runpytest("--avs-db=none", "-p", "no:xdist", "--junitxml=out.xml")
    result.assert_outcomes(failed=2)
    row = by_gap(pytester)[10.0]
    assert row["minimized"] == {"gap": 120.0}
    assert row["avoidable"] == {"collision": False}
    assert row["minimized_avoidable"] == {"collision": True}
    assert "t" in row["minimized_violations"]["collision"]  # where the minimized case failed first
    # the shrink row of the minimized candidate carries its judgement as well
    table = (pytester.path / "avs-report" / "shrink.jsonl").read_text().splitlines()
    shrunk = [r for r in map(json.loads, table) if r["params"] == {"gap": 120.0}]
    assert shrunk and shrunk[-1]["avoidable"] == {"collision": True}
    out = result.stdout.str()
    assert "(found case): UNAVOIDABLE" in out and "(minimized case): avoidable" in out
    assert 'name="avs.minimized_avoidable.collision" value="true"' in (pytester.path / "out.xml").read_text()
    item = row["item"].partition("[")[2].rstrip("]")
    card = next((pytester.path / "avs-report" / "cases").glob(f"*.{item}.html")).read_text()
    # a header over each case's columns, the reference driver's judgement among them
    assert "class='group'>case as found</th>" in card and "class='group'>minimized case</th>" in card
    assert card.count("<th>reference driver</th>") == 2
    assert "show the <b>minimized case</b> (gap=120)" in card
    assert "(minimized case)</figcaption>" in card


def test_whether_a_scene_starts_rss_unsafe_does_not_depend_on_the_egos_first_action():
    # a car 50 m ahead in the ego's lane at the ego's speed: RSS-unsafe from t = 0 (in line,
    # closer than the safe ~90 m). If the ego changes lane in its first step, the lane
    # direction estimated from the step after tilts by ~7 degrees, the car ahead appears
    # 6 m to the side and the initial scene looked laterally safe: not unsafe at all.
    from pytest_avscenario.monitors.rss import rss_margins
    from pytest_avscenario.outcome import CaseOutcome
    from pytest_avscenario.campaign.pipeline import starts_unsafe
    from pytest_avscenario.trajectory import Trajectory

    t = np.arange(0.0, 2.0, 0.1)

    def scene(lateral_mps):
        y = -lateral_mps * t  # leaving the lane centre from the first step on
        vy = np.full_like(t, -lateral_mps)
        vy[0] = 0.0  # placed driving along its lane
        heading = np.arctan2(vy, 25.0)
        return Trajectory.from_arrays(t, agents={
            "ego": {"x": 25.0 * t, "y": y, "vx": 25.0, "vy": vy, "heading": heading,
                    "lane": "L0", "lane_offset": y},
            "lead": {"x": 50.0 + 25.0 * t, "y": 0.0 * t, "vx": 25.0, "vy": 0.0, "heading": 0.0,
                     "lane": "L0", "lane_offset": 0.0},
        })

    straight, swerving = scene(0.0), scene(3.0)
    for traj in (straight, swerving):
        lon, lat = rss_margins(traj)
        assert lon[0, 0] < 0 and lat[0, 0] < 0
        assert starts_unsafe(CaseOutcome(params={}, verdict="fail", trajectory=traj))
    np.testing.assert_allclose(np.stack(rss_margins(swerving))[:, :, 0],
                               np.stack(rss_margins(straight))[:, :, 0])


def test_rows_keep_both_judgements_and_old_rows_still_read():
    from pytest_avscenario.outcome import CaseRow

    old = {"test": "t.py::test_x", "sampler": "halton", "index": 3, "origin": "sampled",
           "params": {"gap": 10.0}, "rho": {"collision": -0.0}, "verdict": "fail",
           "avoidable": {"collision": False}}
    row = CaseRow.from_json(old)
    assert row.unavoidable and row.conflicts is None and row.minimized_avoidable is None
    conflict = {"agent": "side", "t": 0.5, "until": 2.5, "rho": 1.5, "why": "keeps 1.50 m from side"}
    new = CaseRow.from_json({**old, "avoidable": {"collision": True},
                             "conflicts": {"collision": conflict}, "minimized": {"gap": 120.0},
                             "minimized_violations": {"collision": {"t": 5.8, "agent": None}},
                             "minimized_avoidable": {"collision": None},
                             "minimized_conflicts": {"collision": {**conflict, "agent": "late"}}})
    again = CaseRow.from_json(json.loads(json.dumps(new.to_json())))
    assert again.conflicts == {"collision": conflict}
    assert again.minimized_avoidable == {"collision": None}
    assert again.minimized_conflicts["collision"]["agent"] == "late"
    assert again.minimized_violations == {"collision": {"t": 5.8, "agent": None}}

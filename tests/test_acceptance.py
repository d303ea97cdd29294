"""Acceptance criteria gate CI: which counterexamples reject a campaign, rate bounds with
confidence, regressions only, a baseline run; the exit status follows the verdicts."""

import json

import pytest

from pytest_avscenario.acceptance import clopper_pearson_upper, parse_accept, rate

# The other car stands SCALE·x m ahead and 3 m to the side: `distance` (5 m between centres)
# is violated for SCALE·x < 4; the 2-m wide cars never touch, so `collision` always holds.
SCENARIO = """
import os
from pytest_avscenario import scenario, Uniform
from pytest_avscenario.acceptance import rate
from pytest_avscenario.monitors import collision, distance
from pytest_avscenario.trajectory import Trajectory

SCALE = float(os.environ.get("AVS_TEST_SCALE", "20"))

@scenario(x=Uniform(0, 1), samples={samples}, sampler="{sampler}", monitors=[distance(5.0, kind="centre"), collision()]{accept})
def test_gap(case):
    gap = SCALE * case.x
    return Trajectory.from_arrays([0.0, 0.1], {{
        "ego": {{"x": [0.0, 0.0], "y": [0.0, 0.0]}},
        "lead": {{"x": [gap, gap], "y": [3.0, 3.0]}},
    }})
"""


def _scenario(pytester, accept="", samples=8, sampler="halton"):
    pytester.makepyfile(test_gap=SCENARIO.format(
        samples=samples, sampler=sampler, accept=f", accept={accept}" if accept else ""))


def _summary(pytester, report="avs-report"):
    return {(t["test"], t["sampler"]): t for t in
            json.loads((pytester.path / report / "summary.json").read_text())["tests"]}


def test_by_default_any_counterexample_rejects_the_campaign(pytester):
    _scenario(pytester)
    result = pytester.runpytest("--avs-db=none", "--avs-seed=1", "--avs-shrink-budget=0")
    assert result.ret == pytest.ExitCode.TESTS_FAILED
    outcomes = result.parseoutcomes()
    assert outcomes["failed"] >= 1 and "xfailed" not in outcomes
    result.stdout.fnmatch_lines(["REJECTED test_gap [[]halton]: counterexample (distance): [[]halton-00?] and 1 more"])
    (campaign,) = _summary(pytester).values()
    assert campaign["verdict"] == "rejected"


def test_named_metrics_only_reject_their_own_violations(pytester):
    _scenario(pytester, accept='["collision"]')
    result = pytester.runpytest("--avs-db=none", "--avs-seed=1", "--avs-shrink-budget=0",
                                "--junitxml=out.xml")
    assert result.ret == pytest.ExitCode.OK
    outcomes = result.parseoutcomes()
    assert outcomes["xfailed"] >= 1 and "failed" not in outcomes
    assert "REJECTED" not in result.stdout.str()
    (campaign,) = _summary(pytester).values()
    assert campaign["verdict"] == "accepted" and campaign["counterexamples"] == outcomes["xfailed"]
    xml = (pytester.path / "out.xml").read_text()
    assert 'name="avs.test[test_gap.py::test_gap][halton].verdict" value="accepted"' in xml
    # every counterexample is still recorded as one
    rows = [json.loads(l) for l in (pytester.path / "avs-report" / "errors.jsonl").read_text().splitlines()]
    assert sum(r["verdict"] == "fail" for r in rows) == outcomes["xfailed"]

    _scenario(pytester, accept='["distance"]')
    result = pytester.runpytest("--avs-db=none", "--avs-seed=1", "--avs-shrink-budget=0")
    assert result.ret == pytest.ExitCode.TESTS_FAILED
    result.stdout.fnmatch_lines(["REJECTED *: counterexample violating distance: *"])


def test_the_command_line_and_ini_give_defaults_the_marker_beats(pytester):
    _scenario(pytester)
    result = pytester.runpytest("--avs-db=none", "--avs-seed=1", "--avs-shrink-budget=0",
                                "--avs-accept=collision")
    assert result.ret == pytest.ExitCode.OK
    _scenario(pytester, accept='"any"')
    result = pytester.runpytest("--avs-db=none", "--avs-seed=1", "--avs-shrink-budget=0",
                                "--avs-accept=collision")
    assert result.ret == pytest.ExitCode.TESTS_FAILED


def test_a_rate_bound_judges_the_whole_campaign_with_clopper_pearson(pytester):
    # halton over x in [0, 1]: about a fifth of 40 cases violate distance
    _scenario(pytester, accept='[rate("distance", at_most=0.5)]', samples=40)
    result = pytester.runpytest("--avs-db=none", "--avs-seed=1", "--avs-shrink-budget=0")
    assert result.ret == pytest.ExitCode.OK, result.stdout.str()
    (campaign,) = _summary(pytester).values()
    k = campaign["violations"]["distance"]
    assert 5 <= k <= 15 and clopper_pearson_upper(k, 40, 0.95) <= 0.5
    assert result.parseoutcomes()["xfailed"] == k

    _scenario(pytester, accept='[rate("distance", at_most=0.2)]', samples=40)
    result = pytester.runpytest("--avs-db=none", "--avs-seed=1", "--avs-shrink-budget=0")
    assert result.ret == pytest.ExitCode.TESTS_FAILED
    result.stdout.fnmatch_lines([f"REJECTED *: distance rate {k}/40: upper 95% bound *% > 20.0%"])


def test_a_rate_bound_on_an_active_sampler_is_refused_at_collection(pytester):
    _scenario(pytester, accept='[rate("distance", at_most=0.1)]', sampler="mab")
    result = pytester.runpytest("--avs-db=none")
    result.stdout.fnmatch_lines(["*::test_gap: accept: *active sampler*not a random sample*"])


def test_criteria_naming_an_unmonitored_metric_are_refused(pytester):
    _scenario(pytester, accept='["colision"]')
    result = pytester.runpytest("--avs-db=none")
    result.stdout.fnmatch_lines(["*::test_gap: accept: accept names metric 'colision'*distance, collision*"])


def test_regressions_only_fail_when_a_stored_counterexample_fails_again(pytester):
    _scenario(pytester, accept='"regressions"')
    first = pytester.runpytest("--avs-seed=1", "--avs-shrink-budget=0")
    assert first.ret == pytest.ExitCode.OK  # new counterexamples: recorded, expected failures
    stored = list((pytester.path / ".avscenario").rglob("*.json"))
    assert stored and first.parseoutcomes()["xfailed"] >= len(stored)
    second = pytester.runpytest("--avs-seed=2", "--avs-shrink-budget=0")
    assert second.ret == pytest.ExitCode.TESTS_FAILED
    second.stdout.fnmatch_lines(["REJECTED *: a stored counterexample fails again (distance): *replay-0*"])


def test_a_baseline_run_rejects_a_significantly_higher_violation_rate(pytester, monkeypatch):
    _scenario(pytester, accept='["collision"]', samples=40)
    monkeypatch.setenv("AVS_TEST_SCALE", "40")  # distance violated for x < 0.1
    base = pytester.runpytest("--avs-db=none", "--avs-seed=1", "--avs-shrink-budget=0",
                              "--avs-report=before")
    assert base.ret == pytest.ExitCode.OK
    monkeypatch.setenv("AVS_TEST_SCALE", "20")  # now for x < 0.2: twice the rate
    same = pytester.runpytest("--avs-db=none", "--avs-seed=1", "--avs-shrink-budget=0",
                              "--avs-baseline=before/summary.json")
    monkeypatch.setenv("AVS_TEST_SCALE", "8")  # x < 0.5: far worse
    worse = pytester.runpytest("--avs-db=none", "--avs-seed=1", "--avs-shrink-budget=0",
                               "--avs-baseline=before/summary.json")
    assert worse.ret == pytest.ExitCode.TESTS_FAILED
    worse.stdout.fnmatch_lines(["REJECTED *: distance rate */40 (*%) vs */40 (*%) in the baseline, p = *"])
    # twice the rate on 40 cases (8 against 4) is not significant: still accepted
    assert same.ret == pytest.ExitCode.OK and "REJECTED" not in same.stdout.str()


def test_an_unreadable_baseline_is_a_usage_error(pytester):
    _scenario(pytester)
    (pytester.path / "old.json").write_text("{not json")
    result = pytester.runpytest("--avs-baseline=old.json")
    assert result.ret == pytest.ExitCode.USAGE_ERROR
    result.stderr.fnmatch_lines(["ERROR: --avs-baseline: *old.json is not a pytest-avscenario summary.json*"])


def test_errors_always_reject_whatever_accept_says(pytester):
    pytester.makepyfile(test_err="""
from pytest_avscenario import scenario, Uniform
from pytest_avscenario.monitors import distance

@scenario(x=Uniform(0, 1), samples=2, monitors=[distance(5.0, kind="centre")], accept="regressions")
def test_broken(case):
    raise RuntimeError("scene mistake")
""")
    result = pytester.runpytest("--avs-db=none", "--junitxml=out.xml")
    result.assert_outcomes(errors=2)
    assert result.ret == pytest.ExitCode.TESTS_FAILED
    result.stdout.fnmatch_lines(["REJECTED *: 2 cases could not be judged (errors; *"])
    xml = (pytester.path / "out.xml").read_text()
    assert xml.count("<error ") == 2 and "<failure" not in xml


@pytest.mark.parametrize("text, terms", [
    ("any", "any"),
    ("collision, school_bus", "collision,school_bus"),
    ("regressions,collision", "collision,regressions"),
    ("rate:collision<=1%@95%", "rate:collision<=1%@95%"),
    ("rate:ttc<=0.05", "rate:ttc<=5%@95%"),
])
def test_criteria_read_from_text(text, terms):
    assert parse_accept(text).text() == terms


@pytest.mark.parametrize("bad", ["rate:collision<1%", "", "not a name", 5, [rate("x", 0.1), 3]])
def test_bad_criteria_say_what_is_expected(bad):
    with pytest.raises(ValueError):
        parse_accept(bad)


def test_clopper_pearson_upper_bound_matches_known_values():
    # 0 events in 298 trials: the "rule of three" gives about 1 %; exact value 0.01000...
    assert clopper_pearson_upper(0, 298, 0.95) == pytest.approx(0.01, abs=2e-4)
    assert clopper_pearson_upper(5, 5, 0.95) == 1.0
    assert clopper_pearson_upper(1, 10, 0.95) == pytest.approx(0.3942, abs=1e-3)


def test_verdicts_under_xdist_come_from_the_controller(pytester):
    pytest.importorskip("xdist")
    _scenario(pytester, accept='[rate("distance", at_most=0.2)]', samples=40)
    result = pytester.runpytest_subprocess("-n", "2", "--avs-db=none", "--avs-seed=1",
                                           "--avs-shrink-budget=0", "-p", "no:cacheprovider")
    assert result.ret == pytest.ExitCode.TESTS_FAILED
    (campaign,) = _summary(pytester).values()
    k = campaign["violations"]["distance"]
    result.stdout.fnmatch_lines([f"REJECTED *: distance rate {k}/40: upper 95% bound *% > 20.0%"])
    assert result.parseoutcomes()["xfailed"] == k

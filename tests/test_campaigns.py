"""Campaign-level behaviour through pytest: active samplers at run time, time budgets,
the error table and summary, JUnit properties, and pytest-xdist."""

from __future__ import annotations

import json

import pytest

ACTIVE = """
import json, os
from pytest_avscenario import scenario, Uniform

def worst(traj):
    return 0.0

@scenario(x=Uniform(0, 1), y=Uniform(0, 1), samples=12, sampler="{sampler}")
def test_search(case):
    with open(os.environ["AVS_RECORD"], "a") as f:
        f.write(json.dumps(case.params) + "\\n")
    # a synthetic failure region: the corner near (0.9, 0.9)
    assert (case.x - 0.9) ** 2 + (case.y - 0.9) ** 2 > 0.01
"""


def _run(pytester, monkeypatch, src, *args, subprocess=False):
    path = pytester.path / f"rec-{len(list(pytester.path.glob('rec-*')))}.jsonl"
    monkeypatch.setenv("AVS_RECORD", str(path))
    pytester.makepyfile(test_campaign=src)
    run = pytester.runpytest_subprocess if subprocess else pytester.runpytest
    result = run("-p", "no:cacheprovider", *args)
    rows = [json.loads(l) for l in path.read_text().splitlines()] if path.exists() else []
    return result, rows


def test_active_sampler_draws_at_run_time_reproducibly(pytester, monkeypatch):
    r1, a = _run(pytester, monkeypatch, ACTIVE.format(sampler="mab"), "--avs-seed=3", "-v")
    r1.stdout.fnmatch_lines(["*test_search[[]mab-000[]]*", "*test_search[[]mab-011[]]*"])
    _, b = _run(pytester, monkeypatch, ACTIVE.format(sampler="mab"), "--avs-seed=3")
    _, c = _run(pytester, monkeypatch, ACTIVE.format(sampler="mab"), "--avs-seed=4")
    assert len(a) == 12 and a == b
    assert a != c


def test_active_failure_prints_a_rerun_command_that_replays_its_values(pytester, monkeypatch):
    src = ACTIVE.format(sampler="mab").replace("> 0.01", "> 10")  # every case fails
    result, rows = _run(pytester, monkeypatch, src, "--avs-seed=3", "--avs-samples=3",
                        "--avs-shrink-budget=0")
    result.assert_outcomes(failed=3)
    line = [l for l in result.outlines if "re-run only this case:" in l][-1]
    command = line.split("re-run only this case: ")[1]
    assert "--avs-params" not in command and len(command) < 120
    args = [a.strip("'") for a in command.split()[1:]]
    again, replayed = _run(pytester, monkeypatch, src, *args, "--avs-shrink-budget=0")
    again.assert_outcomes(failed=1)
    # the earlier cases are simulated first (their values are recorded too): the last
    # recorded values are the re-run case's, the same as in the full run
    assert replayed[-1] == rows[-1]


def test_time_budget_skips_the_rest_with_a_reason(pytester, monkeypatch):
    src = """
import time
from pytest_avscenario import scenario, Uniform
@scenario(x=Uniform(0, 1), samples=10, time_budget="0.3s")
def test_slow(case):
    time.sleep(0.12)
"""
    result, _ = _run(pytester, monkeypatch, src, "-rs")
    outcomes = result.parseoutcomes()
    assert 2 <= outcomes["passed"] <= 5 and outcomes["passed"] + outcomes["skipped"] == 10
    result.stdout.fnmatch_lines(["*time budget of 0.3 s for halton spent after * cases*"])


def test_bad_time_budget_is_a_collection_error(pytester, monkeypatch):
    src = """
from pytest_avscenario import scenario, Uniform
@scenario(x=Uniform(0, 1), time_budget="soon")
def test_x(case):
    pass
"""
    result, _ = _run(pytester, monkeypatch, src)
    result.stdout.fnmatch_lines(["*::test_x: time_budget must be a positive duration*'soon'*"])


REPORTED = """
from pytest_avscenario import scenario, Uniform, Choice
from pytest_avscenario.monitors import as_monitor

def margin(traj):
    return float(traj.meta["margin"])

@scenario(gap=Uniform(10, 40), road=Choice(["dry", "wet"]), samples=10, monitors=[margin])
def test_margin(case):
    from pytest_avscenario.trajectory import Trajectory
    return Trajectory.from_arrays([0.0, 0.1], {"ego": {"x": [0, 1], "y": [0, 0]}},
                                  meta={"margin": case.gap - 30})
"""


def test_error_table_summary_and_junit(pytester, monkeypatch):
    result, _ = _run(pytester, monkeypatch, REPORTED, "--avs-seed=1", "--junitxml=out.xml",
                     "--avs-shrink-budget=0")
    # the margin is gap - 30: exactly the cases with gap < 30 violate it
    outcomes = result.parseoutcomes()
    rows = [json.loads(l) for l in (pytester.path / "avs-report" / "errors.jsonl").read_text().splitlines()]
    assert len(rows) == 10
    assert sum(r["verdict"] == "fail" for r in rows) == outcomes["failed"]
    assert all((r["verdict"] == "fail") == (r["params"]["gap"] < 30) for r in rows)
    result.stdout.fnmatch_lines([
        "*= avscenario =*",
        f"*test_margin*halton*10*{outcomes['failed']}*",
        "avscenario report: *avs-report*",
    ])
    from pytest_avscenario.report.junit import read_properties

    props = read_properties(pytester.path / "out.xml")
    text = (pytester.path / "out.xml").read_text()
    assert 'name="avs.seed" value="1"' in text
    assert 'avs.test[test_campaign.py::test_margin][halton].samples" value="10"' in text
    assert 'name="avs.verdict" value="fail"' in text and 'name="avs.rho.margin"' in text
    assert props  # the junit reader understands the file


def test_report_can_be_disabled(pytester, monkeypatch):
    _run(pytester, monkeypatch, REPORTED, "--avs-report=none")
    assert not (pytester.path / "avs-report").exists()


def test_plain_runs_write_no_report(pytester):
    pytester.makepyfile("def test_x(): pass")
    pytester.runpytest()
    assert not (pytester.path / "avs-report").exists()


def test_xdist_collects_identically_and_merges_one_table(pytester, monkeypatch):
    pytest.importorskip("xdist")
    serial, _ = _run(pytester, monkeypatch, REPORTED, "--avs-seed=9", "-v", "--avs-report=serial",
                     "--avs-db=none")
    parallel, _ = _run(pytester, monkeypatch, REPORTED, "--avs-seed=9", "-n", "2", "-v",
                       "--avs-report=parallel", "--avs-db=none", subprocess=True)
    assert parallel.parseoutcomes() == serial.parseoutcomes()

    def table(name):
        rows = [json.loads(l) for l in (pytester.path / name / "errors.jsonl").read_text().splitlines()]
        return sorted((r["item"], r["verdict"], json.dumps(r["params"]), r["seed"]) for r in rows)

    assert table("parallel") == table("serial")
    parallel.stdout.fnmatch_lines(["*= avscenario =*", "*test_margin*halton*10*"])

"""Minimal counterexamples and the replay database, through pytest."""

from __future__ import annotations

import json
import shlex

import pytest

SYNTHETIC = """
from pytest_avscenario import scenario, Uniform, Choice, example
from pytest_avscenario.trajectory import Trajectory

def margin(traj):
    return float(traj.meta["margin"])

{pins}
@scenario(gap=Uniform(10, 40, nominal=30), road=Choice(["dry", "wet"]), samples=8,
          monitors=[margin]{budget})
def test_gap(case):
    # fails below a gap of {limit} m, whatever the road
    return Trajectory.from_arrays([0.0, 0.1], {{"ego": {{"x": [0, 1], "y": [0, 0]}}}},
                                  meta={{"margin": case.gap - {limit}}})
"""


def _src(limit=20.0, budget=None, pins=""):
    budget = "" if budget is None else f", shrink_budget={budget}"
    return SYNTHETIC.format(limit=limit, budget=budget, pins=pins)


def test_failure_is_minimized_toward_the_nominal_and_pinnable(pytester):
    pytester.makepyfile(test_gap=_src())
    result = pytester.runpytest("--avs-seed=1", "--junitxml=out.xml", "-v")  # -v: the full tables
    out = result.stdout.str()
    # Halton gaps below 20 m fail: 17.5, 13.75, 11.875, 19.375 (Halton index 1, 3, 7, 9 ...)
    assert result.parseoutcomes()["failed"] >= 1
    assert "parameter          found      minimized        nominal" in out
    line = [l for l in result.outlines if "pin it as a regression above the test: @example(" in l][0]
    pinned = line.split("test: ", 1)[1]
    gap = float(pinned.split("gap=")[1].split(",")[0])
    # the minimized gap lies just below the failure boundary (within 5 % of the range)
    assert 20.0 - 1.5 <= gap < 20.0
    assert "road='dry'" in pinned  # the nominal option still fails, so shrinking takes it
    assert result.outlines[result.outlines.index(line) + 1].strip() == \
        "(with: from pytest_avscenario import example)"
    assert "shrinking:" in out and "of 20 simulations" in out
    xml = (pytester.path / "out.xml").read_text()
    assert 'name="avs.minimized"' in xml and 'name="avs.shrink_sims"' in xml
    shrink_rows = (pytester.path / "avs-report" / "shrink.jsonl").read_text().splitlines()
    main_rows = (pytester.path / "avs-report" / "errors.jsonl").read_text().splitlines()
    assert len(main_rows) == 8 and len(shrink_rows) >= 2
    assert all(json.loads(r)["origin"] == "shrink" for r in shrink_rows)


def test_shrinking_respects_the_budget(pytester):
    pytester.makepyfile(test_gap=_src(budget=3))
    result = pytester.runpytest("--avs-seed=1", "-k", "halton-001")  # gap 17.5 fails
    result.assert_outcomes(failed=1)
    result.stdout.fnmatch_lines(["*minimized (3 simulations): gap=*"])
    # a re-run of one case: its report is apart from the campaign's
    rows = (pytester.path / "avs-report" / "rerun" / "shrink.jsonl").read_text().splitlines()
    assert len(rows) == 1 + 3  # one replay for flakiness, then the budget


def test_budget_zero_disables_shrinking(pytester):
    pytester.makepyfile(test_gap=_src())
    result = pytester.runpytest("--avs-seed=1", "--avs-shrink-budget=0", "-k", "halton-001")
    result.assert_outcomes(failed=1)
    assert "pin it as a regression" not in result.stdout.str()
    assert (pytester.path / "avs-report" / "rerun" / "shrink.jsonl").read_text() == ""


def test_flaky_failure_is_reported_not_shrunk(pytester):
    pytester.makepyfile(test_flaky="""
import itertools
from pytest_avscenario import scenario, Uniform
calls = itertools.count()
@scenario(gap=Uniform(10, 40), samples=1)
def test_flaky(case):
    assert next(calls) > 0, "fails only the first time"
""")
    result = pytester.runpytest("--avs-seed=1")
    result.assert_outcomes(failed=1)
    result.stdout.fnmatch_lines(["*FLAKY: a replay of this case with the same seed did not fail*"])


def test_second_run_replays_stored_failures_first_then_forgets_fixed_ones(pytester):
    pytester.makepyfile(test_gap=_src())
    first = pytester.runpytest("--avs-seed=1", "-v")
    failed = first.parseoutcomes()["failed"]
    stored = sorted((pytester.path / ".avscenario").rglob("*.json"))
    # failures that minimize to the same case are stored once
    assert 1 <= len(stored) <= failed
    entry = json.loads(stored[0].read_text())
    assert entry["minimized"] is True and entry["test"].endswith("test_gap")

    second = pytester.runpytest("--avs-seed=2", "-v")
    lines = [l for l in second.outlines if l.startswith("test_gap.py::test_gap[")]
    assert "[replay-0]" in lines[0] and "FAILED" in lines[0]
    assert sum("[replay-" in l for l in lines) == len(stored)

    # the scenario is fixed: replays pass and their entries are removed
    pytester.makepyfile(test_gap=_src(limit=0.0))
    third = pytester.runpytest("--avs-seed=2", "-v")
    assert third.ret == 0
    assert sum(l.startswith("test_gap.py::test_gap[replay-") and "PASSED" in l
               for l in third.outlines) == len(stored)
    assert list((pytester.path / ".avscenario").rglob("*.json")) == []


def test_changed_declaration_skips_stored_entries_with_a_warning(pytester):
    pytester.makepyfile(test_gap=_src())
    pytester.runpytest("--avs-seed=1")
    pytester.makepyfile(test_gap=_src().replace("Uniform(10, 40, nominal=30)", "Uniform(5, 40, nominal=30)"))
    result = pytester.runpytest("--avs-seed=1", "-v")
    assert not any("[replay-" in l for l in result.outlines)
    result.stdout.fnmatch_lines(["*stored counterexample * skipped: parameter 'gap' changed*"])


def test_corrupt_database_file_is_skipped_with_one_warning(pytester):
    pytester.makepyfile(test_gap=_src())
    pytester.runpytest("--avs-seed=1")
    stored = sorted((pytester.path / ".avscenario").rglob("*.json"))
    stored[0].write_text('{"test": "tru')
    result = pytester.runpytest("--avs-seed=1", "-v")
    assert result.ret in (0, 1)  # the run happens
    assert "INTERNALERROR" not in result.stdout.str()
    assert result.stdout.str().count(stored[0].name) >= 1
    assert stored[0].exists()  # left for the user to inspect


def test_database_can_be_disabled(pytester):
    pytester.makepyfile(test_gap=_src())
    pytester.runpytest("--avs-seed=1", "--avs-db=none")
    assert not (pytester.path / ".avscenario").exists()


def test_examples_run_first_and_are_never_shrunk(pytester):
    pins = "@example(gap=11.0, road='wet')\n@example(gap=35.0)"
    pytester.makepyfile(test_gap=_src(pins=pins))
    result = pytester.runpytest("--avs-seed=1", "-v", "--avs-samples=2", "--avs-db=none")
    lines = [l for l in result.outlines if l.startswith("test_gap.py::test_gap[")]
    assert "[example-0] FAILED" in lines[0] and "[example-1] PASSED" in lines[1]
    out = result.stdout.str()
    section = out.split("_ test_gap[example-0] _")[1].split("_ test_gap[")[0]
    assert "parameters: gap=11, road='wet'" in section
    assert "pin it as a regression" not in section


def test_example_outside_the_space_is_a_collection_error(pytester):
    pytester.makepyfile(test_gap=_src(pins="@example(gap=99.0)"))
    result = pytester.runpytest()
    result.stdout.fnmatch_lines(["*::test_gap: @example #0 (@example(gap=99.0)): parameter 'gap'=99.0 lies outside*"])


def test_assertion_failures_shrink_on_the_same_line(pytester):
    pytester.makepyfile(test_assert="""
from pytest_avscenario import scenario, Uniform
@scenario(speed=Uniform(0, 30, nominal=10), samples=6)
def test_speed(case):
    assert case.speed < 21.0, "too fast"
""")
    result = pytester.runpytest("--avs-seed=1")
    line = [l for l in result.outlines if "@example(" in l][0]
    speed = float(line.split("speed=")[1].rstrip(")"))
    assert 21.0 <= speed <= 21.0 + 0.05 * 30


def test_replays_and_database_under_xdist(pytester):
    pytest.importorskip("xdist")
    pytester.makepyfile(test_gap=_src())
    first = pytester.runpytest_subprocess("--avs-seed=1", "-n", "2", "-p", "no:cacheprovider")
    assert first.parseoutcomes()["failed"] >= 1
    db = pytester.path / ".avscenario"
    stored = sorted(db.glob("*.json"))
    assert stored and not [p for p in db.iterdir() if not p.name.endswith(".json")]
    assert all(json.loads(p.read_text())["minimized"] for p in stored)
    # the controller ships the database: every worker collects the same replay items
    # (xdist refuses to run when worker collections differ)
    second = pytester.runpytest_subprocess("--avs-seed=1", "-n", "2", "-v", "-p", "no:cacheprovider")
    replays = [l for l in second.outlines if l.startswith("[gw") and "[replay-" in l]
    assert len(replays) == len(stored)
    assert "Different tests were collected" not in second.stdout.str()


def test_case_timeout_under_xdist(pytester):
    pytest.importorskip("xdist")
    pytester.makepyfile(test_hang="""
from pytest_avscenario import scenario, Uniform
@scenario(x=Uniform(0, 1), samples=2, case_timeout=0.5)
def test_hang(case):
    while True:
        pass
""")
    result = pytester.runpytest_subprocess("-n", "2", "--avs-db=none", "-p", "no:cacheprovider")
    result.assert_outcomes(errors=2)
    result.stdout.fnmatch_lines(["*CaseTimeout*0.5 s*"])


def test_shrink_max_minimizes_and_stores_only_the_first_failures(pytester):
    pytester.makepyfile(test_gap=_src())
    result = pytester.runpytest("--avs-seed=1", "--avs-shrink-max=1")
    failed = result.parseoutcomes()["failed"]
    assert failed >= 2
    out = result.stdout.str()
    assert out.count("pin it as a regression above the test") == 1
    # one whole sentence per further failure (it once stopped at "...were already")
    note = ("not minimized nor stored: the first failure of this test's halton campaign was "
            "minimized already (--avs-shrink-max 1)")
    assert out.count(note) == failed - 1
    assert len(list((pytester.path / ".avscenario").glob("*.json"))) == 1


def test_hypothesis_example_on_a_scenario_test_says_which_example_to_import(pytester):
    pytester.makepyfile("""
from hypothesis import example
from pytest_avscenario import scenario, Uniform

@example(gap=12.0)
@scenario(gap=Uniform(10, 40))
def test_pinned(case):
    pass
""")
    result = pytester.runpytest("--avs-db=none", "--avs-report=none")
    result.stdout.fnmatch_lines(["*::test_pinned: @example here is Hypothesis's*"
                                 "from pytest_avscenario import example*"])
    assert result.ret == pytest.ExitCode.INTERRUPTED


def test_a_counterexample_says_it_in_at_most_twenty_lines_by_default(pytester):
    # eight metrics (five violated), nine parameters, minimized: the compact text still fits
    pytester.makepyfile(test_many="""
from pytest_avscenario import scenario, Uniform
from pytest_avscenario.monitors import distance
from pytest_avscenario.trajectory import Trajectory

@scenario(samples=1, shrink_budget=5, monitors=[distance(d, kind="centre", name=f"d{d}") for d in range(1, 9)],
          **{f"p{i}": Uniform(0, 1, nominal=0.5) for i in range(9)})
def test_many(case):
    return Trajectory.from_arrays([0.0, 0.1], {"ego": {"x": [0.0, 0.0], "y": [0.0, 0.0]},
                                               "other": {"x": [4.0, 4.0], "y": [3.0, 3.0]}})
""")
    result = pytester.runpytest("--avs-db=none", "--avs-seed=1")
    text = result.stdout.str()
    section = text[text.index("_ test_many[halton-000] _"):text.index("= avscenario =")]
    lines = [l for l in section.strip().splitlines()[1:] if not l.startswith("=")]
    assert 5 < len(lines) <= 20, section
    assert sum(l.strip().startswith("d") and "rho" in l for l in lines) == 3  # d6, d7, d8 violated
    assert any("pin it as a regression" in l for l in lines)
    assert lines[-1].strip().startswith("re-run only this case: pytest ")
    verbose = pytester.runpytest("--avs-db=none", "--avs-seed=1", "-v").stdout.str()
    assert "parameter          found      minimized        nominal" in verbose

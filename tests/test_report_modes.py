"""Failure modes: a campaign's counterexamples grouped by metric and agent and described by
rules over the parameters, in the parameters' own units."""

import re

import numpy as np
import pytest

from pytest_avscenario.outcome import CaseRow
from pytest_avscenario.report.modes import failure_modes
from pytest_avscenario.space import Choice, FeatureSpace, IntRange, Uniform

TEST = "tests/test_follow.py::test_follow"


def space():
    return FeatureSpace({"gap": Uniform(5.0, 40.0, unit="m"), "lead_decel": Uniform(1.0, 8.0, unit="m/s^2"),
                         "speed": Uniform(5.0, 30.0, unit="m/s"), "road": Choice(["dry", "wet", "icy"]),
                         "lanes": IntRange(1, 4)})


def campaign(n=300, seed=0, fails=None):
    """Two known failure regions with the lead car as the critical agent: distance is violated
    when gap < 14 m and lead_decel > 5 m/s²; ttc when speed > 24 m/s on a wet or icy road."""
    fails = fails or {
        "distance": lambda p: p["gap"] < 14.0 and p["lead_decel"] > 5.0,
        "ttc": lambda p: p["speed"] > 24.0 and p["road"] != "dry",
    }
    sp = space()
    rng = np.random.default_rng(seed)
    rows = []
    for i in range(n):
        p = sp.from_unit(rng.random(sp.d))
        rho = {m: (-1.0 if f(p) else 1.0) for m, f in fails.items()}
        violated = {m: {"t": 2.0, "agent": "lead", "threshold": 5.0} for m, v in rho.items() if v < 0}
        rows.append(CaseRow(test=TEST, item=f"{TEST}[halton-{i:03d}]", sampler="halton", index=i, seed=i,
                            origin="sampled", params=p, rho=rho, verdict="fail" if violated else "pass",
                            violations=violated or None))
    return rows


def test_two_failure_regions_are_recovered_with_their_bounds():
    rows = campaign()
    modes = failure_modes(rows, space(), ["distance", "ttc"])
    # the few cases in both regions stay with their first metric: two modes, not three
    assert [m.metrics for m in modes] == [("ttc",), ("distance",)]
    ttc, dist = modes
    assert dist.also == {"ttc": sum(1 for r in rows if r.rho["distance"] < 0 and r.rho["ttc"] < 0)} != {}
    # the rules name exactly the parameters that matter, on the right side, near the truth
    (gap, decel) = dist.bounds
    assert (gap.parameter, gap.lo, decel.parameter, decel.hi) == ("gap", None, "lead_decel", None)
    assert gap.hi == pytest.approx(14.0, abs=1.5) and decel.lo == pytest.approx(5.0, abs=0.6)
    (speed, road) = ttc.bounds
    assert speed.parameter == "speed" and speed.hi is None and speed.lo == pytest.approx(24.0, abs=1.5)
    assert road.values == ("wet", "icy")
    for mode in (ttc, dist):
        assert mode.agent == "lead" and mode.recall == 1.0 and mode.precision > 0.9
        assert mode.representative in mode.items
    # every counterexample belongs to exactly one mode; ids by decreasing count
    failing = {r.item for r in rows if r.verdict == "fail"}
    assert sorted(i for m in modes for i in m.items) == sorted(failing)
    assert [m.id for m in modes] == [f"M{k}" for k in range(1, len(modes) + 1)]
    assert [m.count for m in modes] == sorted((m.count for m in modes), reverse=True)
    assert sum(m.share for m in modes) == pytest.approx(1.0)


def test_rules_read_as_parameter_bounds_with_units():
    modes = failure_modes(campaign(), space(), ["distance", "ttc"])
    rules = {m.metrics: m.rule for m in modes}
    assert re.fullmatch(r"gap < [\d.]+ m and lead_decel > [\d.]+ m/s²", rules[("distance",)])
    assert re.fullmatch(r"speed > [\d.]+ m/s and road in \{wet, icy\}", rules[("ttc",)])
    assert modes[0].to_json()["rule"] == modes[0].rule and "items" not in modes[0].to_json()


def test_the_same_kind_of_failure_keeps_its_key_between_runs():
    first = {m.key for m in failure_modes(campaign(seed=0), space(), ["distance", "ttc"])}
    again = {m.key for m in failure_modes(campaign(seed=5), space(), ["distance", "ttc"])}
    assert "distance|lead|gap<,lead_decel>" in first & again
    assert "ttc|lead|speed>,road in" not in first  # the key has no spaces or values
    assert "ttc|lead|speed>,roadin" in first & again


def test_modes_are_deterministic_and_independent_of_row_order():
    rows = campaign()
    a = failure_modes(rows, space(), ["distance", "ttc"])
    b = failure_modes(list(reversed(rows)), space(), ["distance", "ttc"])
    assert a == b  # the same modes, representatives and item lists


def test_a_small_group_is_one_mode_with_its_bounding_box():
    sp = space()
    rows = campaign(n=60, fails={"distance": lambda p: False})
    bad = [dict(sp.from_unit([0.05, 0.5, 0.5, 0.5, 0.5]), gap=7.0 + k, lanes=2) for k in range(3)]
    rows += [CaseRow(test=TEST, item=f"{TEST}[replay-{k}]", sampler="halton", index=k, seed=k, origin="replay",
                     params=p, rho={"distance": -0.5}, verdict="fail") for k, p in enumerate(bad)]
    (mode,) = failure_modes(rows, sp, ["distance"])
    assert mode.kind == "box" and mode.count == 3 and mode.agent is None
    assert mode.key == "distance|-|box"  # not its cases' bounds: the same few failures match between runs
    assert "7 ≤ gap ≤ 9 m" in mode.rule and "lanes = 2" in mode.rule
    assert mode.representative == f"{TEST}[replay-1]"  # the middle one
    (one,) = failure_modes(rows[:-2], sp, ["distance"])  # a single case: its values, not a box
    assert "gap = 7 m" in one.rule and "≤" not in one.rule


def test_at_most_five_modes_and_none_without_counterexamples():
    rows = campaign()
    assert failure_modes([r for r in rows if r.verdict == "pass"], space(), ["distance"]) == []
    many = {f"m{k}": (lambda k: lambda p: abs(p["gap"] - (6 + 4.5 * k)) < 1.0)(k) for k in range(7)}
    modes = failure_modes(campaign(fails=many), space(), list(many))
    assert len(modes) == 5


# --------------------------------------------------------------------------- through pytest

# The lead car stands `gap` + 0.5 m ahead, a second car `offset` m to the side: with a 4-m
# distance threshold only the lead comes too close (gap < 3.5 m); with 8 m the side car does
# too (offset < 8 m), a second failure mode.
SCENARIO = """
import os
from pytest_avscenario import scenario, Uniform
from pytest_avscenario.monitors import distance
from pytest_avscenario.trajectory import Trajectory

LIMIT = float(os.environ.get("AVS_TEST_LIMIT", "4"))

@scenario(gap=Uniform(0, 20, unit="m"), offset=Uniform(6, 20, unit="m"), samples=40, sampler="halton",
          monitors=[distance(LIMIT, kind="centre")])
def test_pair(case):
    return Trajectory.from_arrays([0.0, 0.1], {
        "ego": {"x": [0.0, 0.0], "y": [0.0, 0.0]},
        "lead": {"x": [case.gap + 0.5, case.gap + 0.5], "y": [0.0, 0.0]},
        "side": {"x": [0.0, 0.0], "y": [case.offset, case.offset]},
    })
"""
RUN = ("--avs-db=none", "--avs-seed=1", "--avs-shrink-budget=0", "--avs-case-pictures=0", "-p", "no:cacheprovider")


def test_modes_and_the_comparison_with_a_baseline_run_reach_the_terminal_summary_json_and_index(
        pytester, monkeypatch):
    import json

    pytester.makepyfile(test_pair=SCENARIO)
    monkeypatch.setenv("AVS_TEST_LIMIT", "4")
    before = pytester.runpytest(*RUN, "--avs-report=before")
    monkeypatch.setenv("AVS_TEST_LIMIT", "8")
    after = pytester.runpytest(*RUN, "--avs-report=after", "--avs-baseline=before/summary.json")
    new = json.loads((pytester.path / "after" / "summary.json").read_text())

    # the modes: counted in the terminal table, described in summary.json
    before.stdout.fnmatch_lines(["test *cex  min  modes*", "test_pair  halton *8    0      1*",
                                 "*modes: failure modes*"])
    after.stdout.fnmatch_lines(["test_pair  halton *19    0      2*"])
    (lead, side) = new["tests"][0]["modes"]
    assert (lead["id"], lead["agent"], lead["key"]) == ("M1", "lead", "distance|lead|gap<")
    assert (side["id"], side["agent"], side["key"]) == ("M2", "side", "distance|side|offset<")
    assert re.fullmatch(r"gap < 7\.\d+ m", lead["rule"]) and re.fullmatch(r"offset < [78]\.?\d* m", side["rule"])
    assert lead["count"] + side["count"] == new["tests"][0]["counterexamples"] == 19
    assert "items" not in lead and lead["representative"]["item"].startswith("test_pair.py::test_pair[halton-")

    # the index: a table of modes, each representative linked to its card; a mode column
    index = (pytester.path / "after" / "index.html").read_text()
    assert "2 failure modes" in index and "<code>gap &lt; 7." in index
    card = re.search(r"<tr id='m-[^']+-halton-M1'>.*?<a href='(cases/[^']+)'>", index).group(1)
    assert "failure mode M1 (distance with lead: gap &lt; 7." in (pytester.path / "after" / card).read_text()
    assert "<th>mode</th>" in index and "<td>M2</td>" in index

    # the comparison with the baseline: in the terminal, summary.json and atop the index
    after.stdout.fnmatch_lines([
        "this run compared with *before*summary.json:",
        "  test_pair  halton   distance  19/40 (47.5%)  8/40 (20.0%)  ↑ +27.5 pts",
        "  new mode test_pair [[]halton] M2: distance with side, offset < * m (4 cases)",
    ])
    cmp = new["comparison"]
    assert cmp["rates"] == [{"test": "test_pair.py::test_pair", "sampler": "halton", "metric": "distance",
                             "now": {"violations": 19, "samples": 40}, "before": {"violations": 8, "samples": 40},
                             "rate_now": 0.475, "rate_before": 0.2}]
    assert [(m["status"], m["key"]) for m in cmp["modes"]] == [("kept", "distance|lead|gap<"),
                                                               ("new", "distance|side|offset<")]
    assert index.index("Compared with an earlier run") < index.index("<table id='summary'>")
    assert "↑ +27.5 pts" in index
    assert re.search(r"<td class='bad'>new</td>.*<a href='#m-[^']+-halton-M2'>M2</a>", index)

    # the command on two finished runs, the other way round: the side car's mode is gone
    import subprocess
    import sys

    done = subprocess.run([sys.executable, "-m", "pytest_avscenario.report", "compare", "after", "before/summary.json",
                           "--html", "cmp/page.html"], cwd=pytester.path, capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    lines = done.stdout.splitlines()
    assert lines[0] == "before/summary.json compared with after/summary.json:"
    assert "  test_pair  halton   distance  8/40 (20.0%)  19/40 (47.5%)  ↓ -27.5 pts" in lines
    assert any(l.startswith("  gone mode test_pair [halton] (was M2): distance with side, offset < ") for l in lines)
    page = (pytester.path / "cmp" / "page.html").read_text()
    assert "<td class='good'>gone</td>" in page and "was M2" in page
    missing = subprocess.run([sys.executable, "-m", "pytest_avscenario.report", "compare", "nowhere", "before"],
                             cwd=pytester.path, capture_output=True, text=True)
    assert missing.returncode == 2 and "cannot read nowhere" in missing.stderr
    blocked = subprocess.run([sys.executable, "-m", "pytest_avscenario.report", "compare", "after", "before",
                              "--html", "cmp"], cwd=pytester.path, capture_output=True, text=True)
    assert blocked.returncode == 2 and "error: cannot write --html cmp" in blocked.stderr
    assert "Traceback" not in blocked.stderr


def test_overlapping_failures_go_to_the_metric_first_in_priority():
    rows = campaign()
    both = sum(1 for r in rows if r.rho["distance"] < 0 and r.rho["ttc"] < 0)
    by_order = {}
    for order in (["distance", "ttc"], ["ttc", "distance"]):
        modes = {m.metrics[0]: m for m in failure_modes(rows, space(), order)}
        by_order[order[0]] = modes
    assert by_order["distance"]["distance"].also == {"ttc": both}
    assert by_order["ttc"]["ttc"].also == {"distance": both}
    assert by_order["ttc"]["ttc"].count == by_order["distance"]["ttc"].count + both


def test_a_baseline_without_modes_compares_rates_and_says_the_modes_are_unknown(tmp_path):
    import json

    from pytest_avscenario.acceptance import load_baseline
    from pytest_avscenario.report.compare import compare, format_comparison
    from pytest_avscenario.report.summary import TestInfo, summarize

    rows = campaign(n=60)
    (now,) = summarize(rows, {TEST: TestInfo(("distance", "ttc"), space(), ("halton",))}, cross_check=False)
    old = tmp_path / "summary.json"  # as a run before failure modes existed wrote it
    old.write_text(json.dumps({"tests": [{"test": TEST, "sampler": "halton", "samples": 50,
                                          "violations": {"distance": 1, "ttc": 0}}]}))
    lines = format_comparison(compare([now], load_baseline(old)))
    k = now.violations["distance"]
    (line,) = [l for l in lines if " distance " in l]
    assert line.split() == ["test_follow", "halton", "distance", f"{k}/60", f"({100 * k / 60:.1f}%)", "1/50",
                            "(2.0%)", "↑", f"+{100 * (k / 60 - 0.02):.1f}", "pts"]
    assert lines[-1] == "  test_follow [halton]: failure modes not recorded in one of the runs"

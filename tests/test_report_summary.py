"""The paper's table: counts per test and sampler, ε, the terminal text, suite properties."""

import math

import numpy as np
import pytest

from pytest_avscenario.report.coverage import epsilon_coverage
from pytest_avscenario.report.summary import (
    TestInfo,
    format_pointer,
    format_table,
    suite_properties,
    summarize,
    summary_to_json,
)
from pytest_avscenario.space import Choice, FeatureSpace, Uniform

FOLLOW = "tests/test_follow.py::test_vehicle_following"
PARK = "tests/test_park.py::test_parallel_park"
METRICS = ("progress", "distance", "ttc", "lane")


def follow_space():
    return FeatureSpace({"gap": Uniform(10.0, 40.0), "speed": Uniform(5.0, 15.0), "weather": Choice(["dry", "wet"])})


def row(test, sampler, i, rho, origin="sampled", verdict=None, sim=0.5, item=None, **params):
    if verdict is None:
        verdict = "fail" if any(v < 0 for v in rho.values()) else "pass"
    return {
        "test": test, "item": item or f"{test}[{sampler}-{i}]", "sampler": sampler, "index": i,
        "seed": 1, "origin": origin, "params": params, "rho": rho, "verdict": verdict,
        "sim_time_s": sim, "error": None,
    }


@pytest.fixture
def rows():
    rng = np.random.default_rng(0)
    out = []
    # halton on vehicle following: 6 samples; case 1 violates distance and ttc, case 4 lane.
    for i in range(6):
        rho = {"progress": 3.0, "distance": 1.0, "ttc": math.inf, "lane": 0.2}
        if i == 1:
            rho.update(distance=-0.5, ttc=-1.0)
        if i == 4:
            rho.update(lane=-0.1)
        g, s = rng.uniform(10, 40), rng.uniform(5, 15)
        out.append(row(FOLLOW, "halton", i, rho, gap=g, speed=s, weather="dry"))
    # an @example that fails must not count as a sample, but is a counterexample
    out.append(row(FOLLOW, "halton", 6, {"progress": -2.0, "distance": 1.0, "ttc": 1.0, "lane": 0.1},
                   origin="example", gap=10.0, speed=5.0, weather="wet"))
    # shrinking of case 1: two candidates, one still failing
    for j, d in enumerate((0.3, -0.1)):
        out.append(row(FOLLOW, "halton", j, {"progress": 3.0, "distance": d, "ttc": 1.0, "lane": 0.2},
                       origin="shrink", item=f"{FOLLOW}[halton-1]", sim=0.25, gap=30.0, speed=10.0, weather="dry"))
    # the bandit on the same test: 3 samples, one distance violation, never shrunk
    for i in range(3):
        d = -1.0 if i == 2 else 2.0
        out.append(row(FOLLOW, "mab", i, {"progress": 3.0, "distance": d, "ttc": 5.0, "lane": 0.3},
                       gap=12.0 + i, speed=6.0, weather="dry"))
    # parking: no continuous parameters, only two metrics
    for i in range(2):
        out.append(row(PARK, "random", i, {"distance": 0.5 - i, "collision": 1.0}, side="left"))
    return out


@pytest.fixture
def tests_info():
    return {
        FOLLOW: TestInfo(metrics=METRICS, space=follow_space()),
        PARK: TestInfo(metrics=("distance", "collision"), space=FeatureSpace({"side": Choice(["left", "right"])})),
    }


def test_counts_follow_the_papers_rules(rows, tests_info):
    summary = summarize(rows, tests_info)
    assert [(s.test, s.sampler) for s in summary] == [(FOLLOW, "halton"), (FOLLOW, "mab"), (PARK, "random")]
    halton, mab, park = summary
    assert halton.samples == 6  # the example and the shrink candidates are not samples
    assert halton.violations == {"progress": 0, "distance": 1, "ttc": 1, "lane": 1}
    assert halton.counterexamples == 3  # cases 1 and 4 and the failing example
    assert halton.minimized == 1 and halton.shrink_sims == 2
    assert halton.sim_time_s == pytest.approx(7 * 0.5 + 2 * 0.25)
    assert mab.violations["distance"] == 1 and mab.minimized == 0
    assert park.metrics == ("distance", "collision") and park.violations == {"distance": 1, "collision": 0}


def test_epsilon_is_the_coverage_of_the_sampled_continuous_parameters(rows, tests_info):
    halton = summarize(rows, tests_info)[0]
    space = follow_space()
    pts = np.array([space.to_unit(r["params"])[:2] for r in rows
                    if r["sampler"] == "halton" and r["origin"] == "sampled"])
    assert halton.continuous == ("gap", "speed")
    assert halton.epsilon == epsilon_coverage(pts)
    assert halton.covering_radius is not None and 0 < halton.fraction_within < 1
    park = summarize(rows, tests_info)[2]
    assert park.epsilon is None and park.covering_radius is None


def test_terminal_table_text(rows, tests_info):
    text = format_table(summarize(rows, tests_info))
    lines = text.splitlines()
    header = lines[0].split()
    # The paper's metric order (as declared), then the extra metric of the second test.
    assert header == ["test", "sampler", "samples", "Progress", "Distance", "TTC", "Lane",
                      "Collision", "ε", "cex", "min", "modes", "sim", "s"]
    assert set(lines[1]) == {"-", " "}
    assert lines[-1].startswith("ε: coverage")  # the legend
    halton, mab, park = (line.split() for line in lines[2:-1])
    assert halton == [FOLLOW.rpartition("::")[2], "halton", "6", "0", "1", "1", "1", "—", halton[8], "3", "1", "3", "4.0"]
    assert float(halton[8]) == pytest.approx(summarize(rows, tests_info)[0].epsilon, abs=5e-4)
    # A metric a test does not declare, and ε without continuous parameters, are "—".
    assert park == [PARK.rpartition("::")[2], "random", "2", "—", "1", "—", "—", "0", "—", "1", "0", "1", "1.0"]
    # Columns line up: every numeric column ends at the same offset on every line.
    eps_end = lines[0].index("ε") + 1
    assert all(line[eps_end - 1] != " " for line in lines[2:-1])


def test_errors_column_appears_only_when_a_case_errored(rows, tests_info):
    assert "errors" not in format_table(summarize(rows, tests_info))
    rows.append(row(PARK, "random", 9, {}, verdict="error"))
    summary = summarize(rows, tests_info)
    assert summary[2].errors == 1 and summary[2].samples == 3
    assert "errors" in format_table(summary).splitlines()[0]


def test_undeclared_tests_and_metrics_still_show(rows):
    summary = summarize(rows)  # no declarations at all: no ε, metrics in order seen
    assert summary[0].metrics == METRICS and summary[0].epsilon is None
    assert format_table([]) == ""


def test_suite_properties(rows, tests_info):
    props = suite_properties(summarize(rows, tests_info), seed=42,
                             versions={"pytest-avscenario": "0.1.0", "highway-env": "1.12.1"})
    assert list(props)[:3] == ["avs.seed", "avs.version.pytest-avscenario", "avs.version.highway-env"]
    key = f"avs.test[{FOLLOW}][halton]"
    assert props[f"{key}.samples"] == "6"
    assert props[f"{key}.violations.distance"] == "1"
    assert props[f"{key}.modes"] == "3"  # distance, lane and the @example's progress
    assert float(props[f"{key}.epsilon"]) > 0
    assert props[f"avs.test[{PARK}][random].epsilon"] == "—"
    assert all(isinstance(v, str) for v in props.values())


def test_summary_json_and_pointer(rows, tests_info, tmp_path):
    import json

    data = summary_to_json(summarize(rows, tests_info))
    json.dumps(data, allow_nan=False)
    assert data[0]["violations"]["ttc"] == 1 and data[2]["epsilon"] is None
    assert format_pointer(tmp_path).startswith("avscenario report: ")
    assert str(tmp_path / "index.html") in format_pointer(tmp_path)


def test_rows_in_json_form_count_the_same(rows, tests_info):
    from pytest_avscenario.outcome import CaseRow

    json_rows = [CaseRow.from_json(r).to_json() for r in rows]
    assert summarize(json_rows, tests_info) == summarize(rows, tests_info)


def test_terminal_table_fits_the_terminal_width(rows, tests_info):
    summary = summarize(rows, tests_info)
    wide = format_table(summary, width=400)
    narrow = format_table(summary, width=80)
    assert max(map(len, narrow.splitlines())) <= 80 < max(map(len, wide.splitlines()[:-1]))
    # two lines per campaign when narrow: the figures, then the violations per metric
    lines = narrow.splitlines()
    assert lines[3].strip() == "violations: Distance 1, TTC 1, Lane 1"  # the metrics violated
    legend = lines[2 + 2 * len(summary):]
    assert len(legend) >= 2 and " ".join(l.strip() for l in legend).startswith("ε: coverage")


def test_long_test_names_are_shortened_in_the_middle_to_fit_columns(rows, tests_info):
    from dataclasses import replace

    from pytest_avscenario.report.summary import ellipsize

    long = "test_" + "unprotected_left_turn_with_a_lateral_car_running_the_stop_" * 2 + "east"
    summary = [replace(s, test=f"example_tests/test_mod.py::{long}") if i == 0 else s
               for i, s in enumerate(summarize(rows, tests_info))]
    for columns in (120, 100, 80):
        text = format_table(summary, width=columns)
        assert max(map(len, text.splitlines())) <= columns, (columns, text)
        name_line = text.splitlines()[2]
        assert "…" in name_line and name_line.startswith("test_unprot") and "_east" in name_line
    # the legend wraps instead of running to 200+ characters
    assert all(len(l) <= 120 for l in format_table(summary, width=120).splitlines())
    assert ellipsize("abcdefghij", 5) == "ab…ij" and ellipsize("abc", 5) == "abc"


def test_short_names_stay_unique():
    from pytest_avscenario.report.summary import short_names

    assert short_names(["a/t1.py::test_x", "a/t2.py::test_y"]) == {
        "a/t1.py::test_x": "test_x", "a/t2.py::test_y": "test_y"}
    assert short_names(["a/t1.py::test_x", "b/t2.py::test_x"]) == {
        "a/t1.py::test_x": "t1.py::test_x", "b/t2.py::test_x": "t2.py::test_x"}
    assert short_names(["a/t.py::test_x", "b/t.py::test_x"]) == {
        "a/t.py::test_x": "a/t.py::test_x", "b/t.py::test_x": "b/t.py::test_x"}


def test_a_campaign_of_replays_counts_the_violations_of_its_cases(rows, tests_info):
    """Replays of stored failures are no samples, but their row must not say "violations:
    none" beside its counterexamples."""
    replays = [row(FOLLOW, "replay", i, {"progress": 3.0, "distance": -1.0, "ttc": -0.5 if i else 1.0,
                                         "lane": 0.2}, origin="replay", gap=20.0, speed=8.0, weather="dry")
               for i in range(3)]
    summary = summarize(rows + replays, tests_info)
    rep = next(s for s in summary if s.sampler == "replay")
    assert rep.samples == 0 and rep.counterexamples == 3
    assert rep.violations["distance"] == 0  # the paper's counts stay over sampled cases
    assert rep.case_violations["distance"] == 3 and rep.case_violations["ttc"] == 2
    narrow = format_table(summary, width=80).splitlines()
    i = next(k for k, l in enumerate(narrow) if " replay " in f" {l} ")
    assert narrow[i + 1].strip() == "violations: Distance 3, TTC 2 (among its 3 cases)"
    wide = next(l for l in format_table(summary, width=400).splitlines() if " replay " in l)
    assert wide.split()[:6] == ["test_vehicle_following", "replay", "0", "0", "3", "2"]

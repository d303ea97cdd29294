"""The plugin's spine, through pytest itself: marker, expansion, ids, seeds, options, verdicts."""

from __future__ import annotations

import json
import subprocess
import sys
import textwrap

import pytest

RECORDING_TEST = """
import json, os
from pytest_avscenario import scenario, Uniform, Choice, IntRange

@scenario(gap=Uniform(10.0, 40.0), road=Choice(["dry", "wet", "icy"]), lanes=IntRange(1, 3),
          samples=8, sampler="{sampler}")
def test_follow(case):
    with open(os.environ["AVS_RECORD"], "a") as f:
        f.write(json.dumps({{"id": case.test, "params": case.params, "seed": case.seed,
                            "draw": float(case.rng.random())}}) + "\\n")
"""


def _record(pytester, monkeypatch, *args, sampler="halton"):
    path = pytester.path / f"record-{len(list(pytester.path.glob('record-*')))}.jsonl"
    monkeypatch.setenv("AVS_RECORD", str(path))
    pytester.makepyfile(test_rec=RECORDING_TEST.format(sampler=sampler))
    result = pytester.runpytest("-p", "no:cacheprovider", *args)
    rows = [json.loads(line) for line in path.read_text().splitlines()] if path.exists() else []
    return result, rows


def test_scenario_expands_into_items_with_readable_ids(pytester):
    pytester.makepyfile(
        """
        from pytest_avscenario import scenario, Uniform
        @scenario(gap=Uniform(10, 40), samples=12)
        def test_follow(case):
            assert 10 <= case.gap <= 40
        def test_plain():
            pass
        """
    )
    result = pytester.runpytest("-v", "-m", "scenario", "--avs-seed=1")
    result.stdout.fnmatch_lines(
        ["*test_follow[[]halton-000[]] PASSED*", "*test_follow[[]halton-011[]] PASSED*"]
    )
    result.assert_outcomes(passed=12, deselected=1)


def test_header_names_the_seed(pytester):
    pytester.makepyfile("def test_x(): pass")
    result = pytester.runpytest("--avs-seed=1234")
    result.stdout.fnmatch_lines(["avscenario: seed=1234 (replay with --avs-seed=1234)"])


def test_default_seed_is_fresh_and_last_replays_it(pytester):
    pytester.makepyfile("def test_x(): pass")
    first = pytester.runpytest()
    seed = [l for l in first.outlines if l.startswith("avscenario: seed=")][0].split("=")[1].split()[0]
    again = pytester.runpytest("--avs-seed=last")
    again.stdout.fnmatch_lines([f"avscenario: seed={seed} *"])


def test_marker_is_registered_and_documented(pytester):
    pytester.makepyfile(
        """
        from pytest_avscenario import scenario, Uniform
        @scenario(gap=Uniform(10, 40), samples=2)
        def test_follow(case):
            pass
        """
    )
    pytester.runpytest("--strict-markers").assert_outcomes(passed=2)
    pytester.runpytest("--markers").stdout.fnmatch_lines(["@pytest.mark.scenario(*"])


def test_plugin_can_be_disabled(pytester):
    pytester.makepyfile("def test_x(): pass")
    result = pytester.runpytest("-p", "no:avscenario")
    assert not any("avscenario: seed" in l for l in result.outlines)
    result.assert_outcomes(passed=1)


def test_same_seed_same_cases_other_seed_other_cases(pytester, monkeypatch):
    _, a = _record(pytester, monkeypatch, "--avs-seed=7")
    _, b = _record(pytester, monkeypatch, "--avs-seed=7")
    _, c = _record(pytester, monkeypatch, "--avs-seed=8")
    assert len(a) == 8
    assert a == b
    # unscrambled Halton points do not depend on the seed; case seeds and rng draws do
    assert [r["params"] for r in a] == [r["params"] for r in c]
    assert [r["seed"] for r in a] != [r["seed"] for r in c]
    assert [r["draw"] for r in a] != [r["draw"] for r in c]


def test_random_sampler_depends_on_seed_only(pytester, monkeypatch):
    _, a = _record(pytester, monkeypatch, "--avs-seed=7", sampler="random")
    _, b = _record(pytester, monkeypatch, "--avs-seed=7", sampler="random")
    _, c = _record(pytester, monkeypatch, "--avs-seed=8", sampler="random")
    assert [r["params"] for r in a] == [r["params"] for r in b]
    assert [r["params"] for r in a] != [r["params"] for r in c]


def test_selecting_one_case_gives_the_same_values(pytester, monkeypatch):
    _, everything = _record(pytester, monkeypatch, "--avs-seed=7")
    _, one = _record(pytester, monkeypatch, "--avs-seed=7", "-k", "halton-005")
    assert one == [everything[5]]


def test_categorical_and_integer_take_their_share_of_the_halton_point(pytester, monkeypatch):
    _, rows = _record(pytester, monkeypatch, "--avs-seed=7", "--avs-samples=30")
    roads = [r["params"]["road"] for r in rows]
    lanes = [r["params"]["lanes"] for r in rows]
    # stratified: every value appears, in near-equal shares (30 points over 3 values)
    assert {roads.count(v) for v in ("dry", "wet", "icy")} <= {9, 10, 11}
    assert {lanes.count(v) for v in (1, 2, 3)} <= {9, 10, 11}


def test_override_options_samples_and_sampler(pytester, monkeypatch):
    result, rows = _record(pytester, monkeypatch, "--avs-seed=7", "--avs-samples=3",
                           "--avs-sampler=random")
    result.assert_outcomes(passed=3)
    assert all("[random-" in r["id"] for r in rows)


def test_ini_is_a_default_the_marker_beats(pytester):
    pytester.makeini("[pytest]\navs_samples = 4\navs_sampler = random\n")
    pytester.makepyfile(
        """
        from pytest_avscenario import scenario, Uniform
        @scenario(gap=Uniform(10, 40))
        def test_ini(case):
            pass
        @scenario(gap=Uniform(10, 40), samples=2, sampler="halton")
        def test_marker(case):
            pass
        """
    )
    result = pytester.runpytest("-v")
    result.stdout.fnmatch_lines(["*test_ini[[]random-003[]]*", "*test_marker[[]halton-001[]]*"])
    result.assert_outcomes(passed=6)


def test_two_samplers_on_one_test(pytester):
    pytester.makepyfile(
        """
        from pytest_avscenario import scenario, Uniform
        @scenario(gap=Uniform(10, 40), samples=2, sampler=["halton", "random"])
        def test_follow(case):
            assert case.sampler in ("halton", "random")
        """
    )
    result = pytester.runpytest("-v")
    result.stdout.fnmatch_lines(["*[[]halton-000[]]*", "*[[]halton-001[]]*", "*[[]random-000[]]*", "*[[]random-001[]]*"])


def test_case_gives_attribute_and_mapping_access(pytester):
    pytester.makepyfile(
        """
        import numpy as np
        from pytest_avscenario import scenario, Uniform, Constant
        @scenario(gap=Uniform(10, 40), lanes=Constant(2), weather="dry", samples=1)
        def test_follow(case):
            assert case.gap == case["gap"]
            assert case.lanes == 2 and case.weather == "dry"
            assert case.index == 0 and case.sampler == "halton" and case.origin == "sampled"
            assert isinstance(case.rng, np.random.Generator)
            assert dict(case) == {"gap": case.gap, "lanes": 2, "weather": "dry"}
        """
    )
    pytester.runpytest().assert_outcomes(passed=1)


def test_failure_message_lists_parameters_and_rerun_command(pytester):
    pytester.makepyfile(
        """
        from pytest_avscenario import scenario, Uniform
        @scenario(gap=Uniform(10, 40), samples=4)
        def test_follow(case):
            assert case.gap < 30, "lead too far"
        """
    )
    result = pytester.runpytest("--avs-seed=5", "--avs-shrink-budget=0")
    result.assert_outcomes(passed=3, failed=1)
    result.stdout.fnmatch_lines([
        "*parameters: gap=32.5*",
        "*re-run only this case: pytest 'test_failure_message_lists_parameters_and_rerun_command.py::test_follow[[]halton-002[]]' --avs-seed=5*",
    ])


def test_the_printed_rerun_command_reruns_that_case(pytester):
    pytester.makepyfile(
        """
        from pytest_avscenario import scenario, Uniform
        @scenario(gap=Uniform(10, 40), samples=6, sampler="random")
        def test_follow(case):
            assert case.gap < 20
        """
    )
    result = pytester.runpytest("--avs-seed=11", "--avs-shrink-budget=0", "--avs-db=none")
    line = [l for l in result.outlines if "re-run only this case:" in l][0]
    cmd = line.split("re-run only this case: pytest ", 1)[1]
    import shlex
    again = pytester.runpytest(*shlex.split(cmd), "--avs-shrink-budget=0", "--avs-db=none")
    again.assert_outcomes(failed=1)
    gap = [l for l in result.outlines if "parameters: gap=" in l][0]
    again.stdout.fnmatch_lines([f"*{gap.strip()}*"])


def test_avs_params_pins_values(pytester):
    pytester.makepyfile(
        """
        from pytest_avscenario import scenario, Uniform, Choice
        @scenario(gap=Uniform(10, 40), road=Choice(["dry", "wet"]), samples=3)
        def test_follow(case):
            assert case.gap == 12.5 and case.road == "dry" and case.origin == "pinned"
        """
    )
    pytester.runpytest('--avs-params={"gap": 12.5}').assert_outcomes(passed=3)


BAD_DECLARATIONS = [
    ("gap=Uniform(40, 10)", "case", "parameter 'gap': Uniform needs lo < hi"),
    ("gap=Uniform(0, float('inf'))", "case", "parameter 'gap': Uniform hi must be finite"),
    ("gap=Uniform(10, 40, nominal=50)", "case", "parameter 'gap': Uniform nominal=50 lies outside"),
    ("road=Choice([])", "case", "parameter 'road': Choice needs at least one option"),
    ("speed=Normal(10, -1, 0, 20)", "case", "parameter 'speed': Normal needs sd > 0"),
    ("lanes=IntRange(3, 1)", "case", "parameter 'lanes': IntRange needs lo < hi"),
    ("gap=Uniform(10, 40), sampler='sobolish'", "case", "unknown sampler 'sobolish'*available:*halton*"),
    ("gap=Uniform(10, 40), samples=0", "case", "samples must be >= 1, got 0*"),
    ("gap=Uniform(10, 40), samples=-3", "case", "samples must be >= 1, got -3*"),
    ("gap=Uniform(10, 40)", "", "a @scenario test must request the `case` fixture*"),
    ("tmp_path=Uniform(10, 40)", "case", "parameter 'tmp_path' clashes with the fixture 'tmp_path'*"),
    ("index=Uniform(10, 40)", "case", "parameter 'index' clashes with the case attribute*"),
    ("gap=object()", "case", "parameter 'gap':*neither a distribution*"),
    ("gap=Uniform", "case", "parameter 'gap': Uniform must be called with its arguments"),
    # arguments that used to raise at import, as the plugin's own traceback without the test
    ("gap=Uniform(2**2000, 1)", "case", "parameter 'gap': Uniform lo must be finite, got <an int of about 603 digits>"),
    ("gap=Distribution()", "case", "parameter 'gap': Distribution is the abstract base class; use one of Uniform*"),
    ("road=Choice(['a', 'b'], weights=5)", "case", "parameter 'road': Choice weights must be a list of numbers*"),
    ("gap=Uniform(10, 40), monitors=5", "case", "monitors must be a list of monitors, e.g. monitors=[[]distance(5.0)*got 5"),
    ("Uniform(10, 40), gap=Uniform(10, 40)", "case", "@scenario takes keyword arguments only*1 positional*"),
    # accepted, then broken later
    ("gap=Uniform(-1e308, 1e308)", "case", "parameter 'gap': Uniform [[]-1e+308, 1e+308[]] is wider than the largest float*"),
    ("lanes=IntRange(0, 2**60)", "case", "parameter 'lanes': IntRange hi must lie within ±2**53*use Uniform*"),
    ("road=Choice({'dry', 'wet'})", "case", "parameter 'road': Choice options must be a list, not a set*"),
    ("gap=Uniform(10, 40), case_timeout=1e20", "case", "case_timeout must be at most 86400 s (a day), got 1e+20*"),
    ("gap=Uniform(10, 40), sample=100", "case", "parameter 'sample'=100: did you mean samples=?*"),
    ("gap=Uniform(10, 40), sampler_options={'skip': 10**30}", "case",
     "sampler 'halton' could not draw 20 cases with sampler_options={'skip': 1000000000000000000000000000000}: OverflowError*"),
]


@pytest.mark.parametrize("decl, args, message", BAD_DECLARATIONS)
def test_bad_declarations_are_collection_errors_naming_test_and_parameter(pytester, decl, args, message):
    pytester.makepyfile(
        f"""
        from pytest_avscenario import scenario, Uniform, Choice, IntRange, Normal, Distribution
        @scenario({decl})
        def test_broken({args}):
            pass
        def test_fine():
            pass
        """
    )
    result = pytester.runpytest()
    assert result.ret == pytest.ExitCode.INTERRUPTED or result.ret != 0
    result.stdout.fnmatch_lines([f"*::test_broken: {message}*"])
    # a message, not a traceback from inside the plugin
    assert "pytest_avscenario/" not in result.stdout.str()
    assert "Traceback" not in result.stdout.str()


def test_bare_mark_is_rejected_with_advice(pytester):
    pytester.makepyfile(
        """
        import pytest
        @pytest.mark.scenario(gap=1)
        def test_bare(case):
            pass
        """
    )
    result = pytester.runpytest()
    result.stdout.fnmatch_lines(["*test_bare: use the @scenario(...) decorator*"])


def test_case_fixture_outside_a_scenario_is_an_error(pytester):
    pytester.makepyfile("def test_x(case): pass")
    result = pytester.runpytest()
    result.assert_outcomes(errors=1)
    result.stdout.fnmatch_lines(["*only available to tests decorated with @scenario*"])


def test_plugin_load_imports_nothing_heavy(pytester):
    pytester.makepyfile(
        """
        import sys
        def test_plain():
            heavy = [m for m in ("highway_env", "pygame", "matplotlib", "pandas", "scipy")
                     if m in sys.modules]
            assert heavy == []
        """
    )
    # a real process: the in-process pytester shares this interpreter's modules
    result = pytester.runpytest_subprocess("-p", "avscenario")
    result.assert_outcomes(passed=1)


def test_plugin_is_registered_through_the_entry_point():
    out = subprocess.run(
        [sys.executable, "-c",
         "import importlib.metadata as m; print([e.value for e in m.entry_points(group='pytest11') if e.name == 'avscenario'])"],
        capture_output=True, text=True, check=True,
    ).stdout
    assert "pytest_avscenario.pytest_plugin.hooks" in out

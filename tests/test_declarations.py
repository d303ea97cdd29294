"""Declaring a scenario wrongly, as a user would: every mistake is an error naming the test and
saying what to do, never a vanished test, a silently dropped decorator, or the plugin's own
traceback."""

from __future__ import annotations

import json

import pytest


def _clean(result):
    out = result.stdout.str() + result.stderr.str()
    assert "INTERNALERROR" not in out
    assert "pytest_avscenario/" not in out, out  # no traceback through the plugin's files
    assert "Traceback" not in out, out
    return out


def test_bare_scenario_is_a_collection_error_not_a_vanished_test(pytester):
    pytester.makepyfile(test_bare="""
from pytest_avscenario import scenario

@scenario
def test_follow(case):
    pass
""")
    result = pytester.runpytest("--avs-db=none", "--avs-report=none")
    _clean(result)
    result.stdout.fnmatch_lines(["test_bare.py::test_follow: @scenario is written without "
                                 "parentheses*write @scenario(...) with the parameters*"])
    assert result.ret == pytest.ExitCode.INTERRUPTED


def test_bare_example_is_a_collection_error_not_a_vanished_test(pytester):
    pytester.makepyfile(test_pin="""
from pytest_avscenario import scenario, example, Uniform

@example
@scenario(gap=Uniform(10, 40), samples=2)
def test_follow(case):
    pass
""")
    result = pytester.runpytest("--avs-db=none", "--avs-report=none")
    _clean(result)
    result.stdout.fnmatch_lines(["test_pin.py::test_follow: @example #0: @example is written "
                                 "without parentheses*"])


def test_example_without_scenario_is_a_collection_error_not_a_silent_pass(pytester):
    pytester.makepyfile(test_lone="""
from pytest_avscenario import example

@example(gap=12.5)
def test_follow():
    pass
""")
    result = pytester.runpytest("--avs-db=none", "--avs-report=none")
    _clean(result)
    result.stdout.fnmatch_lines(["*test_lone.py::test_follow: @example pins a case of a @scenario "
                                 "test, but this test has no @scenario(...)*"])
    assert result.ret == pytest.ExitCode.INTERRUPTED


def test_stacked_scenarios_are_a_collection_error(pytester):
    # the upper declaration is even invalid: it used to be dropped without a word
    pytester.makepyfile(test_stack="""
from pytest_avscenario import scenario, Uniform

@scenario(gap=Uniform(40, 10))
@scenario(gap=Uniform(10, 40), samples=2)
def test_follow(case):
    pass
""")
    result = pytester.runpytest("--avs-db=none", "--avs-report=none")
    _clean(result)
    result.stdout.fnmatch_lines(["test_stack.py::test_follow: 2 @scenario declarations apply "
                                 "to this test*keep one*"])


@pytest.mark.parametrize("keyword, setting", [
    ("sample=100", "samples"),
    ("samplers='random'", "sampler"),
    ("case_time_out=5", "case_timeout"),
    ("seeds=3", "seed"),
    ("monitor='distance'", "monitors"),
    ("shrink_budjet=3", "shrink_budget"),
])
def test_a_plain_value_under_a_misspelt_setting_name_is_refused(pytester, keyword, setting):
    name, value = keyword.split("=")
    pytester.makepyfile(test_typo=f"""
from pytest_avscenario import scenario, Uniform

@scenario(gap=Uniform(10, 40), {keyword})
def test_follow(case):
    pass
""")
    result = pytester.runpytest("--avs-db=none", "--avs-report=none")
    _clean(result)
    result.stdout.fnmatch_lines([
        f"test_typo.py::test_follow: parameter '{name}'={value}: did you mean {setting}=?*"
        f"write {name}=Constant({value}) if it really is a constant parameter"])


def test_constants_that_only_look_like_settings_stay_parameters(pytester):
    # the rule's escape hatch (Constant), distributions, and ordinary names close to a short
    # setting (speed ~ seed, accel ~ accept) are parameters as before
    pytester.makepyfile(test_ok="""
from pytest_avscenario import scenario, Uniform, Constant

@scenario(gap=Uniform(10, 40), sample=Constant(100), samplers=Uniform(0, 1), speed=10,
          accel=2.5, simple=True, samples=3)
def test_follow(case):
    assert (case.sample, case.speed, case.accel, case.simple) == (100, 10, 2.5, True)
    assert 0 <= case.samplers <= 1
""")
    result = pytester.runpytest("--avs-db=none", "--avs-report=none")
    result.assert_outcomes(passed=3)


@pytest.mark.parametrize("names, message", [
    ("**{'__class__': 3}", "parameter '__class__': names of the form __name__ are Python's own*"),
    ("**{'a b': 3}", "parameter 'a b' is not a valid Python name*rename it*"),
    ("**{'class': 3}", "parameter 'class' is not a valid Python name*not a keyword*"),
    ("_abc_impl=3", "parameter '_abc_impl' clashes with the case attribute*"),
])
def test_parameter_names_case_cannot_read_are_refused(pytester, names, message):
    pytester.makepyfile(test_names=f"""
from pytest_avscenario import scenario, Uniform

@scenario(gap=Uniform(10, 40), {names})
def test_follow(case):
    pass
""")
    result = pytester.runpytest("--avs-db=none", "--avs-report=none")
    _clean(result)
    result.stdout.fnmatch_lines([f"test_names.py::test_follow: {message}"])


@pytest.mark.parametrize("decorator, message", [
    ("@scenario(gap=Uniform(10, 40), monitors=[ttc('x')])",
     "test_imp.py::test_follow: ttc: threshold must be a number, got 'x' (raised by its decorator "
     "at test_imp.py:4 while the module was imported, so none of the module's tests were collected)"),
    ("@scenario(gap=Uniform(10, 40), accept=rate('distance', 'often'))",
     "test_imp.py::test_follow: ValueError: *(raised by its decorator at test_imp.py:4*"),
    ("@scenario(gap=Uniform(10, 40), **{1: 2})",
     "test_imp.py::test_follow: TypeError: keywords must be strings (raised by its decorator*"),
])
def test_an_error_raised_while_the_decorator_runs_at_import_names_the_test(pytester, decorator, message):
    pytester.makepyfile(test_imp=f"""
from pytest_avscenario import scenario, Uniform
from pytest_avscenario.monitors import ttc
from pytest_avscenario.acceptance import rate
{decorator}
def test_follow(case):
    pass
""")
    result = pytester.runpytest("--avs-db=none", "--avs-report=none")
    _clean(result)
    result.stdout.fnmatch_lines([message])


def test_a_bad_monitor_built_at_module_level_names_the_line(pytester):
    pytester.makepyfile(test_mod="""
from pytest_avscenario.monitors import ttc
SAFE = ttc(2.0, kind="centre", radius=-1)
""")
    result = pytester.runpytest("--avs-db=none", "--avs-report=none")
    _clean(result)
    result.stdout.fnmatch_lines(["test_mod.py: ttc: radius must be > 0, got -1.0 (raised at "
                                 "test_mod.py:2 while the module was imported*"])


def test_numpy_values_are_plain_values_and_reach_the_case_as_python_values(pytester):
    pytester.makepyfile(test_np="""
import numpy
from pytest_avscenario import scenario, Choice, Constant, Uniform

@scenario(lanes=Choice([numpy.int64(1), 2]), wet=Choice([numpy.bool_(False), True]),
          mu=Constant(numpy.float64(0.7)), x=Uniform(0, 1, nominal=numpy.float64(0.25)), samples=4)
def test_follow(case):
    assert type(case.lanes) is int and type(case.wet) is bool and type(case.mu) is float
""")
    result = pytester.runpytest("--avs-db=none", "--avs-seed=1")
    result.assert_outcomes(passed=4)
    rows = [json.loads(line) for line in
            (pytester.path / "avs-report" / "errors.jsonl").read_text().splitlines()]
    assert {r["params"]["lanes"] for r in rows} == {1, 2}


def test_choice_weights_that_would_overflow_and_odd_option_counts_survive_the_report(pytester):
    # the report rebuilds each space from its description: weights of 1e308 once summed to
    # inf, and seven equal weights came back different from their own description
    pytester.makepyfile(test_w="""
from pytest_avscenario import scenario, Choice

@scenario(road=Choice(["dry", "wet"], weights=[1e308, 1e308]), lane=Choice(list(range(7))),
          samples=4)
def test_follow(case):
    pass
""")
    result = pytester.runpytest("--avs-db=none", "--avs-seed=1")
    result.assert_outcomes(passed=4)
    out = _clean(result)
    assert "SpaceError" not in out and "overflow encountered" not in out
    summary = json.loads((pytester.path / "avs-report" / "summary.json").read_text())
    assert "test_w.py::test_follow" in json.dumps(summary)


def test_choice_options_that_replay_differently_are_stored_as_they_replay(pytester):
    # a tuple option comes back from the database as a list: the case gets the list from the
    # start, and a stored counterexample is replayed instead of refused
    pytester.makepyfile(test_t="""
from pytest_avscenario import scenario, Choice

@scenario(size=Choice([(1, 2), (3, 4)]), samples=2)
def test_follow(case):
    assert case.size == [1, 2]
""")
    first = pytester.runpytest("--avs-seed=1", "--avs-report=none")
    first.assert_outcomes(passed=1, failed=1)
    again = pytester.runpytest("--avs-seed=1", "--avs-report=none", "-v")
    again.stdout.fnmatch_lines(["*test_follow[[]replay-0[]] FAILED*"])

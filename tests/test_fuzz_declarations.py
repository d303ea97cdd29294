"""Fuzzing ``@scenario`` declarations through pytest itself (slow set: ``-m slow``).

Hypothesis writes batches of test modules, one declaration each — valid and invalid
distributions with extreme or odd arguments, settings, misspelt settings, monitors, odd
parameter names, stacked or bare decorators — and runs each batch as one pytest session with
the replay database on. Whatever was declared, the run must show no INTERNALERROR and no
traceback through the plugin's own files; a declaration error is a collection error naming
the test; and every scenario item that ran has its row in ``errors.jsonl``. The last step runs
the last batch again, so stored counterexamples are replayed too.

The batches are the same on every run; ``FUZZ_RANDOM=1`` draws new ones, and
``FUZZ_DUMP=path`` appends each session's output to ``path``. The bodies build no world: they
return a small trajectory from arrays (so monitors judge it), fail an assertion, or raise,
depending on the case's values.
"""

from __future__ import annotations

import json
import os
import re
import time

import pytest
from hypothesis import HealthCheck, Phase, given, settings
from hypothesis import strategies as st

pytestmark = pytest.mark.slow

BATCHES = 20  # Hypothesis examples; each one a pytest session
PER_BATCH = 30  # declarations (test modules) per session

HEADER = """\
import numpy
from pytest_avscenario import (scenario, example, Uniform, Normal, IntRange, Choice, Constant,
                               Distribution)
from pytest_avscenario.monitors import distance, ttc, progress, collision, always, gap, ego_speed
from pytest_avscenario.acceptance import rate
from pytest_avscenario.trajectory import Trajectory
"""

BODY = """\
def {name}({args}):
    import zlib
    h = zlib.crc32(repr(sorted((k, repr(v)) for k, v in case.params.items())).encode()) % 1000 / 1000
    if h < 0.1:
        raise RuntimeError("the fuzz body raises")
    assert h < 0.8, "a counterexample: shrunk, stored in the database, replayed"
    t = numpy.arange(0.0, 2.0, 0.1)
    return Trajectory.from_arrays(t, agents={{
        "ego": {{"x": 10.0 * t, "y": 0 * t, "vx": 10.0, "vy": 0.0, "lane_offset": 0.1}},
        "lead": {{"x": 40.0 * h - 1.0 + 8.0 * t, "y": 0 * t, "vx": 8.0, "vy": 0.0}},
    }})
"""

# conftest of every session: each item's outcome, to compare with the rows of errors.jsonl
OUTCOMES = """
import json, os

def pytest_runtest_logreport(report):
    with open(os.environ["FUZZ_OUTCOMES"], "a") as f:
        f.write(json.dumps([report.nodeid, report.when, report.outcome,
                            bool(getattr(report, "wasxfail", None))]) + "\\n")
"""

# -------------------------------------------------------------------------- values as source
ODD = st.sampled_from([
    "0", "1", "-1", "2", "2.5", "-0.0", "1e308", "-1e308", "5e-324", "float('nan')",
    "float('inf')", "-float('inf')", "2**2000", "-2**64", "10**5000", "True", "False", "None",
    "'x'", "''", "'3'", "[]", "[1, 2]", "(1, 2)", "{1, 2}", "{'a': 1}", "numpy.int64(3)",
    "numpy.float64(2.5)", "numpy.bool_(True)", "numpy.array([1.0, 2.0])", "object()", "Uniform",
    "lambda: 0", "b'x'", "[float('nan')]", "{1: 'a'}",
])
FLOAT = st.floats(allow_nan=True, allow_infinity=True).map(
    lambda x: repr(x) if x == x and abs(x) != float("inf") else f"float('{x}')")
NUMBER = st.one_of(st.integers(-10**6, 10**6).map(str), FLOAT, ODD)
SMALL = st.floats(-1e3, 1e3, allow_nan=False)


@st.composite
def ordered(draw, integers=False):
    """Two numbers, usually lo < hi (so many declarations are valid), sometimes anything."""
    if draw(st.integers(0, 9)) == 0:
        return draw(NUMBER), draw(NUMBER)
    if integers:
        a, b = sorted(draw(st.lists(st.integers(-10**17, 10**17), min_size=2, max_size=2, unique=True)))
    else:
        a, b = sorted(draw(st.lists(st.one_of(SMALL, st.floats(allow_nan=False, allow_infinity=False)),
                                    min_size=2, max_size=2, unique=True)))
    return repr(a), repr(b)


OPTION = st.one_of(
    st.integers(-5, 5).map(repr), st.text("abcé ", max_size=3).map(repr), SMALL.map(repr),
    st.sampled_from(["True", "None", "(1, 2)", "[1, 2]", "[[1], {'k': 2}]", "numpy.int64(1)",
                     "numpy.float64(0.5)", "numpy.bool_(False)", "{'b': 1, 'a': 2}",
                     "{'a': 2, 'b': 1}", "float('nan')", "object()", "2**70", "10**5000"]),
)


@st.composite
def odd_distribution(draw):
    """Any distribution expression, mostly wrong: odd argument types and values."""
    kind = draw(st.sampled_from(["Uniform", "Normal", "IntRange", "Choice", "Constant", "plain",
                                 "odd"]))
    if kind == "Uniform":
        lo, hi = draw(ordered())
        nominal = draw(st.one_of(st.none(), NUMBER, st.just(f"({lo} + {hi}) / 2")))
        return f"Uniform({lo}, {hi}{'' if nominal is None else f', nominal={nominal}'})"
    if kind == "Normal":
        lo, hi = draw(ordered())
        mean = draw(st.one_of(NUMBER, st.just(f"({lo} + {hi}) / 2")))
        sd = draw(st.one_of(NUMBER, SMALL.map(lambda x: repr(abs(x) + 0.01))))
        return f"Normal({mean}, {sd}, {lo}, {hi})"
    if kind == "IntRange":
        lo, hi = draw(ordered(integers=True))
        nominal = draw(st.one_of(st.none(), NUMBER))
        return f"IntRange({lo}, {hi}{'' if nominal is None else f', nominal={nominal}'})"
    if kind == "Choice":
        options = draw(st.lists(OPTION, max_size=6))
        container = draw(st.sampled_from(["[{}]", "({},)", "{{{}}}", "numpy.array([{}])"]))
        text = container.format(", ".join(options)) if options or container == "[{}]" else "[]"
        weights = draw(st.one_of(
            st.none(), st.just("5"), st.just("'ab'"),
            st.lists(st.sampled_from(["1", "0", "-1", "1e308", "5e-324", "0.1", "2", "True",
                                      "float('inf')", "numpy.float64(0.3)", "2**2000"]),
                     min_size=len(options), max_size=len(options)).map(lambda w: f"[{', '.join(w)}]"),
            st.lists(SMALL.map(lambda x: repr(abs(x))), max_size=7).map(lambda w: f"[{', '.join(w)}]"),
        ))
        return f"Choice({text}{'' if weights is None else f', weights={weights}'})"
    if kind == "Constant":
        return f"Constant({draw(st.one_of(OPTION, ODD))})"
    if kind == "plain":
        return draw(st.one_of(OPTION, ODD))
    return draw(st.sampled_from([
        "Distribution()", "Uniform", "Uniform()", "Uniform(1)", "Uniform(0, 1, 2, 3)",
        "Uniform(2**2000, 1)", "Choice([1, 2], weights=5)", "Choice('abc')",
        "Choice([(1, 2), [1, 2]])", "IntRange(0, 2**60)", "IntRange(0.0, 3)",
        "Normal(0, 1e300, -1, 1)", "Uniform(-1e308, 1e308)", "Choice({1, 2})",
    ]))


@st.composite
def valid_distribution(draw):
    """A distribution that should be accepted, extreme values included."""
    kind = draw(st.sampled_from(["Uniform", "Normal", "IntRange", "Choice", "Constant", "plain",
                                 "extreme"]))
    if kind == "Uniform":
        lo, hi = sorted(draw(st.lists(SMALL, min_size=2, max_size=2, unique=True)))
        return f"Uniform({lo!r}, {hi!r})"
    if kind == "Normal":
        lo, hi = sorted(draw(st.lists(SMALL, min_size=2, max_size=2, unique=True)))
        return f"Normal({(lo + hi) / 2!r}, {(hi - lo) / 4 + 1e-3!r}, {lo!r}, {hi!r})"
    if kind == "IntRange":
        lo, hi = sorted(draw(st.lists(st.integers(-2**53, 2**53), min_size=2, max_size=2, unique=True)))
        return f"IntRange({lo}, {hi})"
    if kind == "Choice":
        options = draw(st.lists(st.one_of(st.integers(-5, 5), st.text("abcé ", max_size=3), st.none(),
                                          st.booleans(), SMALL), min_size=1, max_size=5,
                                unique_by=lambda o: (type(o), o)))
        weights = draw(st.one_of(st.none(), st.lists(
            st.sampled_from(["1", "0.1", "1e308", "3", "numpy.float64(0.3)", "5e-324"]),
            min_size=len(options), max_size=len(options))))
        text = "[" + ", ".join(map(repr, options)) + "]"
        weights = "" if weights is None else ", weights=[" + ", ".join(weights) + "]"
        return f"Choice({text}{weights})"
    if kind == "Constant":
        return f"Constant({draw(st.sampled_from(['1', '2.5', repr('wet'), '[1, 2]', 'None', 'numpy.int64(4)']))})"
    if kind == "plain":
        return draw(st.sampled_from(["3", "2.5", "'dry'", "True", "None", "(1, 2)", "numpy.float64(1.5)"]))
    return draw(st.sampled_from([
        "Uniform(-1e300, 1e300)", "Uniform(0, 5e-324)", "Uniform(1e308, 1.7e308)",
        "Choice([1, 2], weights=[1e308, 1e308])", "Choice([numpy.int64(1), 2])",
        "Choice([(1, 2), [3]])", "Choice(numpy.array([1, 2]))", "Choice([1, 1.0, True])",
        "Choice(list(range(49)))", "Choice(['a', 'b', 'c'], weights=[0.1, 0.1, 0.1])",
        "IntRange(-2**53, 2**53)", "Normal(0, 1e-300, -1, 1)", "Constant(numpy.bool_(True))",
        "Choice([{'b': 1, 'a': 2}, {'a': 1}])", "Uniform(0, 1, nominal=numpy.float64(0.25))",
    ]))


NAME = st.sampled_from(["gap", "speed", "accel", "x", "lane", "seed_offset", "road", "weather",
                        "λ", "simple"])
MISSPELT = st.sampled_from(["sample", "samplers", "case_time_out", "seeds", "monitor", "Samples",
                            "sampels", "acept", "shrinkbudget", "time_budgets", "sampler_option",
                            "prority", "shrink_maxs"])
BAD_NAME = st.sampled_from([
    "__class__", "__dict__", "__len__", "_abc_impl", "index", "rng", "params", "get", "tmp_path",
    "request", "case", "world", "**{'a b': X}", "**{'class': X}", "**{'': X}", "**{'1x': X}",
    "**{1: X}", "**{'x-y': X}"])

VALID_SETTINGS = {
    "sampler": st.sampled_from(["'halton'", "'random'", "['halton', 'random']", "'mab'", "'sa'",
                                "'ce'", "'bo'"]),
    "seed": st.sampled_from(["0", "7", "2**70"]),
    "monitors": st.sampled_from(["[distance(5.0)]", "[distance(5.0), ttc(2.0)]", "[collision()]",
                                 "[always(gap('lead') >= 5.0).named('gap5')]", "[lambda tr: 0.5]",
                                 "distance(2.0)"]),
    "shrink_budget": st.sampled_from(["0", "2"]),
    "shrink_max": st.sampled_from(["0", "1", "None"]),
    "time_budget": st.sampled_from(["'30m'", "60", "1e300"]),
    "case_timeout": st.sampled_from(["5", "'2m'", "86400"]),
    "accept": st.sampled_from(["'any'", "'regressions'"]),
}

# every value, good and bad, a setting may be given
SETTINGS = {
    "samples": st.one_of(st.sampled_from(["1", "2", "2", "2", "3"]),
                         st.sampled_from(["0", "-1", "10**12", "2.5", "'3'", "True", "None",
                                          "numpy.int64(2)", "10**5000", "'two'"])),
    "sampler": st.sampled_from(["'halton'", "'random'", "['halton', 'random']", "'mab'",
                                "'sa'", "'ce'", "'bo'", "'nope'", "5", "['halton', 'halton']",
                                "[]", "'halton,random'", "None"]),
    "seed": st.sampled_from(["0", "7", "2**70", "-1", "'x'", "True", "None", "1.5"]),
    "monitors": st.sampled_from([
        "[distance(5.0)]", "[distance(5.0), ttc(2.0)]", "[collision()]", "[progress(1.0)]",
        "5", "'distance'", "[distance]", "[distance(), distance()]", "distance(2.0)",
        "[lambda tr: 0.5]", "[lambda a, b: 0.0]", "[]", "None", "[always(gap('lead') >= 5.0)]",
        "[always(ego_speed() >= 0).named('moving')]", "{'a': distance()}", "[ttc('x')]",
        "[ttc(radius=-1)]", "[distance(float('nan'))]", "[progress(2**2000)]", "[object()]",
        "(distance(1.0) for _ in range(1))",
    ]),
    "priority": st.sampled_from(["['distance']", "['ttc', 'distance']", "[('ttc', 'distance')]",
                                 "['nope']", "'distance'", "5", "[]", "None",
                                 "[('distance', 'distance')]"]),
    "sampler_options": st.sampled_from(["{}", "{'scramble': True}", "{'foo': 1}", "{1: 2}",
                                        "5", "None", "{'skip': -1}", "{'scramble': 'x'}",
                                        "{'skip': 10**5000}"]),
    "shrink_budget": st.sampled_from(["0", "2", "-1", "2.5", "'x'", "10**30", "True"]),
    "shrink_max": st.sampled_from(["0", "1", "-1", "None", "'all'"]),
    "time_budget": st.sampled_from(["'30m'", "'90s'", "60", "1e300", "-1", "0", "'soon'",
                                    "float('inf')", "'1e-9'", "[1]"]),
    "case_timeout": st.sampled_from(["5", "'2m'", "1e20", "86401", "-3", "0", "'soon'",
                                     "float('nan')", "True", "10**5000"]),
    "accept": st.sampled_from(["'any'", "'regressions'", "['distance']", "'distance'",
                               "'nope nope'", "5", "[]", "rate('distance', 0.5)",
                               "rate('distance', 'x')", "rate('nope', 0.01, 0.95)",
                               "'rate:distance<=50%'", "'rate:distance<=x'",
                               "rate('distance', float('nan'))", "[rate('distance', 2.0)]"]),
}


@st.composite
def declaration(draw):
    """Source text of one test's decorators and arguments: a valid declaration, or one with a
    single fault (an odd distribution, parameter name, setting value, misspelt setting, or
    decorator shape)."""
    names = draw(st.lists(NAME, min_size=1, max_size=3, unique=True))
    keywords = [f"{n}={draw(valid_distribution())}" for n in names]
    keywords.append(f"samples={draw(st.sampled_from(['1', '2', '2', '3']))}")
    for key in draw(st.lists(st.sampled_from(sorted(VALID_SETTINGS)), max_size=3, unique=True)):
        keywords.append(f"{key}={draw(VALID_SETTINGS[key])}")
    args = "case"
    fault = draw(st.sampled_from(["none"] * 5 + ["distribution"] * 3 + ["setting"] * 3 +
                                 ["name", "misspelt", "shape"]))
    if fault == "distribution":
        keywords.append(f"{draw(NAME.filter(lambda n: n not in names))}={draw(odd_distribution())}")
    elif fault == "setting":
        key = draw(st.sampled_from(sorted(SETTINGS)))
        keywords = [k for k in keywords if not k.startswith(f"{key}=")]
        keywords.append(f"{key}={draw(SETTINGS[key])}")
    elif fault == "name":
        bad = draw(BAD_NAME)
        value = draw(valid_distribution())
        keywords.append(bad.replace("X", value) if bad.startswith("**") else f"{bad}={value}")
    elif fault == "misspelt":
        value = draw(st.one_of(valid_distribution(), st.sampled_from(["100", "'random'", "5"])))
        keywords.append(f"{draw(MISSPELT)}={value}")
    keywords = draw(st.permutations(keywords))
    keywords.sort(key=lambda k: k.startswith("**"))  # an unpacking comes last
    decorators = [f"@scenario({', '.join(keywords)})"]
    if fault == "shape":
        shape = draw(st.sampled_from(["bare", "stacked", "positional", "example", "bad example",
                                      "bare example", "no case"]))
        if shape == "bare":
            decorators = ["@scenario"]
        elif shape == "stacked":
            decorators.insert(0, "@scenario(y=Uniform(0, 1), samples=2)")
        elif shape == "positional":
            decorators = [f"@scenario({draw(valid_distribution())}, {', '.join(keywords)})"]
        elif shape == "example":
            pins = ", ".join(f"{n}={draw(OPTION)}" for n in names[:2])
            decorators.insert(0, f"@example({pins})")
        elif shape == "bad example":
            decorators.insert(0, "@example(1, 2)")
        elif shape == "bare example":
            decorators.insert(0, "@example")
        else:
            args = ""
    return "\n".join(decorators), args


PLUGIN_FRAME = re.compile(r"pytest_avscenario/[\w/]+\.py:\d+")


def _outcomes(path):
    """Final outcome per item: error (any phase but call failed), failed, passed, skipped."""
    final: dict[str, str] = {}
    for line in path.read_text().splitlines() if path.exists() else []:
        nodeid, when, outcome, xfail = json.loads(line)
        if outcome == "failed":
            final[nodeid] = "failed" if when == "call" and final.get(nodeid) != "error" else "error"
        elif outcome == "skipped" and xfail:
            final.setdefault(nodeid, "xfailed")
        elif outcome == "skipped":
            final.setdefault(nodeid, "skipped")
        elif when == "call":
            final.setdefault(nodeid, "passed")
    return final


def _check_session(pytester, directory, report, modules, result, outcomes_path):
    out = result.stdout.str() + result.stderr.str()
    if os.environ.get("FUZZ_DUMP"):  # for a human chasing a failure
        with open(os.environ["FUZZ_DUMP"], "a") as f:
            f.write(f"=== {directory} ret={result.ret}\n{out}\n")
    where = f"session {directory}; modules:\n" + "\n\n".join(
        f"{name}:\n{text}" for name, text in sorted(modules.items()))
    assert "INTERNALERROR" not in out, out[-6000:] + where
    assert result.ret in (pytest.ExitCode.OK, pytest.ExitCode.TESTS_FAILED,
                          pytest.ExitCode.NO_TESTS_COLLECTED), (result.ret, out[-6000:])
    frames = PLUGIN_FRAME.findall(out)
    assert not frames and "Traceback (most recent call last)" not in out, \
        f"plugin frames shown: {frames[:5]}\n{out[-6000:]}"
    # every collection error names its test
    sections = re.split(r"_{3,} ERROR collecting (\S+) _{3,}", out)
    for path, text in zip(sections[1::2], sections[2::2]):
        stem = path.rsplit("/", 1)[-1][:-3]
        text = text.split("\n=")[0]
        assert f"{path}::{stem}" in text or f"{path}::Test" in text, \
            f"collection error of {path} does not name the test:\n{text}\n{modules.get(stem)}"
    final = _outcomes(outcomes_path)
    ran = {n for n, o in final.items() if o in ("passed", "failed", "error", "xfailed")}
    rows_file = pytester.path / report / "errors.jsonl"
    rows = [json.loads(line) for line in rows_file.read_text().splitlines()] if rows_file.exists() else []
    items = [r["item"] for r in rows]
    assert len(items) == len(set(items)), "a case has two rows"
    assert set(items) == ran, (f"rows without an item: {sorted(set(items) - ran)[:5]}; items "
                               f"without a row: {sorted(ran - set(items))[:5]}")
    return len(ran)


def test_fuzzed_declarations_give_clean_errors_and_a_row_per_case(pytester, monkeypatch):
    pytester.makeconftest(OUTCOMES)
    counts = {"declarations": 0, "items": 0, "sessions": 0}
    last: list[tuple] = []
    t0 = time.monotonic()

    def session(directory, report, modules, again=False):
        outcomes_path = pytester.path / f"{directory}-{report}.outcomes.jsonl"
        monkeypatch.setenv("FUZZ_OUTCOMES", str(outcomes_path))
        result = pytester.runpytest(
            directory, "-p", "no:cacheprovider", "--avs-seed=1", "--avs-db=db",
            f"--avs-report={report}", "--continue-on-collection-errors", "-q", "-W",
            "ignore::pytest.PytestReturnNotNoneWarning")
        counts["items"] += _check_session(pytester, directory, report, modules, result, outcomes_path)
        counts["sessions"] += 1

    @settings(max_examples=BATCHES, derandomize=not os.environ.get("FUZZ_RANDOM"), deadline=None,
              database=None,
              phases=[Phase.explicit, Phase.generate],
              suppress_health_check=list(HealthCheck))
    @given(batch=st.lists(declaration(), min_size=PER_BATCH, max_size=PER_BATCH))
    def run(batch):
        directory = f"b{counts['sessions']:02d}"
        modules = {}
        for i, (decorators, args) in enumerate(batch):
            name = f"test_{directory}_{i:02d}"
            modules[name] = f"{HEADER}\n\n{decorators}\n{BODY.format(name=name, args=args)}"
            pytester.makepyfile(**{f"{directory}/{name}": modules[name]})
        session(directory, f"report-{directory}", modules)
        counts["declarations"] += len(batch)
        last[:] = [(directory, modules)]

    run()
    # the last batch again: its stored counterexamples are replayed from the database
    directory, modules = last[0]
    session(directory, f"report-{directory}-again", modules)
    took = time.monotonic() - t0
    print(f"fuzzed {counts['declarations']} declarations in {counts['sessions']} sessions, "
          f"{counts['items']} items with rows, {took:.0f} s")
    assert counts["declarations"] >= 300

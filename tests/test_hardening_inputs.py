"""Issue #32: hostile inputs the plugin reads or prints — the baseline summary, --avs-params,
the commands it prints for a user to paste. Each is a usage error naming the file or option,
the field and what was wrong (never an INTERNALERROR, never a silently disabled gate)."""

from __future__ import annotations

import html
import json
import re
import shlex
import subprocess

import pytest

# the lead stands 20·x m ahead, 3 m to the side: `distance` (5 m) is violated for x < 0.2
# (2 of the 8 Halton cases), `collision` never; accept=["collision"] leaves the baseline to gate
FAILING = """
from pytest_avscenario import scenario, Uniform
from pytest_avscenario.monitors import collision, distance
from pytest_avscenario.trajectory import Trajectory

@scenario(x=Uniform(0, 1), samples=8, monitors=[distance(5.0, kind="centre"), collision()], accept=["collision"])
def test_follow(case):
    gap = 20 * case.x
    return Trajectory.from_arrays([0.0, 0.1], {
        "ego": {"x": [0.0, 0.0], "y": [0.0, 0.0]},
        "lead": {"x": [gap, gap], "y": [3.0, 3.0]},
    })
"""


def _baseline(pytester, campaigns, **extra) -> str:
    data = {"tests": [{"test": "test_base.py::test_follow", "sampler": "halton", "samples": n,
                       "violations": {"distance": k, "collision": 0}, "modes": []}
                      for n, k in campaigns], **extra}
    pytester.path.joinpath("base.json").write_text(json.dumps(data))
    return "--avs-baseline=base.json"


def _run(pytester, *args):
    pytester.makepyfile(test_base=FAILING)
    return pytester.runpytest_subprocess("--avs-seed=1", "--avs-shrink-budget=0", "--avs-db=none",
                                         "-p", "no:cacheprovider", *args)


@pytest.mark.parametrize("count, why", [
    (-1, "negative"),
    (101, "more than its 100 samples"),
    (1.5, "not a whole number"),
    ("3", "not a whole number"),
    (True, "not a whole number"),
])
def test_a_baseline_count_out_of_bounds_is_a_usage_error_naming_file_and_field(pytester, count, why):
    # a negative count was accepted at start-up and disabled every campaign's verdict (null,
    # exit 0): a gate that is silently off
    data = {"tests": [{"test": "test_base.py::test_follow", "sampler": "halton", "samples": 100,
                       "violations": {"distance": count}, "modes": []}]}
    pytester.path.joinpath("base.json").write_text(json.dumps(data))
    result = _run(pytester, "--avs-baseline=base.json")
    assert result.ret == pytest.ExitCode.USAGE_ERROR, result.stderr.str()
    err = result.stderr.str()
    assert "INTERNALERROR" not in err + result.stdout.str()
    assert "base.json" in err and "tests[0].violations.distance" in err and why in err


@pytest.mark.parametrize("text, why", [
    ('{"tests": [{"test": "t", "sampler": "halton", "samples": Infinity, "violations": {}}]}', "Infinity"),
    ('{"tests": [{"test": "t", "sampler": "halton", "samples": 4, "violations": {"a": 1e400}}]}', "tests[0].violations.a"),
    ('{"tests": [{"test": "t", "sampler": "halton", "samples": NaN, "violations": {}}]}', "NaN"),
    ("[" * 100_000 + "]" * 100_000, "nested more than"),
    ('{"tests": [{"test": "t", "sampler": "halton", "samples": ' + "9" * 5000 + ', "violations": {}}]}', "digits"),
    ('{"tests": [{"test": "t", "sampler": "halton", "samples": -3, "violations": {}}]}', "tests[0].samples"),
    ('{"tests": {"test": "t"}}', "tests"),
    ('{"tests": [{"test": 5, "sampler": "halton", "samples": 3, "violations": {}}]}', "tests[0].test"),
], ids=["Infinity", "1e400", "NaN", "deep", "digits", "negative-samples", "tests-object", "test-number"])
def test_a_hostile_baseline_is_a_usage_error_never_an_internalerror(pytester, text, why):
    pytester.path.joinpath("base.json").write_text(text)
    result = _run(pytester, "--avs-baseline=base.json")
    err = result.stderr.str()
    assert "INTERNALERROR" not in err + result.stdout.str()
    assert result.ret == pytest.ExitCode.USAGE_ERROR, err
    assert "--avs-baseline" in err and "base.json" in err and why in err


def test_a_baseline_that_is_not_a_regular_file_is_refused_before_it_is_opened(pytester):
    pytester.path.joinpath("base").mkdir()
    result = _run(pytester, "--avs-baseline=base")
    assert result.ret == pytest.ExitCode.USAGE_ERROR
    assert "not a regular file" in result.stderr.str()


def test_an_interrupted_summary_is_refused_as_a_baseline_unless_asked(pytester):
    flag = _baseline(pytester, [(100, 0)], interrupted=True)
    result = _run(pytester, flag)
    assert result.ret == pytest.ExitCode.USAGE_ERROR
    err = result.stderr.str()
    assert "base.json" in err and "interrupted" in err and "--avs-baseline-partial" in err
    # asked for: the partial baseline gates as any other
    again = _run(pytester, flag, "--avs-baseline-partial")
    assert again.ret == pytest.ExitCode.TESTS_FAILED


def test_a_valid_baseline_still_gates(pytester):
    # the reference point of the tests above: 0/100 before, 2/4 now is a significant worsening
    result = _run(pytester, _baseline(pytester, [(100, 0)]))
    assert result.ret == pytest.ExitCode.TESTS_FAILED
    result.stdout.fnmatch_lines(["REJECTED *: distance rate 2/8 (*) vs 0/100 (*) in the baseline*"])


@pytest.mark.parametrize("value, why", [
    ('{"x": ' + "9" * 5000 + "}", "digits"),
    ('{"x": ' + "[" * 40_000 + "]" * 40_000 + "}", "nested more than"),
    ('{"x": Infinity}', "Infinity"),
    ('{"x": 1e400}', "too large"),
    ("[1, 2]", "JSON object"),
    ("{oops", "not valid JSON"),
], ids=["digits", "deep", "Infinity", "1e400", "list", "broken"])
def test_hostile_avs_params_are_a_usage_error_naming_the_option(pytester, value, why):
    pytester.makepyfile(test_base=FAILING)
    result = pytester.runpytest_subprocess("--avs-seed=1", "--avs-db=none", "-p", "no:cacheprovider",
                                           "--avs-params", value)
    err = result.stderr.str()
    assert "INTERNALERROR" not in err + result.stdout.str()
    assert result.ret == pytest.ExitCode.USAGE_ERROR, err
    assert "--avs-params" in err and why in err


HOSTILE_DIR = "d'$(touch PWNED)'x"


def test_every_printed_rerun_command_is_shell_quoted(pytester):
    # a directory named d'$(touch PWNED)'x printed a command that ran `touch PWNED` when pasted
    sub = pytester.path / HOSTILE_DIR
    sub.mkdir()
    (sub / "test_evil.py").write_text(
        "from pytest_avscenario import scenario, Uniform, Choice\n"
        "@scenario(gap=Uniform(10, 40), word=Choice([\"it's $(touch PWNED2) `touch PWNED3`\"]), samples=2)\n"
        "def test_follow(case):\n"
        "    assert case.gap < 20\n")
    result = pytester.runpytest_subprocess(
        "--avs-seed=1", "--avs-shrink-budget=0", "--avs-db=none", "-p", "no:cacheprovider",
        "--avs-report=rep", "--avs-params",
        json.dumps({"word": "it's $(touch PWNED2) `touch PWNED3`"}), HOSTILE_DIR)
    terminal = [l.split("re-run only this case: ", 1)[1] for l in result.outlines if "re-run only this case: " in l]
    cards = [html.unescape(m) for p in (pytester.path / "rep").rglob("*.html")
             for m in re.findall(r"<pre class='rerun'>([^<]*)</pre>", p.read_text())]
    assert terminal and cards
    for command in {*terminal, *cards}:
        # what a shell makes of it: exactly the words the plugin meant, nothing executed
        echoed = subprocess.run(["sh", "-c", "printf '%s\\n' " + command.split(" ", 1)[1]],
                                cwd=pytester.path, capture_output=True, text=True, timeout=30)
        words = echoed.stdout.splitlines()
        assert words[0].startswith(f"{HOSTILE_DIR}/test_evil.py::test_follow["), command
        assert "it's $(touch PWNED2) `touch PWNED3`" in words[words.index("--avs-params") + 1]
        assert shlex.split(command)[1:] == words
    assert not list(pytester.path.rglob("PWNED*"))


def test_a_full_disk_while_the_report_folder_is_closed_is_one_line_not_a_traceback(pytester):
    # #32 item 7: an all-passing run ended with a raw OSError from the folder clean-up and
    # exit status 1. The disk fills after the report is written: every flush and close of the
    # manifest's log (and the error table's files) now fails with ENOSPC, simulated in-process
    pytester.makeconftest("""
import errno
import pytest
from pytest_avscenario.pytest_plugin.stash import controller_key

class Full:
    closed = False
    def _full(self, *args):
        raise OSError(errno.ENOSPC, "No space left on device")
    write = flush = close = _full

@pytest.hookimpl(trylast=True)
def pytest_sessionfinish(session):
    state = session.config.stash[controller_key]
    state._claimed._log = Full()
    if state.table is not None:
        state.table._jsonl = {"x": Full()}
""")
    pytester.makepyfile(FOUR_PASSING)
    result = pytester.runpytest_subprocess("--avs-db=none", "-p", "no:cacheprovider", "-p", "no:xdist")
    out = result.stdout.str() + result.stderr.str()
    assert result.ret == pytest.ExitCode.OK, out
    assert "Traceback" not in out and "INTERNALERROR" not in out
    assert "could not finish the report folder's manifest and lock under" in out
    assert "No space left on device" in out


FOUR_PASSING = """
from pytest_avscenario import scenario, Uniform

@scenario(x=Uniform(0, 1), samples=4)
def test_x(case):
    pass
"""


def test_comparing_two_finished_reports_by_hand_reads_an_interrupted_one_with_a_note(tmp_path, capsys):
    from pytest_avscenario.report.__main__ import main

    for name, extra in (("old.json", {"interrupted": True, "stopped": "KeyboardInterrupt"}), ("new.json", {})):
        (tmp_path / name).write_text(json.dumps({"tests": [
            {"test": "t.py::test_x", "sampler": "halton", "samples": 10, "violations": {"collision": 1}}], **extra}))
    assert main(["compare", str(tmp_path / "old.json"), str(tmp_path / "new.json")]) == 0
    assert "old.json is the summary of an interrupted run" in capsys.readouterr().err

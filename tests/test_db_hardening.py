"""The replay database against hostile or stale entries and unwritable places, through pytest:
one warning per bad file (never an INTERNALERROR or a setup error), nothing outside the
declared space reaches a test body, and a database that cannot be written never hides a
failure."""

from __future__ import annotations

import errno
import json
import os
from pathlib import Path

import pytest

from pytest_avscenario.db import ReplayDB, entry_name
from pytest_avscenario.space import Choice, FeatureSpace, Uniform

TEST = "test_gap.py::test_gap"

# a body that fails loudly if anything but a declared value or a case seed reaches it
GUARDED = """
from pytest_avscenario import scenario, Uniform, Choice

@scenario(gap=Uniform(10, 40, nominal=30), road=Choice(["dry", "wet"]), samples=1)
def test_gap(case):
    assert type(case.gap) is float and 10 <= case.gap <= 40, case.gap
    assert type(case.road) is str and case.road in ("dry", "wet"), case.road
    assert type(case.seed) is int and 0 <= case.seed < 2**63, case.seed
"""

GOOD = {"gap": 12.5, "road": "wet"}


def _space():
    return FeatureSpace({"gap": Uniform(10, 40, nominal=30), "road": Choice(["dry", "wet"])})


def store(pytester, params=GOOD, raw=None, name=None, **fields) -> Path:
    """Write an entry of test_gap as the plugin would, with ``params`` and ``fields`` changed
    (``raw``: (old, new) text replaced in the file), named as the plugin names it unless
    ``name`` is given."""
    db = ReplayDB(pytester.path / ".avscenario")
    saved = db.save(TEST, GOOD, {"margin": -1.0}, 1234, _space(), minimized=True, versions={})
    data = json.loads(saved.path.read_text())
    data.update(fields, params=params)
    text = json.dumps(data, indent=2)
    if raw is not None:
        assert raw[0] in text
        text = text.replace(*raw)
    saved.path.unlink()
    path = saved.path.parent / (name or entry_name(TEST, params))
    path.write_text(text)
    return path


def the_line(result, path: Path) -> str:
    """The one output line that names ``path`` (a warning)."""
    lines = [line for line in result.outlines if path.name in line]
    assert len(lines) == 1, result.stdout.str()
    return lines[0]


def test_a_valid_crafted_entry_is_replayed(pytester):
    # the control of the tests below: the crafted entries differ from this one only where they
    # are bad
    pytester.makepyfile(test_gap=GUARDED)
    store(pytester)
    result = pytester.runpytest("-v", "--avs-seed=1")
    result.assert_outcomes(passed=2)
    assert "test_gap.py::test_gap[replay-0] PASSED" in result.stdout.str()


HUGE = "1" * 5000
DEEP = "[" * 100_000 + "]" * 100_000


DUMMY = "aaaaaaaaaaaa-00000000000000000001.json"  # what JSON that cannot be read is named


@pytest.mark.parametrize("how, why", [
    (dict(raw=('"gap": 12.5', f'"gap": {HUGE}'), name=DUMMY), "digits"),
    (dict(raw=('"gap": 12.5', f'"gap": {DEEP}'), name=DUMMY), "nested"),
    # readable, named right, but deeper than any entry: nothing later recurses on it
    (dict(params=dict(GOOD, gap=json.loads("[" * 200 + "]" * 200))), "nested"),
    (dict(raw=('"margin": -1.0', f'"margin": 1{"0" * 400}')), "rho"),
    (dict(raw=('"created": ', f'"created": 1{"0" * 400}, "was": ')), "created"),
    (dict(raw=('"minimized": true', f'"minimized": true, "x": {HUGE}'), name=DUMMY), "digits"),
], ids=["5000-digit-param", "deeply-nested-param", "200-levels", "400-digit-rho",
        "400-digit-created", "5000-digit-extra-field"])
def test_an_unreadable_entry_is_skipped_with_one_warning_and_the_run_goes_on(pytester, how, why):
    pytester.makepyfile(test_gap=GUARDED)
    path = store(pytester, **how)
    result = pytester.runpytest("-v", "--avs-seed=1")
    out = result.stdout.str() + result.stderr.str()
    assert "INTERNALERROR" not in out and "Traceback" not in out
    result.assert_outcomes(passed=1)
    line = the_line(result, path)
    assert why in line and "left on disk" in line
    assert path.exists()


BAD_PARAMS = [
    (dict(GOOD, gap=1e6), "'gap'=1000000.0 lies outside Uniform("),
    (dict(GOOD, gap=9.99), "'gap'=9.99 lies outside"),
    (dict(GOOD, gap="12.5"), "'gap'='12.5' is not a number"),
    (dict(GOOD, gap=[12.5]), "'gap'=[12.5] is not a number"),
    (dict(GOOD, gap=True), "'gap'=True is not a number"),
    (dict(GOOD, gap=None), "'gap'=None is not a number"),
    (dict(GOOD, gap=10 ** 400), "'gap'=1000000000"),
    (dict(GOOD, road="icy"), "'road'='icy' is not one of the options ['dry', 'wet']"),
    (dict(GOOD, road=["wet"]), "'road'=['wet'] is not one of the options"),
    (dict(GOOD, road=1), "'road'=1 is not one of the options"),
    ({"road": "wet"}, "'gap' is missing"),
    (dict(GOOD, speed=3.0), "'speed' is not declared"),
]


@pytest.mark.parametrize("params, why", BAD_PARAMS, ids=[
    "gap-far-out", "gap-just-below", "gap-string", "gap-list", "gap-bool", "gap-null",
    "gap-400-digits", "road-unknown", "road-list", "road-number", "gap-missing", "undeclared"])
def test_a_stored_entry_outside_the_declared_space_is_skipped_naming_test_and_parameter(
        pytester, params, why):
    pytester.makepyfile(test_gap=GUARDED)
    path = store(pytester, params=params)
    result = pytester.runpytest("-v", "--avs-seed=1")
    assert "INTERNALERROR" not in result.stdout.str()
    result.assert_outcomes(passed=1)  # the sampled case; nothing replayed, no setup error
    assert "[replay-" not in result.stdout.str()
    line = the_line(result, path)
    assert TEST in line and why in line and "left on disk" in line
    assert path.exists()


@pytest.mark.parametrize("seed, why", [
    (-1, "-1"), (2 ** 63, str(2 ** 63)), (1.5, "1.5"), ("7", "'7'"), (None, "None"),
])
def test_a_stored_entry_with_a_bad_seed_is_skipped_naming_test_and_seed(pytester, seed, why):
    pytester.makepyfile(test_gap=GUARDED)
    path = store(pytester, seed=seed)
    result = pytester.runpytest("-v", "--avs-seed=1")
    result.assert_outcomes(passed=1)
    line = the_line(result, path)
    assert TEST in line and "'seed'" in line and why in line and "2**63" in line
    assert path.exists()


# ----------------------------------------------------------------- a database that cannot be written

FAILING = """
from pytest_avscenario import scenario, Uniform, Choice
from pytest_avscenario.trajectory import Trajectory

def margin(traj):
    return float(traj.meta["margin"])

@scenario(gap=Uniform(10, 40, nominal=30), road=Choice(["dry", "wet"]), samples=8,
          monitors=[margin], shrink_budget=4)
def test_gap(case):
    return Trajectory.from_arrays([0.0, 0.1], {"ego": {"x": [0, 1], "y": [0, 0]}},
                                  meta={"margin": case.gap - 20.0})
"""


def assert_failures_shown_and_one_warning(result, reason: str) -> None:
    out = result.stdout.str()
    outcomes = result.parseoutcomes()
    failed = outcomes["failed"]
    assert failed >= 2 and "errors" not in outcomes and "error" not in outcomes
    assert "DatabaseError" not in out and "Traceback" not in out and "INTERNALERROR" not in out
    # every failure keeps its normal text, plus one line saying it was not stored
    assert result.outlines.count("scenario violated: margin") == failed
    assert out.count("pin it as a regression above the test: @example(") == failed
    notes = [line for line in result.outlines if "could not store for replay: " in line]
    assert len(notes) == failed and all(reason in line for line in notes)
    # one warning for the run, not one per case
    warned = [line for line in result.outlines if "PytestWarning" in line and "replay database" in line]
    assert len(warned) == 1 and reason in warned[0] and "test_gap[" in warned[0]


@pytest.mark.skipif(not os.path.isdir("/proc/self/fd"), reason="needs /proc/self/fd to find the file")
def test_a_full_disk_does_not_hide_the_failures(pytester, monkeypatch):
    real_fsync = os.fsync

    def full_disk(fd):
        if ".avscenario" in os.readlink(f"/proc/self/fd/{fd}"):
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
        return real_fsync(fd)

    monkeypatch.setattr(os, "fsync", full_disk)
    pytester.makepyfile(test_gap=FAILING)
    result = pytester.runpytest("--avs-seed=1")
    assert_failures_shown_and_one_warning(result, os.strerror(errno.ENOSPC))
    assert list((pytester.path / ".avscenario").iterdir()) == []  # no half-written file


def test_a_database_that_becomes_unwritable_does_not_hide_the_failures(pytester):
    # what even root cannot write through: the database's parent turns into a file after start-up
    pytester.makeconftest("""
from pathlib import Path

def pytest_collection_finish(session):
    Path("store").write_text("a file now")
""")
    pytester.makepyfile(test_gap=FAILING)
    result = pytester.runpytest("--avs-seed=1", "--avs-db=store/db")
    assert_failures_shown_and_one_warning(result, "is a file")
    assert (pytester.path / "store").read_text() == "a file now"  # never removed


def test_a_read_only_database_does_not_hide_the_failures(pytester):
    db = pytester.path / ".avscenario"
    db.mkdir()
    db.chmod(0o555)
    try:
        try:
            (db / "probe").touch()
        except PermissionError:
            pass
        else:  # root (with CAP_DAC_OVERRIDE) writes anyway: the test above shows this case
            (db / "probe").unlink()
            pytest.skip("this user writes into read-only directories (root)")
        pytester.makepyfile(test_gap=FAILING)
        result = pytester.runpytest("--avs-seed=1")
    finally:
        db.chmod(0o755)
    assert_failures_shown_and_one_warning(result, os.strerror(errno.EACCES))


def test_a_fixed_entry_that_cannot_be_removed_only_warns(pytester, monkeypatch):
    pytester.makepyfile(test_gap=GUARDED)
    path = store(pytester)
    real_unlink = os.unlink

    def refuse(p, *args, **kwargs):
        if path.name in str(p):  # the entry, by its path or by its name in its folder (dir_fd)
            raise PermissionError(errno.EACCES, os.strerror(errno.EACCES), str(p))
        return real_unlink(p, *args, **kwargs)

    monkeypatch.setattr(os, "unlink", refuse)
    result = pytester.runpytest("-v", "--avs-seed=1")
    result.assert_outcomes(passed=2)
    assert "test_gap.py::test_gap[replay-0] PASSED" in result.stdout.str()
    warned = [line for line in result.outlines if "PytestWarning" in line and "replay database" in line]
    assert len(warned) == 1 and path.name in warned[0] and "test_gap[replay-0]" in warned[0]
    assert os.strerror(errno.EACCES) in warned[0]
    assert path.exists()

"""The report directory is shared ground: concurrent runs, users' own files, odd declarations.

Issue #16, items 1-3: a second run in the same ``--avs-report`` directory must not take the
first run's rows or numbers, files the plugin did not write are never deleted or
overwritten, and no part of the report can crash the end of the session.
"""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
import time

import pytest

SCENARIOS = """
import os
import pathlib
import time
from pytest_avscenario import scenario, Uniform

@scenario(x=Uniform(0, 1), samples=6)
def test_a(case):
    pass

def test_handshake():
    # the first run waits here, holding rows of test_a, until the second run has finished
    folder = os.environ.get("AVS_HANDSHAKE")
    if folder:
        (pathlib.Path(folder) / "first-has-rows").touch()
        for _ in range(3000):
            if (pathlib.Path(folder) / "second-done").exists():
                return
            time.sleep(0.1)
        raise AssertionError("the second run never finished")

@scenario(y=Uniform(0, 1), samples=5)
def test_b(case):
    pass
"""


def _rows(directory):
    return [json.loads(line) for line in (directory / "errors.jsonl").read_text().splitlines()]


def _samples(directory):
    summary = json.loads((directory / "summary.json").read_text())
    return {t["test"].rpartition("::")[2]: t["samples"] for t in summary["tests"]}


def _wait_for(path, proc):
    # not a timing assertion: only how long to wait for the other process before giving up
    for _ in range(3000):
        if path.exists():
            return
        if proc.poll() is not None:
            pytest.fail(f"the first run ended before it had rows: {proc.communicate()}")
        time.sleep(0.1)
    proc.kill()
    pytest.fail("the first run never reached its handshake")


def test_two_runs_in_one_directory_keep_their_own_rows_and_numbers(pytester, monkeypatch):
    pytester.makepyfile(test_two=SCENARIOS)
    args = ["--avs-report=rep", "--avs-db=none", "--avs-seed=1", "-p", "no:cacheprovider"]
    handshake = pytester.mkdir("handshake")
    monkeypatch.setenv("AVS_HANDSHAKE", str(handshake))
    first = pytester.popen([sys.executable, "-m", "pytest", "-p", "no:xdist", *args],
                           stdout=subprocess.PIPE, stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL)
    try:
        _wait_for(handshake / "first-has-rows", first)
        monkeypatch.delenv("AVS_HANDSHAKE")
        second = pytester.runpytest(*args, "-k", "test_a")
    finally:
        (handshake / "second-done").touch()
        out, _ = first.communicate(timeout=600)
    out = out.decode()
    assert first.returncode == 0, out
    second.assert_outcomes(passed=6)
    # the second run leaves the first run's directory alone, says where it went and why
    second.stdout.fnmatch_lines([
        f"*the report goes to *rep-2 instead of *rep: *rep is in use by another pytest run (pid {first.pid})*",
        "*avscenario report: *rep-2*index.html*",
    ])
    assert "instead of" not in out and f"avscenario report: {pytester.path / 'rep' / 'index.html'}" in out
    rep, rep2 = pytester.path / "rep", pytester.path / "rep-2"
    assert [r["test"].rpartition("::")[2] for r in _rows(rep)] == ["test_a"] * 6 + ["test_b"] * 5
    assert [r["test"].rpartition("::")[2] for r in _rows(rep2)] == ["test_a"] * 6
    assert _samples(rep) == {"test_a": 6, "test_b": 5}
    assert _samples(rep2) == {"test_a": 6}
    assert (rep / "index.html").exists() and (rep2 / "index.html").exists()


def test_a_run_after_a_finished_one_reuses_the_directory_and_replaces_only_its_files(pytester):
    pytester.makepyfile(test_two=SCENARIOS)
    (pytester.path / "rep" / "tables").mkdir(parents=True)
    (pytester.path / "rep" / "tables" / "budget.csv").write_text("mine")
    (pytester.path / "rep" / "notes.txt").write_text("mine")
    args = ["--avs-report=rep", "--avs-db=none", "-p", "no:cacheprovider"]
    pytester.runpytest(*args).assert_outcomes(passed=12)
    assert len(list((pytester.path / "rep" / "tables").glob("*.csv"))) == 3
    result = pytester.runpytest(*args, "-k", "test_b")
    result.assert_outcomes(passed=5)
    assert "instead of" not in result.stdout.str() and not (pytester.path / "rep-2").exists()
    rep = pytester.path / "rep"
    # test_a's table and plots of the first run are gone; the user's files stay
    assert sorted(p.name for p in (rep / "tables").iterdir())[0] == "budget.csv"
    assert len(list((rep / "tables").glob("*-*.csv"))) == 1
    assert all("test_b" in p.name for p in (rep / "plots").iterdir())
    assert (rep / "notes.txt").read_text() == "mine" and (rep / "tables" / "budget.csv").read_text() == "mine"
    assert _samples(rep) == {"test_b": 5}


def test_a_run_without_scenario_cases_neither_creates_nor_locks_the_directory(pytester):
    pytester.makepyfile("def test_plain(): pass")
    pytester.runpytest("-p", "no:cacheprovider").assert_outcomes(passed=1)
    assert not (pytester.path / "avs-report").exists()


@pytest.mark.parametrize("name", [
    "index.html", "summary.json", "errors.jsonl", "shrink.jsonl",
    "tables/mine-0123abcd.csv", "tables/mine-0123abcd.shrink.csv",
    "plots/mine-0123abcd.rho.png", "plots/mine-0123abcd.space.png",
    "cases/mine-0123abcd.png", "cases/mine-0123abcd.gif",
])
def test_a_file_the_plugin_did_not_write_is_never_deleted_or_overwritten(pytester, name):
    pytester.makepyfile(test_two=SCENARIOS)
    theirs = pytester.path / "avs-report" / name
    theirs.parent.mkdir(parents=True, exist_ok=True)
    theirs.write_text("mine")
    an_hour_ago = time.time() - 3600
    os.utime(theirs, (an_hour_ago, an_hour_ago))  # older than the run, like a real leftover
    result = pytester.runpytest("--avs-db=none", "-p", "no:cacheprovider")
    result.assert_outcomes(passed=12)
    assert theirs.read_text() == "mine"
    result.stdout.fnmatch_lines([
        f"*the report goes to *avs-report-2 instead of *avs-report: *avs-report holds files "
        f"pytest-avscenario did not write (*{name}: there is no manifest of ours)*move those files away*",
        "*avscenario report: *avs-report-2*index.html*",
    ])
    assert _samples(pytester.path / "avs-report-2") == {"test_a": 6, "test_b": 5}
    assert sorted(p.name for p in (pytester.path / "avs-report").iterdir()) == [name.partition("/")[0]]


def test_files_beside_ours_are_not_in_the_way(pytester):
    pytester.makepyfile(test_two=SCENARIOS)
    report = pytester.path / "avs-report"
    for name in ("cases/photo.png", "cases/loop.gif", "plots/figure-1.png", "tables/budget.csv", "README.md"):
        (report / name).parent.mkdir(parents=True, exist_ok=True)
        (report / name).write_text("mine")
        os.utime(report / name, (time.time() - 3600,) * 2)
    result = pytester.runpytest("--avs-db=none", "-p", "no:cacheprovider")
    result.assert_outcomes(passed=12)
    assert "instead of" not in result.stdout.str()
    for name in ("cases/photo.png", "cases/loop.gif", "plots/figure-1.png", "tables/budget.csv", "README.md"):
        assert (report / name).read_text() == "mine", name
    assert _samples(report) == {"test_a": 6, "test_b": 5}


FAILING_WORLD = """
from pytest_avscenario import scenario, Uniform
from pytest_avscenario.monitors import distance

@scenario(gap=Uniform(3, 30), samples=4, monitors=[distance(8.0, kind="centre")])
def test_gap(case, world):
    road = world.straight_road(lanes=1, length=300)
    world.ego(road.lane(0), s=20.0, speed=10.0)
    world.car(road.lane(0), s=20.0 + case.gap, speed=10.0)
    world.run(seconds=1)
"""


def test_xdist_workers_case_pictures_land_in_the_claimed_directory(pytester, monkeypatch):
    pytest.importorskip("xdist")
    pytester.makepyfile(test_gap=FAILING_WORLD)
    report = pytester.path / "avs-report"
    (report / "index.html").parent.mkdir()
    (report / "index.html").write_text("mine")  # so this run writes to avs-report-2
    tmp = pytester.mkdir("tmp")
    monkeypatch.setenv("TMPDIR", str(tmp))  # where the workers draw before the controller moves
    result = pytester.runpytest_subprocess("-n", "2", "--avs-db=none", "--avs-shrink-budget=0",
                                           "-p", "no:cacheprovider")
    result.assert_outcomes(passed=3, failed=1)
    pictures = sorted(p.name for p in (pytester.path / "avs-report-2" / "cases").iterdir())
    # the first violation, the time series, the GIF and the card (which took in the replay's data)
    # (and the replay player the cards share), and the case exported (--avs-export's default)
    assert sorted(p.rpartition(".")[2] for p in pictures) == ["gif", "html", "js", "osi", "png",
                                                              "png", "xodr", "xosc", "xosc"]
    manifest = json.loads((pytester.path / "avs-report-2" / ".avs-manifest.json").read_text())
    assert {f"cases/{p}" for p in pictures} <= set(manifest["files"])
    assert list(tmp.iterdir()) == [] and sorted(p.name for p in report.iterdir()) == ["index.html"]
    page = (pytester.path / "avs-report-2" / "index.html").read_text()
    card = next(p for p in pictures if p.endswith(".html"))
    assert f"cases/{card}" in page
    card_page = (pytester.path / "avs-report-2" / "cases" / card).read_text()
    assert all(p in card_page for p in pictures if p.endswith((".png", ".gif")))
    # the replay a worker recorded is on the card, with its slider
    embedded = re.search(r"<script type='application/json' id='replay-data'>(.*?)</script>", card_page, re.S)
    replay = json.loads(embedded.group(1))
    assert "<input type='range'" in card_page and [a["name"] for a in replay["agents"]] == ["ego", "car1"]


def test_a_second_run_clears_the_first_runs_exports_and_keeps_a_users_files(pytester):
    """The OpenSCENARIO/OpenDRIVE files and the OSI trace a run exported are the plugin's own:
    the next run in the folder removes them like its pictures (here it exports nothing), and a
    user's files of the same kinds stay."""
    pytester.makepyfile(test_gap=FAILING_WORLD)
    cases = pytester.path / "avs-report" / "cases"
    common = ("--avs-db=none", "--avs-shrink-budget=0", "--avs-gifs=0", "-p", "no:cacheprovider")
    pytester.runpytest(*common).assert_outcomes(passed=3, failed=1)
    exported = sorted(p.name for p in cases.iterdir() if p.suffix in (".xosc", ".xodr", ".osi"))
    assert sorted(p.rpartition(".")[2] for p in exported) == ["osi", "xodr", "xosc", "xosc"]
    for name in ("mine.xosc", "mine.xodr", "drive.osi"):
        (cases / name).write_text("mine")
    pytester.runpytest(*common, "--avs-export=none").assert_outcomes(passed=3, failed=1)
    assert sorted(p.name for p in cases.iterdir() if p.suffix in (".xosc", ".xodr", ".osi")) == [
        "drive.osi", "mine.xodr", "mine.xosc"]
    assert all((cases / n).read_text() == "mine" for n in ("mine.xosc", "mine.xodr", "drive.osi"))


# --------------------------------------------------------------------------- item 3

ODD = """
from pytest_avscenario import scenario, Uniform, Choice

@scenario(x=Uniform(1e308, 1.7e308), samples=4)
def test_wide(case):
    pass

@scenario(n=Choice([10**400, 1]), y=Uniform(0, 1), samples=4)
def test_huge_int(case):
    pass

@scenario(road=Choice(["dry", "wet"], weights=[1e308, 1e308]), samples=4)
def test_huge_weights(case):
    pass
"""


def test_declarations_accepted_at_collection_give_a_whole_report(pytester):
    pytester.makepyfile(test_odd=ODD)
    result = pytester.runpytest("--avs-db=none", "--junitxml=out.xml", "-p", "no:cacheprovider")
    result.assert_outcomes(passed=12)
    assert result.ret == pytest.ExitCode.OK
    out = result.stdout.str()
    assert "Traceback" not in out and "INTERNALERROR" not in out
    result.stdout.fnmatch_lines(["*= avscenario =*", "test_wide *", "test_huge_int *", "test_huge_weights *",
                                 "*avscenario report: *index.html*"])
    report = pytester.path / "avs-report"
    assert _samples(report) == {"test_wide": 4, "test_huge_int": 4, "test_huge_weights": 4}
    assert (report / "index.html").exists()
    assert any("test_huge_int" in p.name and p.name.endswith(".space.png") for p in (report / "plots").iterdir())
    xml = (pytester.path / "out.xml").read_text()
    assert "avs.test[test_odd.py::test_huge_int][halton].samples" in xml
    wide = json.loads((report / "summary.json").read_text())["tests"][0]
    assert wide["epsilon"] is None or 0 <= wide["epsilon"] <= 1


PASSING = """
from pytest_avscenario import scenario, Uniform

@scenario(x=Uniform(0, 1), samples=4)
def test_gap(case):
    pass
"""


def _boom(exc):
    def boom(*args, **kwargs):
        raise exc
    return boom


def _patch(monkeypatch, target, value):
    # through sys.modules: an earlier in-process run may have left a stale module object as
    # the package's attribute, which is not the module the next run imports
    import importlib

    module, _, name = target.rpartition(".")
    try:
        owner = importlib.import_module(module)
    except ImportError:
        module, _, cls = module.rpartition(".")
        owner = getattr(importlib.import_module(module), cls)
    monkeypatch.setattr(owner, name, value)


@pytest.mark.parametrize("target, exc, part", [
    ("pytest_avscenario.report.plots.plot_test", OverflowError("int too large"),
     "the plots of test_gap.py::test_gap"),
    ("pytest_avscenario.report.coverage.epsilon_coverage", ImportError("scipy: MemoryError"),
     "the ε-coverage [[]halton[]] of test_gap.py::test_gap"),
    ("pytest_avscenario.report.build.summary_to_json", ValueError("NaN"), "summary.json"),
    ("pytest_avscenario.report.html.write_index", RuntimeError("disk"), "index.html"),
    ("pytest_avscenario.report.summary.format_table", ValueError("width"), "the terminal table"),
    ("pytest_avscenario.report.junit.add_suite_properties_to_logxml", TypeError("xml"),
     "the JUnit suite properties"),
])
def test_a_failing_report_part_is_a_warning_and_the_rest_is_written(pytester, monkeypatch, target, exc, part):
    pytester.makepyfile(test_gap=PASSING)
    _patch(monkeypatch, target, _boom(exc))
    result = pytester.runpytest("--avs-db=none", "--junitxml=out.xml", "-p", "no:cacheprovider")
    assert result.ret == pytest.ExitCode.OK  # what the tests decided
    result.assert_outcomes(passed=4)
    result.stdout.fnmatch_lines([f"*avscenario: the report could not make {part} ({type(exc).__name__}: *"
                                 "the other parts of the report are still written*"])
    assert "Traceback" not in result.stdout.str()
    report = pytester.path / "avs-report"
    assert (pytester.path / "out.xml").exists()
    written = {p.name for p in report.iterdir()}
    assert {"errors.jsonl", "summary.json", "index.html"} - written == ({part} & {"summary.json", "index.html"})
    if "terminal table" not in part:
        result.stdout.fnmatch_lines(["*= avscenario =*", "test_gap *halton*4*"])
    if "JUnit" not in part:
        assert "avs.test[test_gap.py::test_gap][halton].samples" in (pytester.path / "out.xml").read_text()


@pytest.mark.parametrize("how", [["-k", "test_a and halton-002"], ["test_two.py::test_a[halton-002]"],
                                 ["-n", "2", "-k", "test_a and halton-002"]],
                         ids=["keyword", "case-id", "xdist"])
def test_re_running_one_case_keeps_the_campaign_report(pytester, how):
    # issue #17 item 6: a run of some cases of a campaign writes DIR/rerun; DIR stays
    pytester.makepyfile(test_two=SCENARIOS)
    args = ["--avs-report=rep", "--avs-db=none", "--avs-seed=1", "-p", "no:cacheprovider"]
    pytester.runpytest(*args).assert_outcomes(passed=12)
    rep = pytester.path / "rep"
    campaign = (rep / "errors.jsonl").read_text(), (rep / "summary.json").read_text(), (rep / "index.html").read_text()
    again = pytester.runpytest(*args, *how)
    again.assert_outcomes(passed=1)
    again.stdout.fnmatch_lines(["*avscenario report: *rep/rerun/index.html*"])
    assert ((rep / "errors.jsonl").read_text(), (rep / "summary.json").read_text()) == campaign[:2]
    assert [r["item"].rpartition("::")[2] for r in _rows(rep / "rerun")] == ["test_a[halton-002]"]
    # the campaign's page is as it was; the re-run's page says what it is and links back
    assert (rep / "index.html").read_text() == campaign[2]
    page = (rep / "rerun" / "index.html").read_text()
    assert "../index.html" in page and "runs 1 of the 6 halton cases" in page
    # a whole campaign again (a test chosen whole is not a re-run) replaces the campaign report
    pytester.runpytest(*args, "-k", "test_b").assert_outcomes(passed=5)
    assert _samples(rep) == {"test_b": 5} and (rep / "rerun" / "errors.jsonl").exists()


def test_the_manifest_knows_a_killed_runs_files_and_is_not_rewritten_per_file(tmp_path):
    from pytest_avscenario.report.folder import MANIFEST, ReportFolder, claim_report_dir

    folder, _ = claim_report_dir(tmp_path / "rep")
    root = folder.path
    before = (root / MANIFEST).read_bytes()
    names = [root / "cases" / f"test_x-{i:08x}.png" for i in range(50)]
    for path in names:
        folder.add(path)
        path.parent.mkdir(exist_ok=True)
        path.write_bytes(b"png")
    # each file is on record before the run ends, without rewriting the whole manifest
    assert (root / MANIFEST).read_bytes() == before
    killed = ReportFolder(root)  # what the next run sees if this one were killed now
    assert {f"cases/{p.name}" for p in names} <= killed.files
    folder.release()
    assert {f"cases/{p.name}" for p in names} <= set(json.loads((root / MANIFEST).read_text())["files"])
    assert [p.name for p in root.iterdir() if p.name.startswith(".avs-manifest")] == [MANIFEST]
    # and the next run deletes them as ours
    again, _ = claim_report_dir(tmp_path / "rep")
    assert again.path == root and not (root / "cases").exists()
    again.release()

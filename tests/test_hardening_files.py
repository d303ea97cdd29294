"""Issue #32: the files family — symbolic links and special files in the report folder and the
replay database. Every file the plugin writes, reads or deletes there goes through one
opener (:mod:`pytest_avscenario.files`): no symlink is followed below the folder, nothing
but a regular file is read or replaced, and no open can block. Runs that could hang on a
FIFO are subprocesses with a timeout, so a regression fails instead of hanging."""

from __future__ import annotations

import errno
import json
import os
import stat

import pytest

from pytest_avscenario import files

pytestmark = pytest.mark.skipif(not hasattr(os, "mkfifo") or os.name != "posix",
                                reason="symbolic links and FIFOs as POSIX has them")

FAILING = """
from pytest_avscenario import scenario, Uniform

@scenario(x=Uniform(0, 1), samples=6)
def test_a(case):
    assert case.x < 0.3
"""


def _tree(folder):
    """Every path below ``folder`` with the contents of its files (symlinks as their target)."""
    out = {}
    for dirpath, dirnames, filenames in os.walk(folder):
        for name in dirnames + filenames:
            p = os.path.join(dirpath, name)
            rel = os.path.relpath(p, folder)
            if os.path.islink(p):
                out[rel] = "-> " + os.readlink(p)
            elif os.path.isfile(p):
                with open(p, "rb") as fh:
                    out[rel] = fh.read()
            else:
                out[rel] = "dir"
    return out


def _run(pytester, *args):
    return pytester.runpytest_subprocess("--avs-db=none", "-p", "no:cacheprovider", "-p", "no:xdist",
                                         *args, timeout=120)


def _assert_moved_to_sibling(result, pytester, *links):
    """The run wrote its whole report to ``avs-report-2``, and the warning names the links."""
    assert result.ret == pytest.ExitCode.TESTS_FAILED
    out = result.stdout.str()
    assert "Traceback" not in out and "INTERNALERROR" not in out
    shown = ", ".join(f"*{link}" for link in links)
    what = ("is a symbolic link or not a regular file" if len(links) == 1
            else "are symbolic links or special files")
    result.stdout.fnmatch_lines([
        f"*the report goes to *avs-report-2 instead of *avs-report: {shown}* {what}; "
        "pytest-avscenario writes through none*",
    ])
    rows = (pytester.path / "avs-report-2" / "errors.jsonl").read_text().splitlines()
    assert len(rows) == 6
    assert len(list((pytester.path / "avs-report-2" / "cases").glob("*.html"))) == 4


def test_a_symlinked_lock_file_is_never_written_through(pytester):
    # before: the target's contents were replaced by the run's pid
    pytester.makepyfile(test_s=FAILING)
    precious = pytester.path / "precious.txt"
    precious.write_text("keep me\n")
    (pytester.path / "avs-report").mkdir()
    (pytester.path / "avs-report" / ".avs-lock").symlink_to(precious)
    result = _run(pytester)
    assert precious.read_text() == "keep me\n"
    _assert_moved_to_sibling(result, pytester, os.path.join("avs-report", ".avs-lock"))
    assert os.path.islink(pytester.path / "avs-report" / ".avs-lock")


def test_a_symlinked_cases_folder_is_neither_cleared_nor_written(pytester):
    # before: the next run deleted the archived cards its manifest listed and wrote its own there
    pytester.makepyfile(test_s=FAILING)
    assert _run(pytester).ret == pytest.ExitCode.TESTS_FAILED
    report = pytester.path / "avs-report"
    archive = pytester.path / "archive"
    (report / "cases").rename(archive)
    (report / "cases").symlink_to(archive, target_is_directory=True)
    before = _tree(archive)
    assert len([n for n in before if n.endswith(".html")]) == 4
    result = _run(pytester)
    assert _tree(archive) == before
    _assert_moved_to_sibling(result, pytester, os.path.join("avs-report", "cases"))


def test_dangling_symlinks_and_fifos_at_report_names_create_nothing_elsewhere_and_never_block(pytester):
    # before: errors.jsonl / shrink.jsonl were written through, creating the links' targets;
    # a FIFO as the manifest blocked the run at start-up (this run is bounded by a timeout)
    pytester.makepyfile(test_s=FAILING)
    elsewhere = pytester.path / "elsewhere"
    elsewhere.mkdir()
    report = pytester.path / "avs-report"
    report.mkdir()
    names = [".avs-manifest.json", "errors.jsonl", "shrink.jsonl", "summary.json", "tables"]
    for name in names[1:]:
        (report / name).symlink_to(elsewhere / name)
    os.mkfifo(report / names[0])
    result = _run(pytester)
    assert list(elsewhere.iterdir()) == []
    _assert_moved_to_sibling(result, pytester, *(os.path.join("avs-report", n) for n in names[:3]))
    assert "and 2 more" in result.stdout.str()


def test_a_link_that_appears_during_the_run_is_refused_by_the_writer(tmp_path):
    # the claim looks once; the writer itself never follows a link below a confined folder
    root = tmp_path / "report"
    outside = tmp_path / "outside"
    outside.mkdir()
    root.mkdir()
    files.confine(root)
    (root / "cases").symlink_to(outside, target_is_directory=True)
    with pytest.raises(OSError) as info:
        files.atomic_write_text(root / "cases" / "card.html", "x")
    assert str(root / "cases") in str(info.value) and "symbolic link" in str(info.value)
    with pytest.raises(OSError):
        files.open_regular(root / "cases" / "rows.jsonl", "w")
    (outside / "old.html").write_text("archived")
    with pytest.raises(OSError):
        files.unlink_file(root / "cases" / "old.html")
    assert list(outside.iterdir()) == [outside / "old.html"]
    # a link at the file's own name is not replaced, and a FIFO is neither opened nor replaced
    (root / "summary.json").symlink_to(outside / "summary.json")
    with pytest.raises(OSError):
        files.atomic_write_text(root / "summary.json", "{}")
    os.mkfifo(root / "pipe.json")
    with pytest.raises(OSError) as info:
        files.read_regular(root / "pipe.json", 100)
    assert "FIFO" in str(info.value)
    with pytest.raises(OSError):
        files.atomic_write_text(root / "pipe.json", "{}")
    assert stat.S_ISFIFO(os.lstat(root / "pipe.json").st_mode)
    assert list(outside.iterdir()) == [outside / "old.html"]
    # what is allowed still works: new folders and files below the root, appends, removal
    files.atomic_write_text(root / "plots" / "a.png", "png")
    with files.open_regular(root / "plots" / "rows.jsonl", "a") as fh:
        fh.write("1\n")
    assert files.read_regular(root / "plots" / "rows.jsonl", 100) == b"1\n"
    files.unlink_file(root / "plots" / "a.png")
    assert sorted(p.name for p in (root / "plots").iterdir()) == ["rows.jsonl"]


REPLAYED = """
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


def test_a_fifo_at_a_replay_entry_does_not_block_the_save(pytester):
    # before: saving the counterexample opened the FIFO to read the old entry and waited forever
    pytester.makepyfile(test_gap=REPLAYED)
    first = pytester.runpytest_subprocess("--avs-seed=1", "-p", "no:xdist", "-p", "no:cacheprovider", timeout=120)
    failed = first.parseoutcomes()["failed"]
    db = pytester.path / ".avscenario"
    entries = sorted(db.iterdir())
    # one file per counterexample: failures minimized to the same boundary share theirs
    assert failed >= 2 and 1 <= len(entries) <= failed
    for entry in entries:
        entry.unlink()
        os.mkfifo(entry)
    result = pytester.runpytest_subprocess("--avs-seed=1", "-p", "no:xdist", "-p", "no:cacheprovider",
                                           "--junitxml=out.xml", timeout=120)
    outcomes = result.parseoutcomes()
    assert outcomes["failed"] == failed and "error" not in outcomes and "errors" not in outcomes
    out = result.stdout.str()
    assert "Traceback" not in out and "INTERNALERROR" not in out
    # the counterexample whose file is a FIFO now (the one nearest nominal, which no other
    # replaces) says it could not be stored; the run goes on
    notes = [line for line in result.outlines if "could not store for replay: " in line]
    assert 1 <= len(notes) <= failed and all("not a regular file" in line for line in notes)
    rows = (pytester.path / "avs-report" / "errors.jsonl").read_text().splitlines()
    assert len(rows) == 8
    assert all(stat.S_ISFIFO(os.lstat(e).st_mode) for e in entries)  # the user's FIFOs stay


"""The error table: incremental, durable, lossless for ±inf, one valid CSV per test."""

import csv
import json
import math
import os
import subprocess
import sys
import textwrap

import numpy as np
import pytest

from pytest_avscenario.report.table import (
    ErrorTable,
    atomic_write_text,
    file_slug,
    prepare_report_dir,
    read_csv_rows,
    read_rows,
)
from pytest_avscenario.outcome import CaseRow

FOLLOW = "tests/test_follow.py::test_vehicle_following"
PED = "tests/test_ped.py::test_pedestrian"


def make_row(test=FOLLOW, index=0, origin="sampled", rho=None, params=None, **kw):
    row = {
        "test": test,
        "item": f"{test}[halton-{index}]",
        "sampler": "halton",
        "index": index,
        "seed": 1234,
        "origin": origin,
        "params": params if params is not None else {"gap": 10.0 + index, "weather": "dry"},
        "rho": rho if rho is not None else {"distance": 1.5 - index, "ttc": math.inf},
        "verdict": "pass" if index < 2 else "fail",
        "sim_time_s": 0.02,
        "error": None,
    }
    row.update(kw)
    return row


def test_a_row_is_readable_while_the_writer_is_still_open(tmp_path):
    table = ErrorTable(tmp_path)
    table.append(make_row(index=0))
    # Read through fresh file handles before close(): only a flushed row is visible here.
    assert [r.index for r in read_rows(tmp_path)] == [0]
    assert [r["index"] for r in read_csv_rows(table.csv_path(FOLLOW))] == [0]
    table.append(make_row(index=1))
    assert [r.index for r in read_rows(tmp_path)] == [0, 1]
    table.close()


def test_a_killed_process_leaves_every_finished_row(tmp_path):
    # The writer's process dies by SIGKILL right after its last append: no close(), no
    # interpreter shutdown, no buffer flushing at exit.
    script = textwrap.dedent(
        f"""
        import os, signal, math
        from pytest_avscenario.report.table import ErrorTable
        t = ErrorTable({str(tmp_path)!r})
        for i in range(5):
            t.append({{"test": "t::a", "sampler": "random", "index": i, "seed": i,
                       "origin": "sampled", "params": {{"x": i / 10}},
                       "rho": {{"d": -1.0 if i == 4 else math.inf}},
                       "verdict": "fail" if i == 4 else "pass", "sim_time_s": 0.1}})
        os.kill(os.getpid(), signal.SIGKILL)
        """
    )
    proc = subprocess.run([sys.executable, "-c", script], cwd=os.getcwd(), capture_output=True)
    assert proc.returncode == -9, proc.stderr.decode()
    rows = read_rows(tmp_path)
    assert [r.index for r in rows] == [0, 1, 2, 3, 4]
    assert rows[0].rho["d"] == math.inf and rows[4].rho["d"] == -1.0
    (csv_file,) = (tmp_path / "tables").glob("*.csv")
    assert len(read_csv_rows(csv_file)) == 5


def test_infinities_round_trip_through_jsonl_and_csv(tmp_path):
    rho = {"distance": -math.inf, "ttc": math.inf, "progress": 0.1 + 0.2, "lane": np.float64(-0.25)}
    with ErrorTable(tmp_path) as table:
        table.append(make_row(rho=rho))
        csv_path = table.csv_path(FOLLOW)
    text = (tmp_path / "errors.jsonl").read_text()
    json.loads(text)  # strict JSON: no bare Infinity
    assert "Infinity" not in text and '"-inf"' in text
    (back,) = read_rows(tmp_path)
    assert back.rho == {"distance": -math.inf, "ttc": math.inf, "progress": 0.1 + 0.2, "lane": -0.25}
    (from_csv,) = read_csv_rows(csv_path)
    assert from_csv["rho"] == back.rho  # bit-identical floats, inf included
    assert from_csv["params"] == {"gap": 10.0, "weather": "dry"}


def test_shrink_candidates_go_to_their_own_table(tmp_path):
    with ErrorTable(tmp_path) as table:
        for i in range(3):
            table.append(make_row(index=i))
        table.append(make_row(index=2, origin="shrink", params={"gap": 20.0, "weather": "dry"}))
        assert table.counts == {"main": 3, "shrink": 1}
    assert [r.origin for r in read_rows(tmp_path)] == ["sampled"] * 3
    assert [r.params["gap"] for r in read_rows(tmp_path, shrink=True)] == [20.0]
    names = sorted(p.name for p in (tmp_path / "tables").iterdir())
    slug = file_slug(FOLLOW)
    assert names == [f"{slug}.csv", f"{slug}.shrink.csv"]


def test_each_test_gets_a_csv_with_its_own_columns(tmp_path):
    with ErrorTable(tmp_path) as table:
        table.append(make_row())
        table.append(make_row(test=PED, params={"wait_s": 2.0}, rho={"distance": 3.0}))
        paths = {t: table.csv_path(t) for t in (FOLLOW, PED)}
    with open(paths[FOLLOW], newline="") as fh:
        header = next(csv.reader(fh))
    assert header[:9] == ["test", "item", "sampler", "index", "seed", "origin", "verdict", "sim_time_s", "error"]
    assert header[9:] == ["param.gap", "param.weather", "rho.distance", "rho.ttc"]
    with open(paths[PED], newline="") as fh:
        assert next(csv.reader(fh))[9:] == ["param.wait_s", "rho.distance"]
    # The combined JSONL holds both tests.
    assert [r.test for r in read_rows(tmp_path)] == [FOLLOW, PED]


def test_a_new_column_widens_the_csv_without_losing_rows(tmp_path):
    with ErrorTable(tmp_path) as table:
        table.append(make_row(index=0, rho={"distance": 1.0}))
        table.append(make_row(index=1, rho={}, verdict="error", error="simulator crashed"))
        table.append(make_row(index=2, rho={"distance": -1.0, "ttc": 0.5}))
        table.append(make_row(index=3, rho={"distance": 2.0, "ttc": math.inf}))
        path = table.csv_path(FOLLOW)
    with open(path, newline="") as fh:
        recs = list(csv.DictReader(fh))
    assert [r["rho.ttc"] for r in recs] == ["", "", "0.5", "inf"]
    assert recs[1]["error"] == "simulator crashed" and recs[1]["rho.distance"] == ""
    assert [r["param.gap"] for r in recs] == ["10.0", "11.0", "12.0", "13.0"]


def test_awkward_values_stay_valid_csv_and_json(tmp_path):
    nasty = 'a,"b"\n<script>alert(1)</script>'
    params = {"label": nasty, "lane": np.int64(2), "flag": np.bool_(True), "route": ["a", "b"]}
    with ErrorTable(tmp_path) as table:
        table.append(make_row(test="t.py::test[<x>,y]", params=params))
        path = table.csv_path("t.py::test[<x>,y]")
    (back,) = read_rows(tmp_path)
    assert back.params == {"label": nasty, "lane": 2, "flag": True, "route": ["a", "b"]}
    assert back.test == "t.py::test[<x>,y]"
    (rec,) = read_csv_rows(path)
    assert rec["params"]["label"] == nasty and rec["params"]["route"] == '["a", "b"]'
    assert "<" not in path.name and "," not in path.name


@pytest.mark.parametrize(
    "change, match",
    [
        ({"verdict": "ok"}, "verdict"),
        ({"origin": "random"}, "origin"),
        ({"rho": [1.0]}, "mappings"),
    ],
)
def test_a_malformed_row_is_refused_naming_the_problem(tmp_path, change, match):
    with pytest.raises(ValueError, match=match):
        CaseRow.from_json(make_row(**change))
    bad = make_row()
    del bad["params"]
    with pytest.raises(ValueError, match="params"):
        ErrorTable(tmp_path).append(bad)


def test_row_json_round_trip_for_transport():
    row = make_row(rho={"ttc": math.inf, "d": -math.inf})
    data = CaseRow.from_json(row).to_json()
    wire = json.dumps(data, allow_nan=False)  # what an xdist worker sends
    assert CaseRow.from_json(json.loads(wire)).rho == {"ttc": math.inf, "d": -math.inf}
    assert CaseRow.from_json(json.loads(wire)) == CaseRow.from_json(row)


def test_reader_tolerates_only_a_torn_last_line(tmp_path):
    with ErrorTable(tmp_path) as table:
        table.append(make_row(index=0))
        table.append(make_row(index=1))
    path = tmp_path / "errors.jsonl"
    good = path.read_text()
    path.write_text(good + '{"test": "half a ro')
    with pytest.warns(UserWarning, match="truncated"):
        assert len(read_rows(tmp_path)) == 2
    lines = good.splitlines(keepends=True)
    path.write_text(lines[0] + "garbage\n" + lines[1])
    with pytest.raises(ValueError, match=":2:"):
        read_rows(tmp_path)


def test_atomic_write_replaces_whole_files(tmp_path):
    target = tmp_path / "sub" / "summary.json"
    atomic_write_text(target, "old")
    atomic_write_text(target, "new")
    assert target.read_text() == "new"
    with pytest.raises(AttributeError):
        atomic_write_text(target, None)  # fails while writing the temporary file
    assert target.read_text() == "new"
    assert sorted(p.name for p in target.parent.iterdir()) == ["summary.json"]


def test_a_new_run_starts_from_empty_tables_and_keeps_user_files(tmp_path):
    with ErrorTable(tmp_path) as table:
        table.append(make_row())
    (tmp_path / "notes.txt").write_text("mine")
    prepare_report_dir(tmp_path)
    assert not (tmp_path / "tables").exists() and not (tmp_path / "errors.jsonl").exists()
    assert (tmp_path / "notes.txt").read_text() == "mine"
    # A report directory pointed at a project: its own tables/ and plots/ survive.
    (tmp_path / "tables").mkdir()
    (tmp_path / "tables" / "budget.csv").write_text("x")
    (tmp_path / "plots").mkdir()
    (tmp_path / "plots" / "figure-1.png").write_text("x")
    with ErrorTable(tmp_path) as table:
        table.append(make_row())
    prepare_report_dir(tmp_path)
    assert sorted(p.name for p in (tmp_path / "tables").iterdir()) == ["budget.csv"]
    assert (tmp_path / "plots" / "figure-1.png").exists()
    with ErrorTable(tmp_path) as table:
        table.append(make_row(index=5))
    assert [r.index for r in read_rows(tmp_path)] == [5]


def test_slugs_are_distinct_for_distinct_tests():
    a, b = file_slug("x/test_a.py::test[1]"), file_slug("y/test_a.py::test[1]")
    assert a != b and a.startswith("test_a.py-test-1")


@pytest.mark.parametrize("fsync", [False, True])
def test_fsync_is_opt_in_and_covers_both_files(tmp_path, monkeypatch, fsync):
    calls = []
    real = os.fsync
    monkeypatch.setattr(os, "fsync", lambda fd: (calls.append(fd), real(fd)))
    with ErrorTable(tmp_path, fsync=fsync) as table:
        table.append(make_row(index=0))
        calls.clear()
        table.append(make_row(index=1))
        assert len(calls) == (2 if fsync else 0)  # per row: the JSONL and the test's CSV


def test_rows_already_in_json_form_are_accepted(tmp_path):
    wire = CaseRow.from_json(make_row(rho={"ttc": math.inf, "distance": -2.0})).to_json()
    assert wire["rho"]["ttc"] == "inf"
    with ErrorTable(tmp_path) as table:
        back = table.append(wire)
    assert back.rho == {"ttc": math.inf, "distance": -2.0}
    assert read_rows(tmp_path)[0].rho["ttc"] == math.inf


def test_only_our_names_listed_in_the_manifest_are_ever_deleted(tmp_path):
    report = tmp_path / "rep"
    with ErrorTable(report) as table:
        table.append(make_row())
    (report / "notes.txt").write_text("mine")
    (tmp_path / "outside.txt").write_text("mine")
    manifest = json.loads((report / ".avs-manifest.json").read_text())
    assert sorted(manifest["files"]) == ["errors.jsonl", "shrink.jsonl", f"tables/{file_slug(make_row()['test'])}.csv"]
    # a hand-edited manifest cannot make a run delete somebody else's file
    manifest["files"] += ["notes.txt", "../outside.txt", "/etc/hostname"]
    (report / ".avs-manifest.json").write_text(json.dumps(manifest))
    prepare_report_dir(report)
    assert not (report / "errors.jsonl").exists() and not (report / "tables").exists()
    assert (report / "notes.txt").read_text() == "mine" and (tmp_path / "outside.txt").read_text() == "mine"


def test_a_table_that_cannot_be_opened_leaks_no_file_handle(tmp_path):
    # the shrink table's path is taken (by a folder): opening fails after errors.jsonl opened
    import gc
    import warnings

    from pytest_avscenario.report.table import ErrorTable

    (tmp_path / "shrink.jsonl").mkdir()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        with pytest.raises(OSError):
            ErrorTable(tmp_path)
        gc.collect()
    assert not [w for w in caught if issubclass(w.category, ResourceWarning)]

"""The replay database (pytest_avscenario.db): round trips, robustness to bad files,
atomicity under concurrent writers, and the xdist snapshot."""

from __future__ import annotations

import json
import math
import multiprocessing
import os
import re
import sys

import numpy as np
import pytest

from pytest_avscenario.db import FORMAT, DatabaseError, ReplayDB, entry_name, space_changes
from pytest_avscenario.space import Choice, FeatureSpace, IntRange, Uniform

TEST = "tests/test_follow.py::test_vehicle_following"
VERSIONS = {"pytest-avscenario": "0.1.0", "highway-env": "1.12.1"}


def space():
    return FeatureSpace({
        "gap": Uniform(10.0, 40.0, nominal=30.0),
        "lanes": IntRange(1, 4),
        "road": Choice(["dry", "wet"]),
        "length": 400,
    })


PARAMS = {"gap": 12.25, "lanes": 3, "road": "wet", "length": 400}
RHO = {"distance": -1.5, "ttc": math.inf, "progress": 0.1, "reaches": -math.inf}


def save(db, params=PARAMS, test=TEST, **kw):
    args = dict(rho=RHO, seed=1234, space=space(), minimized=True, versions=VERSIONS)
    args.update(kw)
    return db.save(test, params, **args)


def test_round_trip_including_infinities(tmp_path):
    db = ReplayDB(tmp_path / ".avscenario")
    saved = save(db)
    assert saved.path.parent == tmp_path / ".avscenario" and saved.path.exists()
    text = saved.path.read_text()
    assert '"inf"' in text and '"-inf"' in text and "Infinity" not in text

    (entry,) = ReplayDB(tmp_path / ".avscenario").entries()
    assert entry == saved
    assert entry.params == PARAMS and entry.rho == RHO
    assert entry.seed == 1234 and entry.minimized is True and entry.versions == VERSIONS
    assert entry.fingerprint == space().fingerprint() and entry.format == FORMAT
    assert FeatureSpace.from_description(entry.space).fingerprint() == entry.fingerprint
    assert ReplayDB(tmp_path / ".avscenario").warnings == []


def test_numpy_values_are_stored_as_plain_json(tmp_path):
    db = ReplayDB(tmp_path)
    params = {"gap": np.float64(12.25), "lanes": np.int64(3), "road": "wet", "length": 400}
    e = save(db, params=params, rho={"distance": np.float32(-0.5)})
    assert e.path.name == entry_name(TEST, PARAMS)
    (loaded,) = db.entries()
    assert loaded.params == PARAMS and type(loaded.params["lanes"]) is int


def test_save_is_idempotent(tmp_path):
    db = ReplayDB(tmp_path)
    first = save(db)
    again = save(db)
    assert again.path == first.path and again.created == first.created
    assert len(db.entries()) == 1 and len(list(tmp_path.iterdir())) == 1
    # another case, or the same case of another test, is another entry
    save(db, params=dict(PARAMS, gap=13.0))
    save(db, test=TEST + "_other")
    assert len(db.entries()) == 3 and len(db.entries(TEST)) == 2


def test_order_is_oldest_first_then_by_name(tmp_path):
    db = ReplayDB(tmp_path)
    paths = []
    for i, created in enumerate([30.0, 10.0, 20.0, 10.0]):
        e = save(db, params=dict(PARAMS, gap=11.0 + i))
        data = json.loads(e.path.read_text())
        data["created"] = created
        e.path.write_text(json.dumps(data))
        paths.append((created, e.path.name))
    assert [e.path.name for e in ReplayDB(tmp_path).entries()] == [n for _, n in sorted(paths)]


def test_delete(tmp_path):
    db = ReplayDB(tmp_path)
    keep, gone = save(db), save(db, params=dict(PARAMS, gap=13.0))
    db.delete(gone)
    assert not gone.path.exists() and keep.path.exists()
    assert db.entries() == [keep]
    db.delete(gone)  # already deleted (e.g. by another worker): fine


def write(tmp_path, name, content: bytes | str):
    p = tmp_path / name
    p.write_bytes(content if isinstance(content, bytes) else content.encode())
    return p


def test_bad_files_are_skipped_with_one_warning_each_and_left_on_disk(tmp_path):
    db = ReplayDB(tmp_path)
    good = save(db)
    full = good.path.read_text()
    other = json.loads(full)
    other["format"] = FORMAT + 1
    other_name = entry_name(TEST, dict(PARAMS, gap=20.0))
    other["params"] = dict(PARAMS, gap=20.0)
    bad = {
        "corrupt": write(tmp_path, "aaaaaaaaaaaa-00000000000000000001.json", "{not json"),
        "truncated": write(tmp_path, "aaaaaaaaaaaa-00000000000000000002.json", full[: len(full) // 2]),
        "empty": write(tmp_path, "aaaaaaaaaaaa-00000000000000000003.json", ""),
        "foreign": write(tmp_path, "aaaaaaaaaaaa-00000000000000000004.json", '{"name": "x"}'),
        "version": write(tmp_path, other_name, json.dumps(other)),
        "nan": write(tmp_path, "aaaaaaaaaaaa-00000000000000000005.json",
                     full.replace('"progress": 0.1', '"progress": NaN')),
        "binary": write(tmp_path, "aaaaaaaaaaaa-00000000000000000006.json", b"\xff\xfe\x00"),
        "renamed": write(tmp_path, "aaaaaaaaaaaa-00000000000000000007.json", full),
    }
    ignored = write(tmp_path, "notes.json", "{}")  # not our name pattern: silently ignored

    assert db.entries() == [good]
    assert len(db.warnings) == len(bad)
    for kind, path in bad.items():
        (msg,) = [w for w in db.warnings if str(path) in w]
        assert path.exists(), kind
    (version_msg,) = [w for w in db.warnings if str(bad["version"]) in w]
    assert f"version {FORMAT + 1}" in version_msg
    assert any("NaN" in w for w in db.warnings)

    db.entries()
    db.entries(TEST)
    assert len(db.warnings) == len(bad)  # each file reported once
    assert ignored.exists() and not any("notes.json" in w for w in db.warnings)


def test_symlinks_are_not_followed(tmp_path):
    secret = tmp_path / "secret.txt"
    secret.write_text("top secret")
    d = tmp_path / "db"
    d.mkdir()
    link = d / "aaaaaaaaaaaa-00000000000000000001.json"
    link.symlink_to(secret)
    db = ReplayDB(d)
    assert db.entries() == []
    assert len(db.warnings) == 1 and "regular file" in db.warnings[0]
    assert "top secret" not in db.warnings[0]


def test_paths_come_from_hashes_never_from_content(tmp_path):
    db = ReplayDB(tmp_path / "db")
    evil_test = "../../../etc/passwd::test_x"
    e = save(db, test=evil_test, params=dict(PARAMS, road="wet"))
    assert e.path.parent == tmp_path / "db"
    assert not (tmp_path / "etc").exists()
    # content naming another path is just data
    data = json.loads(e.path.read_text())
    data["path"] = str(tmp_path / "victim.json")
    e.path.write_text(json.dumps(data))
    victim = tmp_path / "victim.json"
    victim.write_text("keep me")
    (loaded,) = db.entries()
    assert loaded.path == e.path
    db.delete(loaded)
    assert victim.read_text() == "keep me"


def test_a_directory_that_is_a_file(tmp_path):
    f = tmp_path / ".avscenario"
    f.write_text("oops")
    with pytest.raises(DatabaseError, match=r"\.avscenario.*not a directory"):
        ReplayDB(f)
    with pytest.raises(DatabaseError, match="is a file"):
        ReplayDB(f / "sub")
    assert issubclass(DatabaseError, OSError)


@pytest.mark.skipif(sys.platform == "win32" or os.geteuid() == 0,
                    reason="root ignores directory permissions")
def test_an_unwritable_directory(tmp_path):
    d = tmp_path / "ro"
    d.mkdir()
    d.chmod(0o555)
    try:
        with pytest.raises(DatabaseError, match="cannot write"):
            save(ReplayDB(d))
    finally:
        d.chmod(0o755)


def test_an_unwritable_directory_via_a_file_parent(tmp_path):
    # what root cannot bypass: the database path runs through a file
    db = ReplayDB(tmp_path / "db")
    (tmp_path / "db").write_text("now a file")
    with pytest.raises(DatabaseError, match="db"):
        save(db)


def test_no_directory_until_the_first_save(tmp_path):
    db = ReplayDB(tmp_path / ".avscenario")
    assert db.entries() == [] and db.warnings == []
    assert not (tmp_path / ".avscenario").exists()


def _writer(directory: str, worker: int, n: int) -> None:
    db = ReplayDB(directory)
    for i in range(n):
        # every worker also writes the shared cases 0..9: same files, concurrently
        gap = 10.0 + (i if i < 10 else 100 * worker + i) / 1000
        db.save(TEST, dict(PARAMS, gap=gap), RHO, i, space(), False, VERSIONS)
        db.entries()


def test_concurrent_writers(tmp_path):
    ctx = multiprocessing.get_context("spawn" if sys.platform == "win32" else "fork")
    procs = [ctx.Process(target=_writer, args=(str(tmp_path), w, 60)) for w in range(3)]
    for p in procs:
        p.start()
    for p in procs:
        p.join(60)
        assert p.exitcode == 0
    db = ReplayDB(tmp_path)
    entries = db.entries()
    assert db.warnings == []
    assert len(entries) == 10 + 3 * 50
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(e.path.name for e in entries)


def test_snapshot_round_trip(tmp_path):
    db = ReplayDB(tmp_path)
    save(db)
    save(db, params=dict(PARAMS, gap=13.0), rho={"distance": -0.25})
    data = db.snapshot()
    json.dumps(data, allow_nan=False)  # plain JSON, as xdist ships it

    worker = ReplayDB.from_snapshot(tmp_path, json.loads(json.dumps(data)))
    assert worker.entries() == db.entries()
    assert worker.entries(TEST) == db.entries(TEST)
    # the snapshot is fixed: files written later do not change what workers collect
    save(db, params=dict(PARAMS, gap=14.0))
    assert len(worker.entries()) == 2
    # writes still go to disk
    e = worker.save(TEST, dict(PARAMS, gap=15.0), RHO, 1, space(), False, VERSIONS)
    assert e.path.exists() and len(ReplayDB(tmp_path).entries()) == 4


def test_snapshot_items_are_validated_and_paths_recomputed(tmp_path):
    db = ReplayDB(tmp_path)
    good = save(db).to_json()
    evil = dict(good, path="/etc/passwd")
    worker = ReplayDB.from_snapshot(tmp_path, [evil, {"kind": "x"}, 3])
    (e,) = worker.entries()
    assert e.path == tmp_path / entry_name(TEST, PARAMS)
    assert len(worker.warnings) == 2


def test_space_changes_names_the_changed_parameter():
    old = space().describe()
    new = FeatureSpace({
        "gap": Uniform(5.0, 40.0, nominal=30.0),  # changed
        "lanes": IntRange(1, 4),
        "road": Choice(["dry", "wet"]),
        "length": 400,
        "speed": Uniform(5, 15),  # added
    })
    assert space_changes(old, new) == ["gap", "speed"]
    assert space_changes(json.loads(json.dumps(old)), space()) == []
    fewer = FeatureSpace({"gap": Uniform(10.0, 40.0, nominal=30.0), "lanes": IntRange(1, 4),
                          "road": Choice(["dry", "wet"])})
    assert space_changes(old, fewer) == ["length"]


def test_replayed_values_are_the_declared_ones():
    from pytest_avscenario.db import replay_params

    sp = FeatureSpace({"gap": Uniform(10.0, 40.0), "lanes": IntRange(1, 4),
                       "pair": Choice([(1, 2), (3, 4)]), "speed": Choice([5.0, 10.0]),
                       "length": 400})
    # as JSON gives them back: ints for floats, the constant dropped; a tuple option is
    # declared as the list it is stored and replayed as (the space keeps JSON values)
    got = replay_params(sp, {"gap": 12, "lanes": 3.0, "pair": [3, 4], "speed": 10})
    assert got == {"gap": 12.0, "lanes": 3, "pair": [3, 4], "speed": 10.0, "length": 400}
    assert [type(v) for v in got.values()] == [float, int, list, float, int]
    assert list(got) == list(sp.names)  # declaration order
    for bad, why in [({"lanes": 2.5}, "'lanes'=2.5 is not an integer"),
                     ({"lanes": 9}, "'lanes'=9 lies outside IntRange"),
                     ({"pair": [4, 3]}, "'pair'=[4, 3] is not one of the options"),
                     ({"speed": True}, "'speed'=True is not one of the options"),
                     ({"length": 401}, "'length'=401 is not the declared constant 400"),
                     ({"gap": float("inf")}, "'gap'=inf lies outside")]:
        stored = {"gap": 12.0, "lanes": 3, "pair": [3, 4], "speed": 10.0, **bad}
        with pytest.raises(ValueError, match=re.escape(why)):
            replay_params(sp, stored)


def test_hostile_snapshot_items_are_skipped(tmp_path):
    good = save(ReplayDB(tmp_path)).to_json()
    deep: list = []
    for _ in range(5000):
        deep = [deep]
    worker = ReplayDB.from_snapshot(tmp_path, [dict(good, params={"gap": deep}),
                                               dict(good, seed=-1), dict(good, created=10**400)])
    assert worker.entries() == []
    assert len(worker.warnings) == 3
    assert "nested too deeply" in worker.warnings[0] and "'seed' -1" in worker.warnings[1]

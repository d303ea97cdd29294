"""One stored file per counterexample: the replay database does not gather near-duplicates.

Minimizing several failing samples of one failure lands each just past the same boundary, a
few millimetres apart; every run of the same command minimized them again and, before, stored
each as a file of its own (the example suite's database grew from 35 to 53 files over
repeated runs). Now a counterexample is stored once: the same minimized parameters, one
minimized from the same sampled case, or a near-duplicate (the same metrics violated, the
same parameters departing from nominal, within 5 % of their ranges) keeps the one closest to
the nominal scenario; a database that gathered near-duplicates earlier sheds them as their
replays run; cases stored as found (shrinking off) are distinct samples and are kept each;
files that are not the plugin's entries are never touched.
"""

from __future__ import annotations

import json

import pytest

from pytest_avscenario.db import NEAR, ReplayDB, departure, near_duplicate
from pytest_avscenario.space import FeatureSpace, Uniform, Choice

# a lead at the ego's speed, closer than 20 m (centre distance) at some point of the second:
# shrinking moves each failing sample's gap toward the nominal 35 m until just below 20 m
# (speed goes back to its nominal)
TOO_CLOSE = """
from pytest_avscenario import scenario, Uniform
from pytest_avscenario.monitors import distance

@scenario(gap=Uniform(10.0, 40.0, nominal=35.0, unit="m"), speed=Uniform(5.0, 15.0, nominal=10.0),
          samples=8, monitors=[distance(20.0, kind="centre")])
def test_gap(case, world):
    road = world.straight_road(lanes=1, length=200)
    world.ego(road.lane(0), s=10.0, speed=case.speed)
    world.car(road.lane(0), s=10.0 + case.gap, speed=case.speed, name="lead")
    world.run(seconds=0.5)
"""

ARGS = ("--avs-seed=1", "--avs-shrink-budget=8", "--avs-reference-driver=none", "--avs-export=none",
        "--avs-case-pictures=0", "-p", "no:xdist", "-p", "no:cacheprovider")


def entries(path):
    return sorted((path / ".avscenario").glob("*.json"))


def test_repeated_runs_keep_one_file_per_counterexample(pytester, monkeypatch):
    monkeypatch.setenv("COLUMNS", "200")  # the terminal table on one line per campaign
    pytester.makepyfile(test_gap=TOO_CLOSE)
    db = pytester.path / ".avscenario"
    db.mkdir()
    (db / "README.md").write_text("team notes")  # not the plugin's: never touched
    foreign = db / ("0" * 12 + "-" + "0" * 20 + ".json")  # an entry's name, someone else's JSON
    foreign.write_text('{"kind": "some other tool"}')
    first = pytester.runpytest(*ARGS)
    outcomes = first.parseoutcomes()
    assert outcomes["failed"] >= 3  # several samples below 20 m, each minimized
    stored = entries(pytester.path)
    assert foreign in stored and (db / "README.md").read_text() == "team notes"
    ours = [p for p in stored if p != foreign]
    assert len(ours) == 1, [json.loads(p.read_text())["params"] for p in ours]
    entry = json.loads(ours[0].read_text())
    assert 18.0 < entry["params"]["gap"] < 20.0 and entry["params"]["speed"] == 10.0
    assert entry["found"]["case"].startswith("halton-") and entry["found"]["params"]["gap"] < 20.0
    out = first.stdout.str()
    # each further failure says where its counterexample is kept
    assert out.count("not stored again: the replay database holds the same counterexample") \
        + out.count(", replacing ") == outcomes["failed"] - 1

    # the same command again: the stored case replays first, nothing new is stored
    again = pytester.runpytest(*ARGS)
    assert again.parseoutcomes()["failed"] == outcomes["failed"] + 1
    assert [p for p in entries(pytester.path) if p != foreign] == ours
    # the replay's campaign counts its violation among its cases, as the terminal shows it
    summary = json.loads((pytester.path / "avs-report" / "summary.json").read_text())
    replay = next(t for t in summary["tests"] if t["sampler"] == "replay")
    assert replay["samples"] == 0 and replay["counterexamples"] == 1
    assert replay["case_violations"] == {"distance": 1}
    row = next(l for l in again.outlines if l.startswith("test_gap  replay "))
    assert row.split()[2:4] == ["0", "1"]  # samples 0, Distance 1


def test_near_duplicates_stored_earlier_are_shed_as_their_replays_run(pytester):
    pytester.makepyfile(test_gap=TOO_CLOSE)
    space = FeatureSpace({"gap": Uniform(10.0, 40.0, nominal=35.0), "speed": Uniform(5.0, 15.0, nominal=10.0)})
    db = ReplayDB(pytester.path / ".avscenario")
    test = "test_gap.py::test_gap"
    # what earlier versions left: three minimized cases of one failure, and a different one
    for gap in (19.2, 19.7, 19.5):
        db.save(test, {"gap": gap, "speed": 10.0}, {"body": -1.0}, 7, space, True, {})
    other = db.save(test, {"gap": 12.0, "speed": 14.0}, {"body": -1.0}, 7, space, True, {})
    result = pytester.runpytest(*ARGS, "--avs-samples=1")  # one sample: 35 m... passes
    out = result.stdout.str()
    assert out.count("removed from the replay database: ") == 2
    left = {json.loads(p.read_text())["params"]["gap"] for p in entries(pytester.path)}
    # the one nearest the nominal 35 m stays, and the different counterexample
    assert left == {19.7, 12.0} and other.path.exists()


def test_what_counts_as_the_same_counterexample():
    space = FeatureSpace({"gap": Uniform(10.0, 40.0, nominal=35.0), "road": Choice(["dry", "wet"]),
                          "speed": Uniform(5.0, 15.0, nominal=10.0)})
    base = {"gap": 19.5, "road": "dry", "speed": 10.0}
    assert near_duplicate(space, base, {**base, "gap": 19.5 + 30 * NEAR * 0.9})
    assert not near_duplicate(space, base, {**base, "gap": 19.5 + 30 * NEAR * 1.1})
    assert not near_duplicate(space, base, {**base, "road": "wet"})  # another category
    # departing from nominal in another parameter is another counterexample, however slightly
    assert not near_duplicate(space, base, {**base, "speed": 10.01})
    assert departure(space, {"gap": 35.0, "road": "dry", "speed": 10.0}) == 0.0
    assert departure(space, base) == pytest.approx(15.5 / 30)
    assert departure(space, {**base, "road": "wet"}) == pytest.approx(15.5 / 30 + 1)


def test_store_keeps_the_closer_case_and_never_deletes_what_is_not_an_entry(tmp_path):
    space = FeatureSpace({"gap": Uniform(10.0, 40.0, nominal=35.0)})
    db = ReplayDB(tmp_path)
    t = "t.py::test_gap"
    far = db.store(t, {"gap": 19.0}, {"d": -1.0}, 1, space, True, {}, {"case": "halton-001", "params": {"gap": 11.0}})
    assert far.written and not far.replaced
    # nearer the nominal: replaces the farther one
    near = db.store(t, {"gap": 19.6}, {"d": -1.0}, 2, space, True, {}, {"case": "halton-004", "params": {"gap": 15.0}})
    assert near.written and near.replaced == (far.entry.path,) and not far.entry.path.exists()
    # farther again: not stored, the nearer one named
    again = db.store(t, {"gap": 19.1}, {"d": -1.0}, 3, space, True, {}, {"case": "halton-009", "params": {"gap": 12.0}})
    assert not again.written and again.entry.path == near.entry.path
    # other metrics violated: another counterexample, stored beside it
    ttc = db.store(t, {"gap": 19.1}, {"d": -1.0, "ttc": -0.5}, 3, space, True, {}, None)
    assert ttc.written and not ttc.replaced
    # minimized from the same sampled case (same id, values and seed) to a far point: the same
    # counterexample even beyond NEAR; the closer one stays
    same = db.store(t, {"gap": 14.0}, {"d": -1.0}, 2, space, True, {}, {"case": "halton-004", "params": {"gap": 15.0}})
    assert not same.written and same.entry.path == near.entry.path
    # cases stored as found (not minimized) are distinct samples, however near: kept each
    a = db.store(t, {"gap": 30.0}, {"d": -1.0}, 8, space, False, {}, {"case": "halton-020", "params": {"gap": 30.0}})
    b = db.store(t, {"gap": 30.2}, {"d": -1.0}, 9, space, False, {}, {"case": "halton-021", "params": {"gap": 30.2}})
    assert a.written and b.written and a.entry.path.exists() and not b.replaced
    # an entry-shaped name holding someone else's file is not an entry: never deleted
    alien = tmp_path / ("f" * 12 + "-" + "f" * 20 + ".json")
    alien.write_text(json.dumps({"kind": "pytest-avscenario counterexample", "format": 1, "test": t,
                                 "params": {"gap": 19.05}, "rho": {"d": -1.0}, "seed": 1,
                                 "fingerprint": space.fingerprint(), "space": {}, "minimized": True,
                                 "versions": {}, "created": 0.0}))  # its name does not match it
    db.store(t, {"gap": 19.8}, {"d": -1.0}, 5, space, True, {}, None)
    assert alien.exists()

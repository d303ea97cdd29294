"""Stable case identities: with a fixed seed, an active sampler's `test_x[mab-007]` is the same
parameters and seed in every order and process — serial, reversed, shuffled, under xdist, and
re-run alone with -k or --lf."""

import json

import pytest

# A cheap bandit campaign: rho depends on the parameters, so what the sampler learns changes
# what it asks next; about a third of the space fails.
SCENARIO = """
from pytest_avscenario import scenario, Uniform, IntRange
from pytest_avscenario.monitors import distance
from pytest_avscenario.trajectory import Trajectory

@scenario(x=Uniform(0, 1), lane=IntRange(0, 3), samples=16, sampler="mab",
          monitors=[distance(5.0, kind="centre")])
def test_bandit(case):
    gap = 3.0 + 12.0 * case.x + case.lane
    return Trajectory.from_arrays([0.0, 0.1], {
        "ego": {"x": [0.0, 0.0], "y": [0.0, 0.0]},
        "other": {"x": [gap, gap], "y": [3.0, 3.0]},
    })
"""

REVERSE = """
def pytest_collection_modifyitems(items):
    items.reverse()
"""

SHUFFLE = """
import random
def pytest_collection_modifyitems(items):
    random.Random(3).shuffle(items)
"""


def _rows(pytester, report="avs-report"):
    rows = [json.loads(l) for l in (pytester.path / report / "errors.jsonl").read_text().splitlines()]
    return {r["item"]: (r["params"], r["seed"], r["rho"], r["verdict"]) for r in rows}


def _run(pytester, *args, subprocess=False):
    base = ["--avs-db=none", "--avs-seed=5", "--avs-shrink-budget=0", "-p", "no:randomly", *args]
    return (pytester.runpytest_subprocess if subprocess else pytester.runpytest)(*base)


@pytest.fixture
def serial(pytester):
    pytester.makepyfile(test_b=SCENARIO)
    _run(pytester, "-p", "no:cacheprovider")
    rows = _rows(pytester)
    assert len(rows) == 16 and any(v[3] == "fail" for v in rows.values())
    return rows


@pytest.mark.parametrize("order", [REVERSE, SHUFFLE], ids=["reversed", "shuffled"])
def test_any_order_gives_every_id_the_same_case(pytester, serial, order):
    pytester.makeconftest(order)
    _run(pytester, "-p", "no:cacheprovider")
    assert _rows(pytester) == serial


@pytest.mark.parametrize("dist", ["load", "worksteal", "loadscope", "loadfile"])
def test_xdist_gives_every_id_the_same_case(pytester, serial, dist):
    pytest.importorskip("xdist")
    _run(pytester, "-n", "2", f"--dist={dist}", "-p", "no:cacheprovider", subprocess=True)
    assert _rows(pytester) == serial


def test_an_id_run_alone_is_the_same_case(pytester, serial):
    late = "test_b.py::test_bandit[mab-013]"
    # no cache: the cases before it are simulated first, in order
    _run(pytester, late, "-p", "no:cacheprovider")
    assert _rows(pytester, "avs-report/rerun") == {late: serial[late]}


def test_last_failed_re_runs_each_failure_with_its_values(pytester, serial):
    first = _run(pytester)  # with the cache: it keeps the values drawn
    assert _rows(pytester) == serial
    failed = {k for k, v in serial.items() if v[3] == "fail"}
    assert first.parseoutcomes()["failed"] == len(failed)
    again = _run(pytester, "--lf")
    assert set(_rows(pytester, "avs-report/rerun")) == failed
    assert _rows(pytester, "avs-report/rerun") == {k: serial[k] for k in failed}
    assert _rows(pytester) == serial  # the campaign's report stays
    assert again.parseoutcomes()["failed"] == len(failed)  # no failure turned into a pass


def test_the_rerun_command_names_no_parameters(pytester, serial):
    result = _run(pytester, "-p", "no:cacheprovider")
    lines = [l for l in result.outlines if "re-run only this case:" in l]
    assert lines and all("--avs-params" not in l for l in lines)

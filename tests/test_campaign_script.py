"""A campaign runs from a plain script: ``run_campaign`` drives the same pipeline as the
plugin and gives the same rows — case ids, parameters, verdicts, rho, minimized values — as
``pytest --avs-seed=N`` on the same test, with nothing collected by pytest."""

import json
import subprocess
import sys

import pytest

# an active sampler (its case order is the campaign's own), failures minimized, and a world
# driven by the autopilot into a stopped car
SCENARIOS = """
from pytest_avscenario import scenario, Uniform, IntRange, Choice
from pytest_avscenario.monitors import collision, distance
from pytest_avscenario.sim import behaviors as b
from pytest_avscenario.trajectory import Trajectory

@scenario(x=Uniform(0, 1), lane=IntRange(0, 3), samples=8, sampler="mab",
          monitors=[distance(8.0, kind="centre")], shrink_budget=3)
def test_bandit(case):
    gap = 3.0 + 12.0 * case.x + case.lane
    return Trajectory.from_arrays([0.0, 0.1], {
        "ego": {"x": [0.0, 0.0], "y": [0.0, 0.0]},
        "other": {"x": [gap, gap], "y": [3.0, 3.0]},
    })

@scenario(gap=Choice([8.0, 120.0]), samples=2, monitors=[collision()], shrink_budget=0,
          reference_driver="none")
def test_stopped(case, world):
    road = world.straight_road(lanes=1, length=400)
    world.ego(road.lane(0), s=20.0, speed=20.0)
    world.car(road.lane(0), s=20.0 + case.gap, speed=0.0, behavior=b.stopped(), name="stopped")
    world.run(seconds=4)
"""

# a plain script: imports the test module and runs both campaigns, printing their rows
SCRIPT = """
import json, sys
sys.path.insert(0, ".")
from pytest_avscenario.campaign import run_campaign
import test_av

rows = []
for func in (test_av.test_bandit, test_av.test_stopped):
    rows += [r.to_json() for r in run_campaign(func, seed=7, rootdir=".")]
loaded = sorted(m for m in sys.modules if m.startswith("pytest_avscenario.pytest_plugin"))
print(json.dumps({"rows": rows, "plugin": loaded}))
"""

KEYS = ("item", "sampler", "index", "seed", "origin", "params", "verdict", "rho", "minimized",
        "shrink_sims", "flaky", "violations")


def _same(row):
    return {k: row.get(k) for k in KEYS}


def test_a_script_gets_the_rows_pytest_gets(pytester):
    pytester.makepyfile(test_av=SCENARIOS)
    result = pytester.runpytest("--avs-seed=7", "--avs-db=none", "-p", "no:cacheprovider",
                                "-p", "no:randomly")
    outcomes = result.parseoutcomes()
    assert outcomes["failed"] >= 2 and outcomes["passed"] >= 2 and "errors" not in outcomes
    table = pytester.path / "avs-report" / "errors.jsonl"
    by_pytest = [json.loads(line) for line in table.read_text().splitlines()]
    (pytester.path / "script.py").write_text(SCRIPT)
    proc = subprocess.run([sys.executable, "script.py"], cwd=pytester.path, capture_output=True,
                          text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr
    out = json.loads(proc.stdout.splitlines()[-1])
    assert out["plugin"] == []  # the script ran no part of the plugin
    by_script = out["rows"]
    assert sorted(r["item"] for r in by_script) == sorted(r["item"] for r in by_pytest)
    assert {r["item"]: _same(r) for r in by_script} == {r["item"]: _same(r) for r in by_pytest}
    # what is compared is not trivially equal: the campaigns fail, and failures were minimized
    assert {r["verdict"] for r in by_script} == {"pass", "fail"}
    assert any(r.get("minimized") for r in by_script)


def test_the_comparison_sees_another_seed(pytester):
    # negative control: the script's rows with another seed are not pytest's
    pytester.makepyfile(test_av=SCENARIOS.split("@scenario(gap")[0])
    pytester.runpytest("--avs-seed=7", "--avs-db=none", "-p", "no:cacheprovider")
    table = pytester.path / "avs-report" / "errors.jsonl"
    by_pytest = {r["item"]: _same(r) for r in map(json.loads, table.read_text().splitlines())}
    script = SCRIPT.replace("seed=7", "seed=8").replace(", test_av.test_stopped", ",")
    (pytester.path / "script.py").write_text(script)
    proc = subprocess.run([sys.executable, "script.py"], cwd=pytester.path, capture_output=True,
                          text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr
    by_script = {r["item"]: _same(r) for r in json.loads(proc.stdout.splitlines()[-1])["rows"]}
    assert set(by_script) == set(by_pytest) and by_script != by_pytest


def test_a_script_is_told_which_argument_it_cannot_provide(pytester):
    from pytest_avscenario.campaign import run_campaign
    from pytest_avscenario.campaign.settings import DeclarationError

    pytester.makepyfile(test_fx="""
        from pytest_avscenario import scenario, Uniform

        @scenario(x=Uniform(0, 1), samples=2)
        def test_fx(case, tmp_path):
            pass
    """)
    sys.path.insert(0, str(pytester.path))
    try:
        import test_fx
    finally:
        sys.path.remove(str(pytester.path))
        sys.modules.pop("test_fx", None)
    with pytest.raises(DeclarationError, match="test_fx.py::test_fx: run_campaign provides only case, "
                                        "world, avs_driver; the function also takes tmp_path"):
        run_campaign(test_fx.test_fx, rootdir=pytester.path)

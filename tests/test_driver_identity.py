"""The driver under test is recorded wherever a run's results go — the pytest header, the
terminal section, summary.json, the JUnit suite properties, the index and each card — so a
run of one stack is never compared with another's unawares (issue #33, item 3)."""

import hashlib
import json
import shutil

import pytest

from pytest_avscenario.report.junit import read_properties
from pytest_avscenario.sim.drivers.identity import describe, identity_text, same_driver

STACK = """
class MyStack:
    def act(self, observation):
        return (0.0, 0.0)   # holds its speed: runs into a standing car

class Versioned:
    def act(self, observation):
        return (0.0, 0.0)

    def describe(self):
        return {"name": "acme-planner", "kind": "object", "version": "2.3.1"}
"""

# a standing car 25-45 m ahead of an ego at 15 m/s that never brakes: a collision
CRASH = """
from pytest_avscenario import scenario, Uniform
from pytest_avscenario.monitors import collision

@scenario(gap=Uniform(25, 45), samples=2, monitors=[collision()])
def test_{name}(case, world):
    road = world.straight_road(lanes=1, length=300)
    world.ego(road.lane(0), s=20.0, speed=15.0)
    world.car(road.lane(0), s=20.0 + case.gap, speed=0.0)
    world.run(seconds=5)
"""
ARGS = ["--avs-db=none", "--avs-seed=3", "--avs-shrink-budget=0", "--avs-reference-driver=none",
        "--avs-gifs=0", "--avs-case-pictures=0", "--junitxml=junit.xml"]


def _project(pytester, **files):
    pytester.makepyfile(mystack=STACK, **files)
    pytester.makeini("[pytest]\npythonpath = .\n")


def test_an_import_path_driver_shows_in_header_terminal_summary_junit_index_and_cards(pytester):
    _project(pytester, test_crash=CRASH.format(name="crash"))
    result = pytester.runpytest("--avs-driver=mystack:MyStack", "-p", "no:xdist", *ARGS)
    result.assert_outcomes(failed=2)
    result.stdout.fnmatch_lines([
        "avscenario: driver=mystack:MyStack (from --avs-driver; an avs_driver fixture overrides it)",
        "*",
        "driver under test: mystack:MyStack (from --avs-driver)",
    ])
    report = pytester.path / "avs-report"
    summary = json.loads((report / "summary.json").read_text())
    assert summary["driver"] == {"name": "mystack:MyStack", "kind": "import", "from": "--avs-driver"}
    assert summary["tests"][0]["driver"]["name"] == "mystack:MyStack"
    suite = read_properties(pytester.path / "junit.xml")["suite"]
    assert suite["avs.driver"] == "mystack:MyStack (from --avs-driver)"
    assert (suite["avs.driver.name"], suite["avs.driver.kind"]) == ("mystack:MyStack", "import")
    assert "driver under test: mystack:MyStack (from --avs-driver)" in (report / "index.html").read_text()
    cards = sorted((report / "cases").glob("*.html"))
    assert len(cards) == 2
    assert all("driver mystack:MyStack (from --avs-driver)" in c.read_text() for c in cards)
    rows = [json.loads(line) for line in (report / "errors.jsonl").read_text().splitlines()]
    assert [r["driver"]["name"] for r in rows] == ["mystack:MyStack"] * 2


def test_the_default_driver_is_named_autopilot_from_the_default(pytester):
    _project(pytester, test_crash=CRASH.format(name="crash"))
    result = pytester.runpytest("-p", "no:xdist", *ARGS)
    result.stdout.fnmatch_lines(["avscenario: driver=autopilot (from default; an avs_driver fixture overrides it)"])
    summary = json.loads((pytester.path / "avs-report" / "summary.json").read_text())
    assert summary["driver"] == {"name": "autopilot", "kind": "builtin", "from": "default"}


@pytest.mark.parametrize("xdist", [["-p", "no:xdist"], ["-n", "2"]])
def test_a_fixture_overridden_for_some_tests_makes_per_test_drivers(pytester, xdist):
    # one folder's conftest plugs in the team's stack, the other runs the autopilot: the run
    # has several drivers, each test names its own — also from xdist workers
    _project(pytester)
    stack = pytester.mkpydir("stack")
    (stack / "conftest.py").write_text(
        "import pytest\nfrom mystack import Versioned\n\n"
        "@pytest.fixture\ndef avs_driver():\n    return Versioned()\n")
    (stack / "test_mine.py").write_text(CRASH.format(name="mine"))
    auto = pytester.mkpydir("auto")
    (auto / "test_auto.py").write_text(CRASH.format(name="auto"))
    result = pytester.runpytest(*xdist, *ARGS)
    result.stdout.fnmatch_lines(["driver under test: several: *"])
    summary = json.loads((pytester.path / "avs-report" / "summary.json").read_text())
    assert summary["driver"]["kind"] == "several"
    by_test = {t["test"]: t["driver"] for t in summary["tests"]}
    assert by_test["stack/test_mine.py::test_mine"] == {
        "name": "acme-planner", "kind": "object", "version": "2.3.1",
        "from": "avs_driver fixture (stack/conftest.py)"}
    assert by_test["auto/test_auto.py::test_auto"]["name"] == "autopilot"
    suite = read_properties(pytester.path / "junit.xml")["suite"]
    assert suite["avs.test[stack/test_mine.py::test_mine].driver"] == \
        "acme-planner (from avs_driver fixture (stack/conftest.py))"
    assert suite["avs.test[auto/test_auto.py::test_auto].driver"] == "autopilot (from default)"


def test_a_baseline_run_with_another_driver_warns_in_terminal_and_index(pytester):
    _project(pytester, test_crash=CRASH.format(name="crash"))
    pytester.runpytest("-p", "no:xdist", *ARGS)
    shutil.copy(pytester.path / "avs-report" / "summary.json", pytester.path / "main.json")
    same = pytester.runpytest("-p", "no:xdist", "--avs-baseline=main.json", *ARGS)
    assert "two different stacks" not in same.stdout.str()
    other = pytester.runpytest("-p", "no:xdist", "--avs-baseline=main.json", "--avs-driver=mystack:MyStack", *ARGS)
    other.stdout.fnmatch_lines([
        "WARNING: the baseline */main.json was run with driver autopilot, this run with "
        "mystack:MyStack: the comparison is between two different stacks",
    ])
    index = (pytester.path / "avs-report" / "index.html").read_text()
    assert "the comparison is between two different stacks" in index


def test_a_model_file_is_named_with_its_path_and_content_hash(tmp_path):
    model = tmp_path / "dqn.zip"
    model.write_bytes(b"first training run")
    first = describe(f"sb3:{model}@highway-fast-v0")
    assert first == {"name": "sb3:dqn.zip@highway-fast-v0", "kind": "sb3", "file": str(model),
                     "sha256": hashlib.sha256(b"first training run").hexdigest()[:12],
                     "env": "highway-fast-v0"}
    assert identity_text(first) == f"sb3:dqn.zip@highway-fast-v0 (sha256 {first['sha256']})"
    model.write_bytes(b"retrained, same name")
    second = describe(f"sb3:{model}@highway-fast-v0")
    assert second["sha256"] != first["sha256"]
    assert not same_driver(first, second)  # a retrained model is another driver


def test_objects_are_named_by_their_class_or_what_describe_says():
    class Stack:
        def act(self, observation):
            return (0.0, 0.0)

    def policy(observation):
        return (0.0, 0.0)

    class Broken(Stack):
        def describe(self):
            raise RuntimeError("no version file")

    assert describe(Stack())["name"].endswith("Stack") and describe(Stack())["kind"] == "object"
    assert describe(policy) == {"name": f"{__name__}.{policy.__qualname__}", "kind": "function"}
    broken = describe(Broken())
    assert broken["name"].endswith("Broken") and "no version file" in broken["describe_error"]
    assert describe("careful") == {"name": "careful", "kind": "builtin"}


def test_a_stack_out_of_process_is_named_alike_from_the_option_and_the_object():
    from pytest_avscenario.stack import OSIStack

    assert describe("osi:tcp://127.0.0.1:5555") == {"name": "osi:tcp://127.0.0.1:5555", "kind": "osi"}
    assert describe("osi+spawn:python -m mystack {address}")["kind"] == "osi"
    ident = describe(OSIStack("tcp://127.0.0.1:5555"))
    assert (ident["name"], ident["kind"]) == ("osi:tcp://127.0.0.1:5555", "osi")
    assert same_driver(ident, describe("osi:tcp://127.0.0.1:5555"))


def test_a_highway_env_agent_names_its_saved_model_file(tmp_path):
    from pytest_avscenario.sim.drivers import highway_env_agent
    from pytest_avscenario.sim.drivers.sb3 import SB3Model

    model = tmp_path / "ppo.zip"
    model.write_bytes(b"weights")
    ident = describe(highway_env_agent(SB3Model(str(model), "PPO"), env="highway-v0"))
    assert ident["kind"] == "highway_env_agent" and ident["env"] == "highway-v0"
    assert (ident["file"], ident["sha256"], ident["algorithm"]) == (
        str(model), hashlib.sha256(b"weights").hexdigest()[:12], "PPO")

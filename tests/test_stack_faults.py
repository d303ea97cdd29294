"""A stack out of process that misbehaves makes one case an error, never a hang or a lost row.

The stack is tests/data/osi_raw_stack.py (pyzmq + osi3 only) spawned by the plugin; it
misbehaves on purpose in the case ``[halton-001]`` at step 3, and every other case of the
campaign must still run and pass: the error names the case, the step and time, and what was
wrong. Each run is a few seconds at most: the per-step timeout is 0.5 s.
"""

from __future__ import annotations

import json
import sys
import time
from pathlib import Path

import pytest

pytest.importorskip("zmq")
pytest.importorskip("osi3")

from pytest_avscenario.stack import client  # noqa: E402  (before any pytester run)

RAW = Path(__file__).resolve().parent / "data" / "osi_raw_stack.py"

SCENARIO = """
from pytest_avscenario import scenario, Uniform

@scenario(gap=Uniform(30, 50), samples=3, monitors=[])
def test_drive(case, world):
    road = world.straight_road(lanes=1, length=300)
    world.ego(road.lane(0), s=10.0, speed=8.0)
    world.car(road.lane(0), s=10.0 + case.gap, speed=9.0)
    world.run(seconds=1)
"""


@pytest.fixture(autouse=True)
def _stop_stacks():
    yield
    client.stop_all()


@pytest.mark.parametrize("fault, answer, says", [
    ("hang", "motion", "*step 3 (t=0.30 s): no answer to the SensorView within 0.5 s (--avs-stack-timeout)*"),
    ("crash", "motion", "*step 3 (t=0.30 s): the stack process exited with code 3 while it was answering the SensorView*"),
    ("timestamp", "motion", "*step 3 (t=0.30 s): MotionRequest carries the wrong timestamp: 400000000 ns (0.400 s), the request's is 300000000 ns*"),
    ("error", "motion", "*step 3 (t=0.30 s): the stack answered Error: planner failed: no trajectory found*"),
    ("garbage", "motion", "*step 3 (t=0.30 s): its answer: MotionRequest: unparseable bytes*"),
    ("huge", "motion", "*step 3 (t=0.30 s): while sending the SensorView: the peer at * breaks ZeroMQ's REQ/REP: a frame of 68,157,440 bytes, more than the 67,108,864 bytes a message may have*"),
    ("type", "traffic", "*step 3 (t=0.30 s): answer to the SensorView: wrong message type b'SensorView'*"),
    ("teleport", "traffic", "*step 3 (t=0.30 s): TrafficUpdate is physically impossible: it moved 2*a teleport*"),
    ("handshake", "motion", "*step 0 (t=0.00 s): handshake failed: it speaks 'avs-osi/1' revision 1, the plugin 'avs-osi/1' revision 2; it runs at dt=0.05 s, the world steps at 0.1 s*"),
    ("nan", "traffic", "*step 3 (t=0.30 s): TrafficUpdate has a non-finite state*"),
    ("empty", "trajectory", "*step 3 (t=0.30 s): its MotionRequest's desired_trajectory: desired_trajectory has no trajectory_point*"),
    ("past", "trajectory", "*step 3 (t=0.30 s): its MotionRequest's desired_trajectory: trajectory_point[[]0[]].timestamp 200000000 ns (0.200 s) is in the past: the request's is 300000000 ns*"),
    ("nan", "trajectory", "*step 3 (t=0.30 s): its MotionRequest's desired_trajectory: trajectory_point[[]5[]] has a non-finite position (x=*, y=nan)*"),
])
def test_a_faulty_answer_is_an_error_of_its_case_and_the_others_still_run(pytester, fault, answer, says):
    pytester.makepyfile(test_faulty=SCENARIO)
    driver = (f"osi+spawn:{sys.executable} {RAW} {{address}} --answer {answer} --fault {fault} "
              "--case-suffix=-001] --at-step 3")
    start = time.monotonic()
    result = pytester.runpytest("--avs-driver", driver, "--avs-stack-timeout=0.5", "--avs-db=none",
                                "--avs-report=rep", "--avs-gifs=0", "--avs-shrink-budget=0",
                                "-p", "no:xdist", "-p", "no:cacheprovider", "-rA")
    assert time.monotonic() - start < 20
    outcomes = result.parseoutcomes()
    assert outcomes.get("passed") == 2, result.stdout.str()[-3000:]
    assert outcomes.get("failed", 0) + outcomes.get("errors", outcomes.get("error", 0)) == 1
    result.stdout.fnmatch_lines(["*SimError: in test_faulty.py::test_drive?halton-001? agent 'ego': "
                                 "OSI stack*" + says.lstrip("*")])
    result.stdout.fnmatch_lines(["ERROR test_faulty.py::test_drive?halton-001?*"])
    for ok in ("000", "002"):
        result.stdout.fnmatch_lines([f"PASSED*test_drive?halton-{ok}?*"])
    # no row is lost: the error table has all three cases, the faulty one with its error
    rows = [json.loads(line) for line in (pytester.path / "rep" / "errors.jsonl").read_text().splitlines()]
    assert sorted(r["item"][-4:-1] for r in rows) == ["000", "001", "002"]
    (bad,) = [r for r in rows if r["item"].endswith("-001]")]
    assert bad["verdict"] == "error" and "OSI stack" in bad["error"], bad


def test_a_stack_that_is_not_there_is_a_timeout_naming_the_address(pytester):
    pytester.makepyfile(test_faulty=SCENARIO.replace("samples=3", "samples=1"))
    result = pytester.runpytest("--avs-driver", "osi:ipc:///tmp/avs-osi-nobody-listens.sock",
                                "--avs-stack-timeout=0.3", "--avs-db=none", "--avs-report=none",
                                "--avs-shrink-budget=0", "-p", "no:xdist", "-p", "no:cacheprovider")
    result.stdout.fnmatch_lines(["*OSI stack ipc:///tmp/avs-osi-nobody-listens.sock, step 0 (t=0.00 s): "
                                 "no answer to the Reset of this case within 0.3 s*closed and reopened*"])

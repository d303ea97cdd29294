"""The stack-side kit: a Python driver served out of process decides exactly as in process.

``python -m pytest_avscenario.stack.autopilot ADDRESS`` serves the built-in autopilot through
:func:`pytest_avscenario.stack.serve`: each SensorView becomes the Observation the world
would have built, each command a MotionRequest the plugin's controller follows. On the
vehicle-following scenario of example_tests/test_02 (tiny campaigns) the verdicts,
robustness values and trajectories must be those of the autopilot in process.
"""

from __future__ import annotations

import json
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("zmq")
pytest.importorskip("osi3")

from pytest_avscenario.stack import OSIStack, client, kit  # noqa: E402,F401  (before pytester runs)
from pytest_avscenario.sim.world import World  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
EXAMPLES = ROOT / "example_tests"
sys.path.insert(0, str(EXAMPLES))
import subscenarios  # noqa: E402  (the example suite's behaviours: slow_down, wobble)


@pytest.fixture
def served_autopilot(tmp_path):
    """The autopilot served by a stack process of its own (stopped when the test ends)."""
    address = f"ipc://{tmp_path}/autopilot.sock"
    env = {**__import__("os").environ, "PYTHONPATH": str(ROOT)}
    proc = subprocess.Popen([sys.executable, "-m", "pytest_avscenario.stack.autopilot", address],
                            env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    yield address
    proc.kill()
    proc.wait(timeout=10)
    client.stop_all()


def _following(driver, gap, lead_speed, brake_at, decel, final, seed):
    w = World(seed=seed, driver=driver, name="t::following")
    road = w.straight_road(lanes=1, length=400)
    w.ego(road.lane(0), s=20.0, speed=12.0)
    w.car(road.lane(0), s=20.0 + gap, speed=lead_speed,
          behavior=subscenarios.wobble(subscenarios.slow_down(brake_at, decel, final), sd=0.3))
    return w.run(seconds=12)


@pytest.mark.parametrize("gap, lead_speed, brake_at, decel, final", [
    (30.0, 10.0, 3.0, 2.5, 5.0),  # the nominal case
    (11.0, 5.0, 1.0, 8.0, 0.0),  # close, slow, a hard stop: the ego stands still for seconds
    (38.0, 14.0, 4.5, 1.5, 7.0),
])
def test_the_served_autopilot_drives_as_the_autopilot_in_process(served_autopilot, gap, lead_speed,
                                                                  brake_at, decel, final):
    here = _following("autopilot", gap, lead_speed, brake_at, decel, final, seed=11)
    remote = _following(OSIStack(served_autopilot, timeout_s=30), gap, lead_speed, brake_at, decel,
                        final, seed=11)
    for key in ("x", "y", "vx", "vy", "speed", "heading", "lane_offset"):
        a, b = getattr(here, key), getattr(remote, key)
        assert np.nanmax(np.abs(a - b)) <= 1e-9, key
    assert set(here.signals) == set(remote.signals)
    for key in here.signals:
        assert np.nanmax(np.abs(here.signals[key] - remote.signals[key])) <= 1e-9, key
    assert np.array_equal(here.crashed, remote.crashed)


def test_served_as_desired_trajectories_the_autopilot_still_drives_as_in_process():
    # the kit sends where the command held takes the ego (a trajectory from its state now);
    # the plugin's trajectory controller feeds the trajectory's acceleration forward, so on a
    # straight road it recovers the command to rounding: the same following, to 1e-6
    spawn = f"{sys.executable} -m pytest_avscenario.stack.autopilot {{address}} --answer trajectory"
    args = (30.0, 10.0, 3.0, 2.5, 5.0)
    try:
        here = _following("autopilot", *args, seed=11)
        remote = _following(OSIStack(spawn=spawn, timeout_s=30), *args, seed=11)
    finally:
        client.stop_all()
    assert not here.crashed.any() and not remote.crashed.any()
    for key in ("x", "y", "speed", "heading"):
        assert np.nanmax(np.abs(getattr(here, key) - getattr(remote, key))) <= 1e-6, key
    assert here.speed.min() < 8.0  # the lead braked and the ego followed it down


def test_same_seed_same_bits_through_the_stack(served_autopilot):
    runs = [_following(OSIStack(served_autopilot, timeout_s=30), 20.0, 8.0, 2.0, 4.0, 0.0, seed=5)
            for _ in range(2)]
    for key in ("x", "y", "speed", "heading"):
        assert np.array_equal(getattr(runs[0], key), getattr(runs[1], key)), key


def test_a_campaign_gives_the_same_verdicts_served_as_in_process(pytester):
    pytester.makepyfile(subscenarios=(EXAMPLES / "subscenarios.py").read_text())
    pytester.makepyfile(test_following=(EXAMPLES / "test_02_vehicle_following.py").read_text())
    common = ["--avs-seed=3", "--avs-samples=4", "--avs-sampler=halton", "--avs-db=none",
              "--avs-shrink-budget=0", "--avs-reference-driver=none", "--avs-gifs=0",
              "--avs-case-pictures=0", "-p", "no:xdist", "-p", "no:cacheprovider"]
    rows = {}
    served = f"osi+spawn:{sys.executable} -m pytest_avscenario.stack.autopilot"
    # served with both sides blocking, and with both spinning before they block (the
    # plugin's wait and the kit's, which the plugin hands the spin): the same cases
    for name, driver, spin in (("here", "autopilot", "0"), ("served", served, "0"),
                               ("spinning", served, "300")):
        start = time.monotonic()
        result = pytester.runpytest(f"--avs-driver={driver}", f"--avs-report={name}",
                                    f"--avs-stack-spin={spin}", *common)
        assert result.ret in (0, 1), result.stdout.str()[-2000:]
        assert time.monotonic() - start < 60
        rows[name] = [json.loads(line) for line in
                      (pytester.path / name / "errors.jsonl").read_text().splitlines()]
    assert len(rows["here"]) == len(rows["served"]) == len(rows["spinning"]) == 4
    for a, b in zip(rows["served"], rows["spinning"]):  # bit for bit: the same exchanges
        assert (a["item"], a["params"], a["verdict"], a["error"], a["rho"]) == \
            (b["item"], b["params"], b["verdict"], b["error"], b["rho"])
    for a, b in zip(rows["here"], rows["served"]):
        assert (a["item"], a["params"], a["verdict"], a["error"]) == \
            (b["item"], b["params"], b["verdict"], b["error"])
        assert a["rho"].keys() == b["rho"].keys()
        for metric, value in a["rho"].items():
            assert b["rho"][metric] == pytest.approx(value, abs=1e-9), (a["item"], metric)
    # four different situations, not one repeated: the closest approaches differ
    assert len({round(r["rho"]["distance"], 3) for r in rows["here"]}) == 4


@pytest.mark.slow
def test_under_xdist_each_worker_spawns_its_own_stack_and_the_verdicts_stay(pytester):
    pytester.makepyfile(subscenarios=(EXAMPLES / "subscenarios.py").read_text())
    pytester.makepyfile(test_following=(EXAMPLES / "test_02_vehicle_following.py").read_text())
    common = ["--avs-seed=5", "--avs-samples=6", "--avs-sampler=halton", "--avs-db=none",
              "--avs-shrink-budget=0", "--avs-reference-driver=none", "--avs-gifs=0",
              "--avs-case-pictures=0", "-p", "no:cacheprovider"]
    tables = {}
    for name, driver, more in (("here", "autopilot", []),
                               ("served", f"osi+spawn:{sys.executable} -m pytest_avscenario.stack.autopilot",
                                ["-n", "2"])):
        result = pytester.runpytest_subprocess(f"--avs-driver={driver}", f"--avs-report={name}",
                                               *common, *more)
        assert result.ret in (0, 1), result.stdout.str()[-2000:]
        rows = [json.loads(line) for line in (pytester.path / name / "errors.jsonl").read_text().splitlines()]
        tables[name] = {r["item"]: (r["verdict"], r["rho"]) for r in rows}
    assert len(tables["here"]) == 6 and tables["here"] == tables["served"]


def test_a_spawned_kit_ends_with_the_process_that_started_it(tmp_path):
    # the plugin stops its stacks at exit; a plugin killed outright cannot, so the kit
    # notices it lost its parent (within about a second) and ends
    address = f"ipc://{tmp_path}/orphan.sock"
    parent_code = (
        "import os, subprocess, sys, time\n"
        f"p = subprocess.Popen([sys.executable, '-m', 'pytest_avscenario.stack', {address!r}],"
        f" env=dict(os.environ, AVS_OSI_ADDRESS={address!r}, PYTHONPATH={str(ROOT)!r}),"
        " start_new_session=True)\n"
        "print(p.pid, flush=True)\n"
        "time.sleep(60)\n")
    parent = subprocess.Popen([sys.executable, "-c", parent_code], stdout=subprocess.PIPE, text=True)
    kit_pid = int(parent.stdout.readline())
    try:
        deadline = time.monotonic() + 20
        while not (tmp_path / "orphan.sock").exists() and time.monotonic() < deadline:
            time.sleep(0.05)  # bound: serving
        assert (tmp_path / "orphan.sock").exists()
        parent.kill()
        parent.wait(timeout=10)
        deadline = time.monotonic() + 5
        while time.monotonic() < deadline:
            try:
                __import__("os").kill(kit_pid, 0)
            except ProcessLookupError:
                break
            time.sleep(0.1)
        else:
            pytest.fail("the kit outlived the process that spawned it by 5 s")
    finally:
        parent.kill()
        try:
            __import__("os").kill(kit_pid, 9)
        except ProcessLookupError:
            pass

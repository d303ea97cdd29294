"""A stack the plugin spawned never outlives the process that spawned it.

The stack here is tests/data/osi_raw_stack.py, which (unlike the Python kit) does not watch
its parent: only the plugin can stop it. Two ways out are shown: the end of a pytest run
(the plugin's ``pytest_unconfigure``) and any other exit of the interpreter (``atexit``),
here a script that dies of an unhandled exception after a case.
"""

from __future__ import annotations

import os
import subprocess
import sys
import time
from pathlib import Path

import pytest

pytest.importorskip("zmq")
pytest.importorskip("osi3")

from pytest_avscenario.stack import client  # noqa: E402  (before any pytester run)

ROOT = Path(__file__).resolve().parent.parent
RAW = ROOT / "tests" / "data" / "osi_raw_stack.py"


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    try:  # killed but not reaped by its (re)parent: gone all the same
        return " Z " not in Path(f"/proc/{pid}/stat").read_text().split(")", 1)[1][:4]
    except OSError:
        return True


def _gone_within(pid: int, seconds: float) -> bool:
    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline:
        if not _alive(pid):
            return True
        time.sleep(0.05)
    return not _alive(pid)


@pytest.fixture(autouse=True)
def _stop_stacks():
    yield
    client.stop_all()


def test_the_end_of_the_run_stops_the_stack_it_spawned(pytester):
    pytester.makepyfile(test_spawned="""
from pytest_avscenario import scenario, Uniform
from pytest_avscenario.stack import client

@scenario(gap=Uniform(30, 50), samples=1, monitors=[])
def test_drive(case, world):
    road = world.straight_road(lanes=1, length=300)
    world.ego(road.lane(0), s=10.0, speed=8.0)
    world.run(seconds=0.5)
    (spawned,) = client._SPAWNED.values()
    open("stack.pid", "w").write(str(spawned.proc.pid))
""")
    result = pytester.runpytest("--avs-driver", f"osi+spawn:{sys.executable} {RAW} {{address}}",
                                "--avs-db=none", "--avs-report=none", "--avs-shrink-budget=0",
                                "-p", "no:xdist", "-p", "no:cacheprovider")
    result.assert_outcomes(passed=1)
    pid = int((pytester.path / "stack.pid").read_text())
    # this process goes on (no atexit yet): the run's own end stopped the stack
    assert not _alive(pid), f"the spawned stack {pid} outlived the run"
    assert client._SPAWNED == {}


def test_an_interpreter_that_dies_of_an_exception_stops_its_stack(tmp_path):
    script = tmp_path / "dies.py"
    script.write_text(f"""
import sys
from pytest_avscenario.sim.world import World
from pytest_avscenario.stack import OSIStack, client

w = World(seed=1, driver=OSIStack(spawn={f"{sys.executable} {RAW} {{address}}"!r}), name="t::dies")
road = w.straight_road(lanes=1, length=300)
w.ego(road.lane(0), s=10.0, speed=8.0)
w.run(seconds=0.5)
(spawned,) = client._SPAWNED.values()
print(spawned.proc.pid, flush=True)
raise RuntimeError("the script dies here")
""")
    proc = subprocess.run([sys.executable, str(script)], capture_output=True, text=True, timeout=120,
                          env={**os.environ, "PYTHONPATH": str(ROOT)}, cwd=tmp_path)
    assert proc.returncode == 1 and "the script dies here" in proc.stderr, proc.stderr[-2000:]
    pid = int(proc.stdout.split()[0])
    try:
        assert _gone_within(pid, 2.0), f"the spawned stack {pid} outlived the interpreter"
    finally:
        if _alive(pid):
            os.kill(pid, 9)

"""Same case, same bits: across scenes, after highway-env's global constants change, across
processes; and importing the simulator stays light."""

from __future__ import annotations

import os
import subprocess
import sys

import numpy as np
import pytest

from pytest_avscenario.sim import World
from pytest_avscenario.sim import behaviors as b

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)


def following_case(seed: int = 7):
    w = World(seed=seed, rng=np.random.default_rng(seed), driver="idm", name="following")
    road = w.straight_road(lanes=2)
    w.ego(road.lane(0), s=0.0, speed=12.0)
    w.car(road.lane(0), s=25.0, speed=9.0, behavior=b.brake_at(b.uniform(1.0, 5.0), decel=6.0))
    w.car(road.lane(1), s=5.0, speed=11.0, behavior=b.change_lane(b.choice(["left", 1]), at=2.0))
    return w.run(10.0)


def intersection_case(seed: int = 3):
    w = World(seed=seed, driver="idm", name="intersection")
    inter = w.intersection(lanes=2)
    w.ego(inter.stop_line("south").before(25), speed=8.0, route=inter.route("south", "left"))
    w.car(inter.stop_line("north").before(20), speed=8.0, behavior=b.turn("straight"))
    w.car(inter.stop_line("east", 1).before(15), speed=7.0, behavior=b.turn("right", stop=False))
    w.pedestrian(inter.crosswalk("west"), behavior=b.cross(wait=b.uniform(0.0, 2.0), wait_in_road=1.0))
    return w.run(10.0)


def other_scenes():
    w = World(seed=99, driver=lambda o: (1.0, 0.01))
    road = w.two_way_road(lanes=2)
    w.ego(road.lane(1), s=5.0, speed=3.0)
    w.parked_car(road.parking_lane, s=30.0, behavior=b.pull_out(at=1.0))
    w.bus(road.lane(0, "backward"), s=10.0, speed=8.0, behavior=b.bus_stop(t=2.0, duration=2.0))
    w.pedestrian(road.crosswalk(60.0), behavior=b.cross(wait=1.0))
    w.run(6.0)
    intersection_case(seed=5)


@pytest.mark.filterwarnings("ignore:.*intersection-v0 is out of date")
def test_same_case_same_digest_before_and_after_other_scenes(monkeypatch):
    before = following_case().digest(), intersection_case().digest()
    other_scenes()
    assert (following_case().digest(), intersection_case().digest()) == before

    # highway-env's intersection-v0 rewrites IDMVehicle's class constants process-wide;
    # so does any code poking them. Our runs must not notice.
    import gymnasium as gym
    import highway_env  # noqa: F401  (registers the environments)
    from highway_env.road.lane import AbstractLane, StraightLane
    from highway_env.vehicle.behavior import IDMVehicle
    from highway_env.vehicle.controller import ControlledVehicle
    from highway_env.vehicle.kinematics import Vehicle

    for cls in (IDMVehicle, ControlledVehicle, Vehicle, AbstractLane, StraightLane):
        for key, value in list(vars(cls).items()):
            if key.isupper() and not callable(value):
                monkeypatch.setattr(cls, key, value)  # restore at teardown
    env = gym.make("intersection-v0")
    env.reset(seed=0)
    env.close()
    assert IDMVehicle.COMFORT_ACC_MAX == 6  # the rewrite happened
    monkeypatch.setattr(IDMVehicle, "TIME_WANTED", 0.1)
    monkeypatch.setattr(ControlledVehicle, "KP_A", 9.0)
    monkeypatch.setattr(Vehicle, "LENGTH", 9.0)
    monkeypatch.setattr(AbstractLane, "VEHICLE_LENGTH", 1.0)
    np.random.seed(1234)
    assert (following_case().digest(), intersection_case().digest()) == before


def test_different_seeds_differ():
    assert following_case(7).digest() != following_case(8).digest()


def test_same_digest_in_a_fresh_process():
    here = (following_case().digest(), intersection_case().digest())
    code = ("import sys; sys.path.insert(0, sys.argv[1]);"
            "import test_sim_determinism as t;"
            "print(t.intersection_case().digest()); print(t.following_case().digest())")
    out = subprocess.run([sys.executable, "-c", code, HERE], capture_output=True, text=True,
                         cwd=ROOT, timeout=120, env={**os.environ, "PYTHONHASHSEED": "12345"})
    assert out.returncode == 0, out.stderr
    there = tuple(out.stdout.split()[::-1])
    assert there == here


def test_digest_sees_a_one_bit_change():
    tr = following_case()
    tr.x[0, 50] = np.nextafter(tr.x[0, 50], np.inf)
    assert tr.digest() != following_case().digest()


def test_importing_the_simulator_imports_nothing_heavy():
    out = subprocess.run(
        [sys.executable, "-X", "importtime", "-c",
         "import pytest_avscenario.sim, pytest_avscenario.sim.behaviors, "
         "pytest_avscenario.sim.places, pytest_avscenario.sim.drivers"],
        capture_output=True, text=True, cwd=ROOT, timeout=120)
    assert out.returncode == 0, out.stderr
    modules = {line.split("|")[-1].strip().split(".")[0] for line in out.stderr.splitlines()
               if line.startswith("import time:")}
    assert "pytest_avscenario" in modules
    for heavy in ("highway_env", "pygame", "matplotlib", "pandas", "gymnasium"):
        assert heavy not in modules, heavy


def test_building_a_road_imports_highway_env_but_not_pygame():
    # only highway-env's road and vehicle modules: not pygame, nor its gym environments
    code = ("import sys; from pytest_avscenario.sim import World;"
            "w = World(seed=1, driver='idm'); w.straight_road();"
            "print('highway_env.road.road' in sys.modules,"
            " any(m in sys.modules for m in ('pygame', 'gymnasium', 'highway_env.envs')))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT,
                         timeout=120)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "True False"


@pytest.mark.parametrize("case", [following_case, intersection_case])
def test_saved_trajectory_round_trips_with_the_same_digest(case, tmp_path):
    from pytest_avscenario.sim import Trajectory

    tr = case()
    tr.save(tmp_path / "t.npz")
    back = Trajectory.load(tmp_path / "t.npz")
    assert back.digest() == tr.digest()


def test_collision_broad_phase_changes_nothing(monkeypatch):
    from pytest_avscenario.sim.engine import SimRoad

    def crowded():
        w = World(seed=4, driver=lambda o: (2.0, 0.0))  # drives into the queue ahead
        road = w.straight_road(lanes=2)
        w.ego(road.lane(0), s=0.0, speed=12.0)
        for k in range(7):
            w.car(road.lane(k % 2), s=15.0 + 9.0 * k, speed=3.0 + k % 3,
                  behavior=b.change_lane("right" if k % 2 == 0 else "left", at=1.0 + 0.3 * k))
        return w.run(8.0)

    fast = crowded()
    assert fast.crashed.any()  # the comparison covers real contacts
    monkeypatch.setattr(SimRoad, "BROAD_PHASE_FROM", 10**6)
    assert crowded().digest() == fast.digest()

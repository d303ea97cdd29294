"""highway-env's core is loaded without its gym environments, and a later full import still works."""

import subprocess
import sys

SCRIPT = r"""
import sys
from pytest_avscenario.sim import World, behaviors as b

def case():
    w = World(seed=3, driver="idm", name="t")
    road = w.straight_road(lanes=1, length=400)
    w.ego(road.lane(0), s=20, speed=12)
    w.car(road.lane(0), s=45, speed=8, behavior=b.brake_at(2, decel=6))
    return w.run(5).digest()

first = case()
heavy = [m for m in ("gymnasium", "pygame", "matplotlib", "pandas") if m in sys.modules]
assert heavy == [], heavy

import gymnasium as gym
import highway_env
import highway_env.road.road
from pytest_avscenario.sim import engine

env = gym.make("intersection-v0")  # the registration ran, and it rewrites IDMVehicle constants
env.reset(seed=0)
assert highway_env.road.road.Road is engine.Road
assert case() == first
print("ok")
"""


def test_core_loads_light_and_a_later_gym_import_sees_the_same_classes():
    out = subprocess.run([sys.executable, "-W", "ignore", "-c", SCRIPT], capture_output=True, text=True)
    assert out.returncode == 0, out.stderr[-2000:]
    assert out.stdout.strip() == "ok"

"""A trained agent as the AV under test: a DQN from highway-env's ``highway-fast-v0`` drives the ego.

The ego's driver here is the small DQN that ``example_tests/train_dqn.py`` trains with
stable-baselines3 and saves to ``example_tests/models/dqn_highway_fast.zip``, wrapped as
``highway_env_agent(DQN.load(path), env="highway-fast-v0")``: every second (the
environment's ``policy_frequency``) highway-env's own Kinematics observation of the scene is
built, the model picks one of highway-env's meta-actions (lane left, idle, lane right, faster,
slower) and highway-env's ``MDPVehicle`` controllers execute it. The world runs at the
environment's own step, 0.2 s (5 Hz), so the agent is driven exactly as in training. With
``--avs-driver`` (``autopilot``, ``idm``, ``sb3:PATH@ENV``) the same scenarios test that
driver instead — still at 0.2 s: ``world.run(dt=DT)`` fixes the step for every driver, so
the drivers compared in ``train_dqn.py``'s table (and in the README) met the same
simulation. An agent from an environment with another step (``sb3:PATH@highway-v0``,
15 Hz) runs here at 0.2 s with an ``AgentStepWarning``; the scenario speeds lie within
``highway-fast-v0``'s target speeds (20-30 m/s), so no ``AgentSpeedWarning``. The module skips, saying why, when stable-baselines3 is not installed
(``pip install -e ".[sb3]"``) or the model file is missing (train it with
``python example_tests/train_dqn.py``).

The road is the training environment's: three 4-m lanes (0 leftmost), a 30 m/s limit.

* ``test_lead_brakes``: the ego cruises in the middle lane at ``ego_speed`` [m/s] U(20, 30)
  behind a lead ``gap`` [m] U(15, 60) ahead (centre to centre) at ``lead_speed`` [m/s]
  U(18, 30); ``brake_at`` [s] U(1, 6) into the run the lead brakes at ``lead_decel``
  [m/s^2] U(2, 8) down to ``lead_final_speed`` [m/s] U(0, 15) and holds it. A car in the
  left lane, ``left_offset`` [m] U(-30, 30) from the ego, keeps the ego's speed, so a swerve
  left can be unsafe. Nominal: a lead 40 m ahead at 25 m/s slowing gently (3 m/s^2) to
  15 m/s after 3 s.
* ``test_cut_in``: a car ``cut_gap`` [m] U(5, 50) ahead of the ego in the lane to its
  ``cut_from`` side {left, right}, at ``cut_speed`` [m/s] U(15, 30), moves into the ego's lane
  ``cut_at`` [s] U(0.5, 4) into the run over ``cut_duration`` [s] U(1.5, 4) (UN R157's
  cut-in, here without its lateral-speed parametrisation). Nominal: 40 m ahead, from the
  left, at 25 m/s, after 2 s over 3 s.

Monitors: ``collision``; ``off_road`` — the ego's centre stays on the carriageway (an agent
that drives off the road, clear of the traffic, would pass every other check here; lane
changes are among the agent's actions, so the paper's lane keeping is not asked);
``clearance`` — the footprints stay 0.5 m apart (``distance`` with ``footprint=True``: the
paper's 5 m between centres is already broken by a car passing in the next lane at 4 m);
``time_headway(0.5)`` s to the car ahead in the ego's lane; ``progress(11)``.
"""

from __future__ import annotations

import importlib.util
from pathlib import Path

import pytest

from pytest_avscenario import Choice, Uniform, scenario
from pytest_avscenario.monitors import collision, distance, off_road, progress, time_headway
from pytest_avscenario.sim import behaviors as b

from subscenarios import slow_down

MODEL = Path(__file__).resolve().parent / "models" / "dqn_highway_fast.zip"
ENV = "highway-fast-v0"
DT = 0.2  # [s] highway-fast-v0's simulation step (simulation_frequency 5 Hz)
MONITORS = [collision(), off_road(), distance(0.5, footprint=True, name="clearance"),
            time_headway(0.5), progress(11.0)]
PRIORITY = ["collision", "off_road", "clearance", "time_headway", "progress"]


@pytest.fixture(scope="module")
def trained_agent():
    """The DQN of ``models/dqn_highway_fast.zip`` as an ego driver, loaded once per module."""
    if importlib.util.find_spec("stable_baselines3") is None:
        pytest.skip('the trained-agent example needs stable-baselines3: pip install -e ".[sb3]"')
    if not MODEL.is_file():
        pytest.skip(f"no trained model at {MODEL}: python example_tests/train_dqn.py")
    from stable_baselines3 import DQN

    from pytest_avscenario.sim.drivers import highway_env_agent

    return highway_env_agent(DQN.load(MODEL, device="cpu"), env=ENV)


@pytest.fixture
def avs_driver(request, avs_driver):
    """The trained agent, unless ``--avs-driver`` (or ini ``avs_driver``) names the ego's driver."""
    if request.config.getoption("avs_driver") or request.config.getini("avs_driver"):
        return avs_driver
    return request.getfixturevalue("trained_agent")


def highway(world):
    """highway-fast-v0's road: three 4-m lanes, 30 m/s."""
    return world.straight_road(lanes=3, length=1500.0, lane_width=4.0, speed_limit=30.0)


@scenario(
    ego_speed=Uniform(20.0, 30.0, nominal=25.0, unit="m/s"),
    gap=Uniform(15.0, 60.0, nominal=40.0, unit="m"),
    lead_speed=Uniform(18.0, 30.0, nominal=25.0, unit="m/s"),
    brake_at=Uniform(1.0, 6.0, nominal=3.0, unit="s"),
    lead_decel=Uniform(2.0, 8.0, nominal=3.0, unit="m/s²"),
    lead_final_speed=Uniform(0.0, 15.0, nominal=15.0, unit="m/s"),
    left_offset=Uniform(-30.0, 30.0, nominal=-30.0, unit="m"),
    samples=30,
    sampler=["halton", "mab"],
    monitors=MONITORS,
    priority=PRIORITY,
)
def test_lead_brakes(case, world):
    road = highway(world)
    s0 = 100.0
    world.ego(road.lane(1), s=s0, speed=case.ego_speed)
    world.car(road.lane(1), s=s0 + case.gap, speed=case.lead_speed,
              behavior=slow_down(case.brake_at, case.lead_decel, case.lead_final_speed))
    world.car(road.lane(0), s=s0 + case.left_offset, speed=case.ego_speed,
              behavior=b.keep_lane(case.ego_speed))
    world.run(seconds=15, dt=DT)


@scenario(
    ego_speed=Uniform(20.0, 30.0, nominal=25.0, unit="m/s"),
    cut_from=Choice(["left", "right"]),
    cut_gap=Uniform(5.0, 50.0, nominal=40.0, unit="m"),
    cut_speed=Uniform(15.0, 30.0, nominal=25.0, unit="m/s"),
    cut_at=Uniform(0.5, 4.0, nominal=2.0, unit="s"),
    cut_duration=Uniform(1.5, 4.0, nominal=3.0, unit="s"),
    samples=30,
    sampler=["halton", "mab"],
    monitors=MONITORS,
    priority=PRIORITY,
)
def test_cut_in(case, world):
    road = highway(world)
    s0 = 100.0
    world.ego(road.lane(1), s=s0, speed=case.ego_speed)
    lane = 0 if case.cut_from == "left" else 2
    toward = "right" if case.cut_from == "left" else "left"
    world.car(road.lane(lane), s=s0 + case.cut_gap, speed=case.cut_speed,
              behavior=b.change_lane(toward, at=case.cut_at, duration=case.cut_duration))
    world.run(seconds=15, dt=DT)

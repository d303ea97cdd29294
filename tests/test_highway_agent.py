"""Agents trained on highway-env as the ego: the same observations, decisions and trajectory as
in highway-env's own environment, highway-env's frame for the agent, and clear errors.

The policies are deterministic numpy objects with stable-baselines3's ``predict`` signature,
so no torch is needed.
"""

from __future__ import annotations

import math
import pickle
from dataclasses import dataclass

import gymnasium
import highway_env  # noqa: F401  (registers the environment ids)
import numpy as np
import pytest
from highway_env.road.road import Road, RoadNetwork
from highway_env.vehicle.kinematics import Vehicle

import pytest_avscenario.sim.drivers.highway_agent  # noqa: F401  (imported before any pytester run)
from pytest_avscenario.sim import AgentSpeedWarning, AgentStepWarning, DriverError, SimError, World
from pytest_avscenario.sim.behaviors import Behavior
from pytest_avscenario.sim.drivers import highway_env_agent

LANES = 4
WIDTH = 4.0  # highway-env's lane width [m]
LENGTH = 10000.0  # highway-env's straight_road_network length [m]


class LinearPolicy:
    """A fixed random linear policy: argmax (discrete) or tanh (continuous) of W @ obs."""

    def __init__(self, n_out: int, seed: int, continuous: bool = False, gain: float = 1.0):
        self.n_out, self.seed, self.continuous, self.gain = n_out, seed, continuous, gain
        self.W = None
        self.seen: list[np.ndarray] = []
        self.answers: list = []

    def predict(self, obs, state=None, episode_start=None, deterministic=False):
        x = np.asarray(obs, dtype=float).ravel()
        self.seen.append(np.array(obs, copy=True))
        if self.W is None:
            self.W = np.random.default_rng(self.seed).normal(size=(self.n_out, x.size))
        z = self.W @ x
        a = (np.tanh(z) * self.gain).astype(np.float32) if self.continuous else np.array(int(np.argmax(z)))
        self.answers.append(a)
        return a, None


def profile(t: float) -> float:
    """[m/s^2] the lead car's acceleration at time t [s]: cruise, brake, cruise, speed up."""
    if 2.0 <= t < 4.0:
        return -3.0
    if 6.0 <= t < 7.0:
        return 2.0
    return 0.0


@dataclass(frozen=True)
class Scripted(Behavior):
    """The world's side of a scripted car: acceleration by its age, no steering."""

    accelerating: bool = True

    def control(self, agent, world):
        return (profile(agent.age) if self.accelerating else 0.0), 0.0


class ScriptedVehicle(Vehicle):
    """highway-env's side of the same car."""

    def __init__(self, road, position, speed, dt, accelerating=True):
        super().__init__(road, position, 0.0, speed)
        self.n, self.dt, self.accelerating = 0, dt, accelerating

    def act(self, action=None):
        t = self.n * self.dt
        self.n += 1
        super().act({"acceleration": profile(t) if self.accelerating else 0.0, "steering": 0.0})


class RecordingRoad(Road):
    """highway-env's Road, keeping the ego's state after every step."""

    def step(self, dt):
        super().step(dt)
        e = self.vehicles[0]
        self.log.append((e.position[0], e.position[1], e.heading, e.speed))


# ego lane, ego s, ego speed; then (lane, s, speed, scripted?) for the others
SCENE = (1, 100.0, 25.0, [(1, 135.0, 22.0, True), (2, 115.0, 24.0, False),
                          (0, 80.0, 27.0, False), (3, 160.0, 20.0, True)])


def run_in_highway_env(env_id, config, policy, seconds):
    env = gymnasium.make(env_id, config=config).unwrapped
    env.reset(seed=0)
    dt = 1.0 / env.config["simulation_frequency"]
    road = RecordingRoad(network=RoadNetwork.straight_road_network(LANES, speed_limit=30),
                         np_random=env.np_random, record_history=False)
    road.log = []
    lane, s, v, others = SCENE
    ego = env.action_type.vehicle_class(road, np.array([s, lane * WIDTH]), 0.0, v)
    if hasattr(ego, "route"):
        ego.route = [("0", "1", lane)]  # the world gives its ego its route
    road.vehicles.append(ego)
    for ln, so, vo, scripted in others:
        road.vehicles.append(ScriptedVehicle(road, np.array([so, ln * WIDTH]), vo, dt, scripted))
    env.road = road
    env.controlled_vehicles = [ego]
    e = road.vehicles[0]
    road.log.append((e.position[0], e.position[1], e.heading, e.speed))
    obs = env.observation_type.observe()
    crashed = False
    for _ in range(int(round(seconds * env.config["policy_frequency"]))):
        action, _state = policy.predict(obs, deterministic=True)
        if env.config["action"]["type"] == "DiscreteMetaAction":
            action = int(action)
        obs, _r, _term, _trunc, _info = env.step(action)
        crashed |= ego.crashed
    return np.array(road.log), crashed, dt


def run_in_world(env_id, config, policy, seconds):
    agent = highway_env_agent(policy, env=env_id, config=config)
    w = World(seed=0, name="test_equivalence")
    road = w.straight_road(lanes=LANES, length=LENGTH, lane_width=WIDTH, speed_limit=30.0)
    lane, s, v, others = SCENE
    w.ego(road.lane(lane), s=s, speed=v, driver=agent)
    for ln, so, vo, scripted in others:
        w.car(road.lane(ln), s=so, speed=vo, behavior=Scripted(scripted))
    tr = w.run(seconds, dt=agent.dt)
    return w, tr


CONFIGS = {  # env id, config changes, policy (its seed picks a run with lane changes)
    "highway-fast default": ("highway-fast-v0", None, dict(n_out=5, seed=1)),
    "every kinematics feature": (
        "highway-fast-v0",
        {"observation": {"type": "Kinematics", "vehicles_count": 4, "normalize": False,
                         "features": ["presence", "x", "y", "vx", "vy", "heading", "cos_h",
                                      "sin_h", "cos_d", "sin_d", "long_off", "lat_off",
                                      "ang_off"]}},
        dict(n_out=5, seed=8)),
    "highway-v0 at 15 Hz": ("highway-v0", None, dict(n_out=5, seed=4)),
    "occupancy grid": ("highway-fast-v0", {"observation": {"type": "OccupancyGrid"}},
                       dict(n_out=5, seed=3)),
    "time to collision": ("highway-fast-v0", {"observation": {"type": "TimeToCollision"}},
                          dict(n_out=5, seed=8)),
    "lidar, until a crash": ("highway-fast-v0", {"observation": {"type": "LidarObservation"}},
                             dict(n_out=5, seed=1)),
    "continuous action": ("highway-fast-v0",
                          {"action": {"type": "ContinuousAction"}, "policy_frequency": 5},
                          dict(n_out=2, seed=0, continuous=True, gain=0.1)),
}


@pytest.mark.parametrize("which", list(CONFIGS))
def test_same_observations_decisions_and_trajectory_as_highway_env(which):
    env_id, config, pol = CONFIGS[which]
    seconds = 10.0
    ours, theirs = LinearPolicy(**pol), LinearPolicy(**pol)
    w, tr = run_in_world(env_id, config, ours, seconds)
    log, crashed, dt = run_in_highway_env(env_id, config, theirs, seconds)
    assert tr.t[1] == pytest.approx(dt)
    e = tr.ego
    assert len(log) == len(e.x)
    # highway-env ends its episode at a crash (and then shoves the cars apart its own way):
    # compare up to the step the ego crashed, in both or in neither
    hit = np.flatnonzero(e.crashed)
    end = int(hit[0]) + 1 if hit.size else len(e.x)
    assert crashed == bool(hit.size) and crashed == ("crash" in which)
    # the agent saw the same arrays (highway-env's frame) and answered the same
    assert len(ours.seen) >= (seconds if not crashed else 3)
    assert len(ours.seen) == (len(theirs.seen) if not crashed else
                              math.ceil(end * dt * w.agent("ego").session.agent.policy_period ** -1
                                        - 1e-9))
    for k, (a, b) in enumerate(zip(ours.seen, theirs.seen)):
        assert a.shape == b.shape and a.dtype == b.dtype
        np.testing.assert_allclose(a, b, atol=1e-6, err_msg=f"observation {k}")
    for a, b in zip(ours.answers, theirs.answers):
        np.testing.assert_array_equal(a, b)
    # the ego went the same way, mirrored: (x, y, heading) here is (x, -y, -heading) there
    log = log[:end]
    np.testing.assert_allclose(e.x[:end], log[:, 0], atol=1e-6)
    np.testing.assert_allclose(e.y[:end], -log[:, 1], atol=1e-6)
    np.testing.assert_allclose(e.heading[:end], -np.arctan2(np.sin(log[:, 2]), np.cos(log[:, 2])),
                               atol=1e-6)
    np.testing.assert_allclose(e.speed[:end], log[:, 3], atol=1e-6)
    # and the comparison means something: the agent changed its mind and its lane
    if not pol.get("continuous"):
        assert len({int(a) for a in ours.answers}) >= 2
    assert np.ptp(e.y[:end]) > 3.0


def test_the_agent_sees_highway_envs_frame():
    # a car one lane to the right of the ego: y < 0 in the world, y > 0 in highway-env
    pol = LinearPolicy(n_out=5, seed=0)
    agent = highway_env_agent(pol, config={"observation": {"type": "Kinematics",
                                                          "normalize": False,
                                                          "features": ["presence", "x", "y",
                                                                       "heading"]}})
    w = World(seed=0, name="test_frame")
    road = w.straight_road(lanes=3, length=500, lane_width=4.0)
    w.ego(road.lane(1), s=50, speed=25.0, driver=agent)
    car = w.car(road.lane(2), s=70, speed=25.0)
    assert car.position[1] - w.agent("ego").position[1] == pytest.approx(-4.0)
    w.run(0.2, dt=agent.dt)
    obs = pol.seen[0]
    assert obs[0][2] == pytest.approx(4.0)  # ego: lane 1 at y = +4 m in highway-env
    assert obs[1][1] == pytest.approx(20.0) and obs[1][2] == pytest.approx(4.0)


def test_one_decision_per_policy_period_at_any_dividing_dt():
    pol = LinearPolicy(n_out=5, seed=3)
    agent = highway_env_agent(pol)  # highway-fast-v0: 1 Hz decisions, 5 Hz simulation
    w = World(seed=0, name="test_period")
    road = w.straight_road(lanes=3, length=800, lane_width=4.0)
    w.ego(road.lane(1), s=50, speed=25.0, driver=agent)
    with pytest.warns(AgentStepWarning, match=r"runs at dt=0\.05 s \(world\.run\(dt=0\.05\)\), not "
                      r"at its environment's step 0\.2 s.*it still decides every 1 s"):
        w.run(4.95, dt=0.05)
    assert [t for t, _ in w.agent("ego").decisions] == pytest.approx([0.0, 1.0, 2.0, 3.0, 4.0])


def test_a_world_step_that_does_not_divide_the_policy_period_warns_and_decides_near_it():
    agent = highway_env_agent(LinearPolicy(n_out=5, seed=0))
    w = World(seed=0, name="tests/x.py::test_dt[3]")
    road = w.straight_road(lanes=3, length=500, lane_width=4.0)
    w.ego(road.lane(1), s=50, speed=25.0, driver=agent)
    with pytest.warns(AgentStepWarning) as got:
        w.run(3.0, dt=0.3)
    assert len(got) == 1
    msg = str(got[0].message)
    assert msg.startswith("tests/x.py::test_dt[3]: highway_env_agent(LinearPolicy, "
                          "env='highway-fast-v0') runs at dt=0.3 s (world.run(dt=0.3)), not at "
                          "its environment's step 0.2 s (simulation_frequency 5 Hz)")
    assert "0.3 s does not divide its policy period 1 s (policy_frequency 1 Hz), so it " \
           "decides every 0.9 s instead" in msg
    assert msg.endswith("leave the step to the driver (world.run() without dt=) or give dt=0.2")
    assert [t for t, _ in w.agent("ego").decisions] == pytest.approx([0.0, 0.9, 1.8, 2.7])


@pytest.mark.parametrize("answer, expected", [
    (7, "expected an action index 0..4 (0=LANE_LEFT, 1=IDLE, 2=LANE_RIGHT, 3=FASTER, 4=SLOWER)"),
    (np.array([1, 2]), "expected an action index 0..4"),
    (1.5, "expected an action index 0..4"),
    ("left", "expected an action index 0..4"),
])
def test_a_bad_discrete_action_names_the_test_time_and_the_actions(answer, expected):
    agent = highway_env_agent(lambda obs: answer)
    w = World(seed=0, name="test_bad_action")
    road = w.straight_road(lanes=3, length=500, lane_width=4.0)
    w.ego(road.lane(1), s=50, speed=25.0, driver=agent)
    with pytest.raises(SimError) as err:
        w.run(2, dt=agent.dt)
    msg = str(err.value)
    assert "test_bad_action" in msg and "agent 'ego'" in msg and "t=0.00 s" in msg
    assert expected in msg


def test_a_bad_continuous_action_says_what_was_expected():
    agent = highway_env_agent(lambda obs: np.array([0.1, np.nan]),
                              config={"action": {"type": "ContinuousAction"}})
    w = World(seed=0, name="test_bad_continuous")
    road = w.straight_road(lanes=3, length=500, lane_width=4.0)
    w.ego(road.lane(1), s=50, speed=25.0, driver=agent)
    with pytest.raises(SimError, match=r"expected 2 numbers in \[-1, 1\] \(ContinuousAction\)"):
        w.run(2, dt=agent.dt)


def test_a_model_that_raises_is_a_driver_error_with_its_traceback():
    class Broken:
        def predict(self, obs, deterministic=False):
            raise RuntimeError("weights missing")

    agent = highway_env_agent(Broken())
    w = World(seed=0, name="test_broken")
    road = w.straight_road(lanes=3, length=500, lane_width=4.0)
    w.ego(road.lane(1), s=50, speed=25.0, driver=agent)
    with pytest.raises(DriverError) as err:
        w.run(2, dt=agent.dt)
    assert "test_broken" in str(err.value) and "weights missing" in str(err.value)
    assert "RuntimeError" in err.value.driver_traceback


@pytest.mark.parametrize("config, words", [
    ({"observation": {"type": "GrayscaleObservation", "observation_shape": (84, 84),
                      "stack_size": 4, "weights": [0.3, 0.6, 0.1]}},
     ["'GrayscaleObservation' is an image", "Kinematics"]),
    ({"observation": {"type": "KinematicsGoal", "features": ["x"], "scales": [1]}},
     ["'KinematicsGoal' is not supported", "OccupancyGrid"]),
    ({"action": {"type": "ContinuousAction", "dynamical": True}}, ["dynamical", "BicycleVehicle"]),
    ({"observation": {"type": "TimeToCollision"}, "action": {"type": "ContinuousAction"}},
     ["TimeToCollision", "target speeds"]),
])
def test_unsupported_environment_settings_are_refused_naming_the_test(config, words):
    agent = highway_env_agent(LinearPolicy(n_out=5, seed=0), config=config)
    w = World(seed=0, name="tests/t.py::test_agent[1]")
    road = w.straight_road(lanes=3, length=500, lane_width=4.0)
    with pytest.raises(SimError) as err:
        w.ego(road.lane(1), s=50, speed=25.0, driver=agent)
    msg = str(err.value)
    assert "tests/t.py::test_agent[1]" in msg and "highway_env_agent(env='highway-fast-v0')" in msg
    for word in words:
        assert word in msg


def test_an_unknown_environment_id_is_refused():
    agent = highway_env_agent(LinearPolicy(n_out=5, seed=0), env="highway-nonesuch-v9")
    w = World(seed=0, name="test_unknown_env")
    road = w.straight_road(lanes=3, length=500)
    with pytest.raises(SimError, match="highway-nonesuch-v9.*e.g. 'highway-fast-v0'"):
        w.ego(road.lane(0), s=50, speed=25.0, driver=agent)


@pytest.mark.parametrize("model", [None, 3, "dqn.zip"])
def test_a_model_that_cannot_predict_is_refused_at_once(model):
    with pytest.raises(SimError, match="predict.*callable"):
        highway_env_agent(model)


def test_the_agent_pickles_without_its_environment():
    agent = highway_env_agent(LinearPolicy(n_out=5, seed=0), config={"policy_frequency": 2})
    assert agent.dt == pytest.approx(0.2) and agent.policy_period == pytest.approx(0.4)
    again = pickle.loads(pickle.dumps(agent))
    assert again._env is None and again.config == {"policy_frequency": 2}
    assert repr(again) == "highway_env_agent(LinearPolicy, env='highway-fast-v0')"


def test_cases_do_not_depend_on_what_the_agent_drove_before():
    # one agent object over several worlds (as an avs_driver fixture of wider scope):
    # a case gives the same trajectory first or after others
    def case(agent, lanes, seed):
        w = World(seed=seed, name=f"case{seed}")
        road = w.straight_road(lanes=lanes, length=800, lane_width=4.0)
        w.ego(road.lane(1), s=50, speed=25.0, driver=agent)
        w.car(road.lane(1), s=90, speed=20.0)
        return w.run(6, dt=agent.dt)

    alone = case(highway_env_agent(LinearPolicy(n_out=5, seed=3)), 2, 1)
    shared = highway_env_agent(LinearPolicy(n_out=5, seed=3))
    case(shared, 4, 7)
    again = case(shared, 2, 1)
    np.testing.assert_array_equal(alone.y, again.y)
    np.testing.assert_array_equal(alone.x, again.x)
    assert math.isfinite(float(again.x[0, -1]))


# -- as a user meets it: the avs_driver fixture -------------------------------------------------

AGENT_CONFTEST = """
import numpy as np
import pytest
from pytest_avscenario.sim.drivers import highway_env_agent

class Cautious:
    '''Slow down when something is close ahead in the ego's lane, else keep going.'''

    def predict(self, obs, state=None, episode_start=None, deterministic=False):
        assert obs.shape == (5, 5), obs.shape
        ahead = (obs[1:, 0] > 0) & (np.abs(obs[1:, 2]) < 0.1) & (obs[1:, 1] > 0) & (obs[1:, 1] < 0.25)
        return np.array(4 if ahead.any() else 1), None

AGENT = highway_env_agent(Cautious(), env="highway-fast-v0", config=CONFIG)

@pytest.fixture
def avs_driver():
    return AGENT  # one object for every case
"""

AGENT_TEST = """
from pytest_avscenario import scenario, Uniform
from pytest_avscenario.monitors import distance

@scenario(gap=Uniform(30.0, 60.0), samples=3, monitors=[distance(0.5, kind="centre")])
def test_follow(case, world, avs_driver):
    road = world.straight_road(lanes=3, length=1000, lane_width=4.0)
    world.ego(road.lane(1), s=50, speed=25.0)
    world.car(road.lane(1), s=50 + case.gap, speed=20.0)
    world.run(5, dt=avs_driver.dt)
    assert [t for t, _ in world.agent("ego").decisions] == [0.0, 1.0, 2.0, 3.0, 4.0]
"""


def test_an_avs_driver_fixture_returning_a_highway_env_agent_drives_every_case(pytester):
    pytester.makeconftest(AGENT_CONFTEST.replace("CONFIG", "None"))
    pytester.makepyfile(test_agent=AGENT_TEST)
    result = pytester.runpytest("--avs-seed=1", "--avs-db=none", "-p", "no:xdist")
    result.assert_outcomes(passed=3)


def test_an_image_observation_is_refused_naming_the_case_and_the_setting(pytester):
    pytester.makeconftest(AGENT_CONFTEST.replace(
        "CONFIG", "{'observation': {'type': 'GrayscaleObservation'}}"))
    pytester.makepyfile(test_agent=AGENT_TEST.replace("samples=3", "samples=1"))
    result = pytester.runpytest("--avs-seed=1", "--avs-db=none", "-p", "no:xdist")
    result.assert_outcomes(errors=1)
    result.stdout.fnmatch_lines([
        "*test_agent.py::test_follow*highway_env_agent(env='highway-fast-v0'): observation type "
        "'GrayscaleObservation' is an image*(config={'observation': {'type': 'Kinematics'}})"])


def test_a_highway_env_model_given_the_observation_raises_with_a_hint(pytester):
    # what a stable-baselines3 model does with the plugin's Observation dataclass
    pytester.makeconftest("""
import numpy as np
import pytest

class Trained:
    def predict(self, observation, state=None, episode_start=None, deterministic=False):
        if np.asarray(observation).shape != (5, 5):
            raise ValueError(f"Unexpected observation shape {np.asarray(observation).shape}")
        return np.array(1), None

@pytest.fixture
def avs_driver():
    return Trained()
""")
    pytester.makepyfile(test_agent=AGENT_TEST.replace("samples=3", "samples=1").replace(
        "    world.run(5, dt=avs_driver.dt)\n", "    world.run(5)\n"))
    result = pytester.runpytest("--avs-seed=1", "--avs-db=none", "-p", "no:xdist")
    result.assert_outcomes(errors=1)
    result.stdout.fnmatch_lines([
        "*Unexpected observation shape ()*predict() gets the plugin's Observation*"
        "highway_env_agent(model, env='highway-fast-v0')*"])


# -- the agent's own step and speeds ------------------------------------------------------------

def _scene(ego, name="t.py::test_x[halton-000]", speed=25.0, **world):
    w = World(seed=0, name=name, **world)
    road = w.straight_road(lanes=3, length=800, lane_width=4.0)
    w.ego(road.lane(1), s=50, speed=speed, driver=ego)
    w.car(road.lane(1), s=90, speed=22.0)
    return w


@pytest.mark.parametrize("env, step", [("highway-fast-v0", 0.2), ("highway-v0", 1 / 15)])
def test_without_dt_the_world_steps_at_the_agents_environment_step(env, step):
    w = _scene(highway_env_agent(LinearPolicy(n_out=5, seed=3), env=env))
    tr = w.run(2.0)
    assert tr.t[1] == step and w.dt == step and len(tr.t) == round(2.0 / step) + 1
    assert [t for t, _ in w.agent("ego").decisions] == pytest.approx([0.0, 1.0])


def test_the_step_follows_the_scenarios_agent_when_a_reference_drives_the_ego():
    # the avoidability replay: the reference drives, the other agents move as in the case
    w = _scene(None, driver=highway_env_agent(LinearPolicy(n_out=5, seed=3)), ego_driver="careful")
    assert "CarefulDriver" in repr(w.agent("ego").driver)
    assert w.run(1.0).t[1] == 0.2


def test_a_reference_replay_on_a_cluster_takes_the_scenarios_agents_step_along():
    # away from this process the replay's world knows only the reference as its driver
    from types import SimpleNamespace

    from pytest_avscenario.campaign.jobs import _remote_step

    agent = highway_env_agent(LinearPolicy(n_out=5, seed=3), env="highway-v0")
    plan = SimpleNamespace(dt=None, dt_from="")
    assert _remote_step(plan, agent, "careful")["world_dt"] == 1 / 15
    assert _remote_step(plan, agent, None)["world_dt"] is None  # the agent drives: it knows
    assert _remote_step(plan, lambda obs: (0, 0), "careful")["world_dt"] is None
    pinned = SimpleNamespace(dt=0.05, dt_from="--avs-dt")
    assert _remote_step(pinned, agent, "careful") == {"world_dt": 0.05, "world_dt_from": "--avs-dt"}


def test_a_plain_driver_keeps_the_default_step_and_a_driver_may_declare_its_own():
    assert _scene(lambda obs: (0.0, 0.0)).run(1.0).t[1] == 0.1

    class Stack:
        dt = 0.05  # [s] the rate the stack was built for

        def act(self, obs):
            return 0.0, 0.0

    assert _scene(Stack()).run(1.0).t[1] == 0.05
    Stack.dt = -1
    with pytest.raises(SimError, match=r"declares dt=-1: a driver's dt is the step it was made for"):
        _scene(Stack()).run(1.0)


def test_an_agent_at_its_own_step_gives_the_same_bits_every_time():
    def run():
        return _scene(highway_env_agent(LinearPolicy(n_out=5, seed=3)), speed=5.0).run(6.0)

    with pytest.warns(AgentSpeedWarning):
        a, b = run(), run()
    for field in ("x", "y", "speed", "heading"):
        np.testing.assert_array_equal(getattr(a, field), getattr(b, field))


@pytest.mark.parametrize("config, speed, target, words", [
    (None, 5.6, None, "the scenario places the ego at speed=5.6 m/s, outside what "
     "highway_env_agent(<lambda>, env='highway-fast-v0')'s DiscreteMetaAction can hold: its "
     "target speeds are 20, 25, 30 m/s, so the ego (highway-env's MDPVehicle) heads for 20 m/s "
     "from the start; the agent starts where it never was in training — place the ego within "
     "[20, 30] m/s, or test an agent trained for these speeds"),
    (None, 25.0, 35.0, "at target_speed=35 m/s, outside what"),
    ({"action": {"type": "ContinuousAction", "speed_range": [20, 30]}}, 12.0, None,
     "at speed=12 m/s, outside what highway_env_agent(<lambda>, env='highway-fast-v0')'s "
     "ContinuousAction can hold: its speed_range is [20, 30] m/s; the agent starts"),
])
def test_speeds_the_action_type_cannot_hold_are_warned(config, speed, target, words):
    answer = np.zeros(2, dtype=np.float32) if config else 1
    agent = highway_env_agent(lambda obs: answer, config=config)
    w = World(seed=0, name="t.py::test_x[halton-000]")
    road = w.straight_road(lanes=3, length=800, lane_width=4.0)
    with pytest.warns(AgentSpeedWarning) as got:
        w.ego(road.lane(1), s=50, speed=speed, target_speed=target, driver=agent)
    assert len(got) == 1
    assert str(got[0].message).startswith("t.py::test_x[halton-000]: ")
    assert words in str(got[0].message)


STEP_TEST = """
import pytest
from pytest_avscenario import scenario, Uniform

@scenario(speed=Uniform(SPEEDS), samples=3MARKER)
def test_follow(case, world, avs_driver):
    road = world.straight_road(lanes=3, length=1000, lane_width=4.0)
    world.ego(road.lane(1), s=50, speed=case.speed)
    world.car(road.lane(1), s=120, speed=20.0)
    trajectory = world.run(3RUN)
    assert trajectory.t[1] == pytest.approx(STEP, abs=0)
"""


def step_test(pytester, step, speeds="20, 30", marker="", run=""):
    pytester.makeconftest(AGENT_CONFTEST.replace("CONFIG", "None"))
    pytester.makepyfile(test_agent=STEP_TEST.replace("SPEEDS", speeds).replace("MARKER", marker)
                        .replace("RUN", run).replace("STEP", repr(step)))


ARGS = ("--avs-seed=1", "--avs-db=none", "--avs-report=none", "-p", "no:xdist")


@pytest.mark.parametrize("marker, run, options, step, source", [
    ("", "", (), 0.2, None),  # the agent's own step
    ("", ", dt=0.1", (), 0.1, "world.run(dt=0.1)"),
    ("", ", dt=0.1", ("--avs-dt=0.05",), 0.1, "world.run(dt=0.1)"),  # the test's own dt wins
    ("", "", ("--avs-dt=0.1",), 0.1, "--avs-dt"),
    (", dt=0.05", "", ("--avs-dt=0.1",), 0.05, "@scenario(dt=0.05)"),  # marker > command line
    (", dt='auto'", "", ("--avs-dt=0.1",), 0.2, None),
    ("", "", ("--avs-dt=auto",), 0.2, None),
])
def test_the_step_is_the_tests_else_the_command_lines_else_the_agents(
        pytester, marker, run, options, step, source):
    step_test(pytester, step, marker=marker, run=run)
    result = pytester.runpytest(*ARGS, *options)
    if source is None:
        result.assert_outcomes(passed=3)
        return
    result.assert_outcomes(passed=3, warnings=1)  # once per test, not once per case
    result.stdout.fnmatch_lines([
        f"*AgentStepWarning: test_agent.py::test_follow[[]halton-000]: highway_env_agent(Cautious, "
        f"env='highway-fast-v0') runs at dt={step:g} s ({source}), not at its environment's step "
        "0.2 s (simulation_frequency 5 Hz): it still decides every 1 s (policy_frequency 1 Hz)*"
        "or give dt=0.2"])


def test_the_ini_file_sets_the_step_below_the_command_line(pytester):
    step_test(pytester, 0.1)
    pytester.makeini("[pytest]\navs_dt = 0.1\n")
    result = pytester.runpytest(*ARGS)
    result.assert_outcomes(passed=3, warnings=1)
    result.stdout.fnmatch_lines(["*runs at dt=0.1 s (ini avs_dt)*(ini avs_dt = auto, or --avs-dt "
                                 "auto) or give dt=0.2"])
    step_test(pytester, 0.2)
    pytester.runpytest(*ARGS, "--avs-dt=auto").assert_outcomes(passed=3)


def test_scenario_speeds_outside_the_agents_targets_are_warned_once_per_test(pytester):
    step_test(pytester, 0.2, speeds="4, 12")
    result = pytester.runpytest(*ARGS)
    result.assert_outcomes(passed=3, warnings=1)
    result.stdout.fnmatch_lines([
        "*AgentSpeedWarning: test_agent.py::test_follow[[]halton-000]: the scenario places the ego "
        "at speed=8 m/s, outside what highway_env_agent(Cautious, env='highway-fast-v0')'s "
        "DiscreteMetaAction can hold: its target speeds are 20, 25, 30 m/s*"])


@pytest.mark.parametrize("where, value, message", [
    ("--avs-dt", "fast", "ERROR: --avs-dt: dt must be a step in seconds (0 < dt <= 10) or "
                         "'auto', got 'fast'"),
    ("--avs-dt", "0", "ERROR: --avs-dt: dt must be a step in seconds*got '0'"),
    ("marker", "-0.1", "*test_agent.py::test_follow*dt must be a step in seconds (0 < dt <= 10) "
                       "or 'auto', got -0.1 (from @scenario(dt=...))*"),
])
def test_a_bad_step_names_where_it_was_given(pytester, where, value, message):
    step_test(pytester, 0.2, marker=f", dt={value}" if where == "marker" else "")
    result = pytester.runpytest(*ARGS, *([f"--avs-dt={value}"] if where != "marker" else []))
    if where == "marker":
        result.assert_outcomes(errors=1)
        result.stdout.fnmatch_lines([message])
    else:
        assert result.ret == pytest.ExitCode.USAGE_ERROR
        result.stderr.fnmatch_lines([message])

"""``--avs-driver sb3:PATH@ENV``: a saved stable-baselines3 model as the ego.

Every mistake is a usage error at start-up naming the option, checked without torch: so
these run without stable-baselines3 (the zips here are written as stable-baselines3 writes
them: a ``data`` JSON beside ``policy.pth``). The tests that load a real model need
stable-baselines3 and the model ``example_tests/train_dqn.py`` saved, and skip without.
"""

from __future__ import annotations

import json
import pickle
import sys
import types
import zipfile
from pathlib import Path

import pytest

import pytest_avscenario.sim.drivers.highway_agent  # noqa: F401  (imported before any pytester run)
from pytest_avscenario.sim.drivers import sb3
from pytest_avscenario.sim.drivers.sb3 import SB3Spec, check, parse

try:  # torch's C extensions load once per process: import it before a pytester run forgets it
    import stable_baselines3  # noqa: F401
except ImportError:
    pass

MODEL = Path(__file__).resolve().parent.parent / "example_tests" / "models" / "dqn_highway_fast.zip"

SCENARIO = """
from pytest_avscenario import scenario, Uniform

@scenario(gap=Uniform(20, 40), samples=2)
def test_follow(case, world):
    road = world.straight_road(lanes=3, length=600, lane_width=4.0, speed_limit=30.0)
    world.ego(road.lane(1), s=50.0, speed=25.0)
    world.car(road.lane(1), s=50.0 + case.gap, speed=22.0)
    world.run(seconds=3, dt=0.2)
    ego = world.agent("ego")
    assert "sb3:dqn_highway_fast.zip" in repr(ego.driver)
    assert [t for t, _ in ego.decisions] == [0.0, 1.0, 2.0]
"""


def sb3_zip(path: Path, policy_module: str = "stable_baselines3.dqn.policies",
            obs_shape: list[int] = (5, 5), n_actions: int = 5, **extra) -> Path:
    """A zip laid out as stable-baselines3's ``model.save`` lays it out (no network in it)."""
    data = {
        "policy_class": {":type:": "<class 'abc.ABCMeta'>", "__module__": policy_module},
        "observation_space": {":type:": "<class 'gymnasium.spaces.box.Box'>",
                              "_shape": list(obs_shape), "dtype": "float32"},
        "action_space": {":type:": "<class 'gymnasium.spaces.discrete.Discrete'>",
                         "n": str(n_actions), "_shape": []},
        **extra,
    }
    with zipfile.ZipFile(path, "w") as z:
        z.writestr("data", json.dumps(data))
        z.writestr("policy.pth", b"")
    return path


@pytest.mark.parametrize("text, spec", [
    ("sb3:models/dqn.zip", SB3Spec("models/dqn.zip", "highway-fast-v0", None)),
    ("sb3:models/dqn.zip@highway-v0", SB3Spec("models/dqn.zip", "highway-v0", None)),
    ("sb3:ppo:m.zip@merge-v0", SB3Spec("m.zip", "merge-v0", "PPO")),
    ("sb3:C:\\models\\dqn.zip", SB3Spec("C:\\models\\dqn.zip", "highway-fast-v0", None)),
    ("sb3:runs@3/dqn.zip", SB3Spec("runs@3/dqn.zip", "highway-fast-v0", None)),
])
def test_the_spec_names_a_file_an_environment_and_maybe_an_algorithm(text, spec):
    assert parse(text) == spec


def test_check_answers_an_absolute_path_and_reads_the_algorithm_from_the_zip(tmp_path, monkeypatch):
    (tmp_path / "m").mkdir()
    sb3_zip(tmp_path / "m" / "dqn.zip")
    if sys.modules.get("stable_baselines3") is None:  # check() only asks whether it is there
        monkeypatch.setitem(sys.modules, "stable_baselines3", types.ModuleType("stable_baselines3"))
    assert check("sb3:m/dqn.zip", tmp_path) == f"sb3:{tmp_path / 'm' / 'dqn.zip'}@highway-fast-v0"
    assert check("sb3:dqn:m/dqn.zip@highway-v0", tmp_path).startswith("sb3:DQN:/")
    # the path without .zip, as stable-baselines3's load() takes it
    assert check("sb3:m/dqn", tmp_path) == f"sb3:{tmp_path / 'm' / 'dqn.zip'}@highway-fast-v0"


@pytest.mark.parametrize("make, text, message", [
    (None, "sb3:nope.zip", "driver 'sb3:nope.zip': no model file at */nope.zip (read as model 'nope.zip', "
                           "environment 'highway-fast-v0')"),
    # an '@' in the file's name: what was read as what is said
    (None, "sb3:dqn@v2.zip", "*no model file at */dqn (read as model 'dqn', environment 'v2.zip')"),
    (lambda d: (d / "dir.zip").mkdir(), "sb3:dir.zip", "*dir.zip is not a file*"),
    (lambda d: (d / "m.zip").write_text("hello"), "sb3:m.zip", "*m.zip is not a zip file*"),
    (lambda d: zipfile.ZipFile(d / "m.zip", "w").close(), "sb3:m.zip",
     "*m.zip is a zip but not a model saved by stable-baselines3*"),
    (lambda d: sb3_zip(d / "m.zip"), "sb3:m.zip@highway-v9",
     "*unknown environment 'highway-v9'; highway-env's are *highway-fast-v0*"),
    (lambda d: sb3_zip(d / "m.zip"), "sb3:m.zip@parking-v0",
     "*observation type 'KinematicsGoal' is not supported*the environment 'parking-v0'*"),
    (lambda d: sb3_zip(d / "m.zip", obs_shape=[7, 5]), "sb3:m.zip",
     "*takes observations of shape (7, 5), but 'highway-fast-v0' in its default config gives (5, 5)*"),
    (lambda d: sb3_zip(d / "m.zip", n_actions=3), "sb3:m.zip",
     "*chooses among 3 actions*has 5; run it from an avs_driver fixture in conftest.py, giving "
     "the config it was trained with: return highway_env_agent(DQN.load('*m.zip'), "
     "env='highway-fast-v0', config={'action': {...}})"),
    # a continuous model: sb3: runs the environment's default config; the fixture takes config=
    (lambda d: sb3_zip(d / "m.zip", policy_module="stable_baselines3.sac.policies",
                       action_space={":type:": "<class 'gymnasium.spaces.box.Box'>", "_shape": [2]}),
     "sb3:m.zip", "*the model at */m.zip was trained with Box actions, 'highway-fast-v0' in its "
     "default config has Discrete actions; sb3: runs an environment in its default config only, "
     "so run it from an avs_driver fixture in conftest.py, giving the config it was trained "
     "with: return highway_env_agent(SAC.load('*m.zip'), env='highway-fast-v0', "
     "config={'action': {'type': 'ContinuousAction'}})"),
    (lambda d: sb3_zip(d / "m.zip", policy_module="my_algos.policies"), "sb3:m.zip",
     "*cannot tell the algorithm*'my_algos.policies'*name it: sb3:ALGO:PATH@ENV*; for another "
     "algorithm, run it from an avs_driver fixture in conftest.py: "
     "return highway_env_agent(MyAlgo.load('*m.zip'), env='highway-fast-v0')"),
    (None, "sb3:xyz:m.zip", "*unknown algorithm 'xyz'; stable-baselines3's are A2C, *"),
    (None, "sb3:", "*names no model file; write sb3:PATH*"),
])
def test_a_model_that_cannot_drive_is_a_usage_error_at_start_up(pytester, make, text, message):
    pytester.makepyfile(SCENARIO)
    if make is not None:
        make(pytester.path)
    result = pytester.runpytest("--avs-db=none", "--avs-report=none", f"--avs-driver={text}")
    assert result.ret == pytest.ExitCode.USAGE_ERROR
    result.stderr.fnmatch_lines([f"ERROR: --avs-driver: {message}"])
    assert "INTERNALERROR" not in result.stdout.str() + result.stderr.str()


def test_without_stable_baselines3_the_error_says_what_to_install(pytester, monkeypatch):
    monkeypatch.setitem(sys.modules, "stable_baselines3", None)  # as if not installed
    pytester.makepyfile(SCENARIO)
    (pytester.path / "models").mkdir()
    sb3_zip(pytester.path / "models" / "dqn.zip")
    pytester.makeini("[pytest]\navs_driver = sb3:models/dqn.zip@highway-fast-v0\n")
    result = pytester.runpytest("--avs-db=none", "--avs-report=none")
    assert result.ret == pytest.ExitCode.USAGE_ERROR
    assert ("ERROR: ini avs_driver: driver 'sb3:models/dqn.zip@highway-fast-v0' needs "
            "stable-baselines3, which is not installed: pip install \"pytest-avscenario[sb3]\"") \
        in result.stderr.str()


def test_the_trained_agent_example_skips_saying_why_without_stable_baselines3(pytester, monkeypatch):
    monkeypatch.setitem(sys.modules, "stable_baselines3", None)  # as if not installed
    example = MODEL.parent.parent / "test_trained_agent.py"
    result = pytester.runpytest(str(example), "-m", "scenario", "-rs", "--avs-samples=1",
                                "--avs-db=none", "--avs-report=none", "-p", "no:xdist")
    result.assert_outcomes(skipped=4)  # 2 tests x 2 samplers
    reason = 'the trained-agent example needs stable-baselines3: pip install -e ".[sb3]"'
    assert result.stdout.str().count(reason) == 2  # one -rs line per test


# -- with stable-baselines3 and the trained model ----------------------------------------------------

def _needs_model():
    pytest.importorskip("stable_baselines3")
    if not MODEL.is_file():
        pytest.skip(f"no model at {MODEL} (python example_tests/train_dqn.py)")


def test_the_saved_model_drives_the_ego_once_per_policy_period(pytester):
    _needs_model()
    pytester.makepyfile(SCENARIO)
    # in a process of its own: torch's modules cannot be forgotten and imported again
    result = pytester.runpytest_subprocess("--avs-db=none", "--avs-report=none", "-p", "no:xdist",
                                           f"--avs-driver=sb3:{MODEL}")
    result.assert_outcomes(passed=2)


def test_the_driver_pickles_as_its_path_and_decides_as_the_model(tmp_path):
    _needs_model()
    import gymnasium
    from stable_baselines3 import DQN

    agent = sb3.driver(f"sb3:{MODEL}@highway-fast-v0")
    assert sb3.driver(f"sb3:{MODEL}") is agent  # one per process and file
    env = gymnasium.make("highway-fast-v0")
    obs, _ = env.reset(seed=3)
    env.close()
    first = agent.predict(obs)  # loads the model
    blob = pickle.dumps(agent)
    assert len(blob) < 10_000  # the path, not the network
    again = pickle.loads(blob)
    assert again.model._model is None
    reference = DQN.load(MODEL, device="cpu").predict(obs, deterministic=True)[0]
    assert int(again.predict(obs)) == int(first) == int(reference)


# -- the agent's own step, without torch: a stand-in stable_baselines3 whose DQN.load gives a
# numpy policy with the same predict(obs, deterministic=...) -------------------------------------

def fake_sb3(monkeypatch):
    import numpy as np

    class Policy:
        def predict(self, obs, state=None, episode_start=None, deterministic=False):
            assert np.asarray(obs).shape == (5, 5)
            return np.array(1), None  # IDLE

    class DQN:
        @staticmethod
        def load(path, device="auto"):
            return Policy()

    module = types.ModuleType("stable_baselines3")
    module.DQN = DQN
    monkeypatch.setitem(sys.modules, "stable_baselines3", module)


STEP_SCENARIO = """
from pytest_avscenario import scenario, Uniform

@scenario(gap=Uniform(20, 40), samples=2)
def test_follow(case, world):
    road = world.straight_road(lanes=3, length=600, lane_width=4.0, speed_limit=30.0)
    world.ego(road.lane(1), s=50.0, speed=25.0)
    world.car(road.lane(1), s=50.0 + case.gap, speed=22.0)
    trajectory = world.run(seconds=3)
    assert "sb3:m.zip" in repr(world.agent("ego").driver)
    assert trajectory.t[1] == STEP and world.dt == STEP
    assert [t for t, _ in world.agent("ego").decisions] == [0.0, 1.0, 2.0]
"""


@pytest.mark.parametrize("env, step", [("highway-fast-v0", 0.2), ("highway-v0", 1 / 15)])
def test_a_saved_model_runs_at_its_environments_step_unless_told(pytester, monkeypatch, env, step):
    # world.run() without dt: 1 / simulation_frequency of the model's environment
    fake_sb3(monkeypatch)
    sb3_zip(pytester.path / "m.zip")
    pytester.makepyfile(test_follow=STEP_SCENARIO.replace("STEP", repr(step)))
    args = ["--avs-db=none", "--avs-report=none", "-p", "no:xdist", "--avs-seed=1"]
    result = pytester.runpytest(*args, f"--avs-driver=sb3:m.zip@{env}")
    result.assert_outcomes(passed=2)
    # --avs-dt: the command line chooses another step, and hears once what that costs
    pytester.makepyfile(test_follow=STEP_SCENARIO.replace("STEP", "0.1"))
    result = pytester.runpytest(*args, f"--avs-driver=sb3:m.zip@{env}", "--avs-dt=0.1")
    result.assert_outcomes(passed=2, warnings=1)
    result.stdout.fnmatch_lines([
        f"*AgentStepWarning: test_follow.py::test_follow[[]halton-000]: "
        f"highway_env_agent(sb3:m.zip, env='{env}') runs at dt=0.1 s (--avs-dt), not at its "
        f"environment's step {step:g} s*leave the step to the driver (--avs-dt auto) or give "
        f"dt={step:g}"])

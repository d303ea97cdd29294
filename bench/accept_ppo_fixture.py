"""The continuous-action PPO of bench/accept_agents.py as the ego, the README's fixture way.

A plugin's fixture does not override the plugin's own ``avs_driver`` (``-p`` loads it too
early), so the acceptance run used a conftest.py beside symlinks to the example modules::

    mkdir suite && cd suite && ln -s ../example_tests/{test_r157_*,test_12_highway_merge,r157}.py .
    # conftest.py: the example suite's pytest_configure (exec'd from example_tests/conftest.py)
    # and `from accept_ppo_fixture import avs_driver`, with bench/ on sys.path
    AVS_ACCEPT_PPO=/path/ppo.zip pytest . -m scenario -n 2 --avs-seed=0 --avs-samples=30 --avs-sampler=halton

``AVS_ACCEPT_PPO`` is the model's path.
"""

import os

import pytest


@pytest.fixture(scope="session")
def avs_driver():
    from stable_baselines3 import PPO

    from pytest_avscenario.sim.drivers import highway_env_agent

    return highway_env_agent(PPO.load(os.environ["AVS_ACCEPT_PPO"], device="cpu"), env="highway-fast-v0",
                             config={"action": {"type": "ContinuousAction"}})

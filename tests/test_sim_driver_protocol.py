"""The driver protocol for real stacks: a per-case ``reset(world)`` hook and a read-only view of
the whole simulation (every lane, every agent) beyond the Observation."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

import pytest_avscenario.sim.view  # noqa: F401  (imported once, before any pytester run)
from pytest_avscenario.sim import DriverError, World
from pytest_avscenario.sim import behaviors as b

STACK_CONFTEST = """
import pytest

class Stack:
    '''A stack with a map: at reset it reads every lane, each step every agent.'''

    def __init__(self):
        self.resets = []
        self.world = None
        self.steps = 0

    def reset(self, world):
        view = world.view()
        self.world = world
        self.steps = 0
        self.resets.append((view.t, [l.id for l in view.lanes], [a.name for a in view.agents]))

    def act(self, observation):
        self.steps += 1
        view = self.world.view()
        # the car two lanes away is outside the observation's sensor range but in the view
        far = view.agent("far")
        assert view.agent_lanes["far"] == "lane[2]" and far.x > 150
        assert view.agent("ego").x == observation.ego.x
        assert "far" not in [a.name for a in observation.agents]
        return (0.0, 0.0)

STACK = Stack()

@pytest.fixture(scope="session")
def avs_driver():
    return STACK
"""

STACK_TEST = """
from pytest_avscenario import scenario, Uniform

@scenario(speed=Uniform(8.0, 12.0), samples=3)
def test_map(case, world, avs_driver):
    road = world.straight_road(lanes=3, length=600)
    world.ego(road.lane(0), s=10.0, speed=case.speed)
    world.car(road.lane(2), s=250.0, speed=case.speed, name="far")
    world.car(road.lane(1), s=40.0, speed=case.speed, appear=1.0)
    world.run(seconds=2)
    t0, lanes, agents = avs_driver.resets[-1]
    # called for this case, at t = 0 with the agents present then, before any step
    assert avs_driver.world is world and t0 == 0.0
    assert lanes == ["lane[0]", "lane[1]", "lane[2]"] and agents == ["ego", "far"]
    assert avs_driver.steps == 20
"""


def test_reset_is_called_once_per_case_and_the_view_shows_what_the_observation_does_not(pytester):
    pytester.makeconftest(STACK_CONFTEST)
    pytester.makepyfile(test_map=STACK_TEST + """

def test_after_every_case(avs_driver):
    assert len(avs_driver.resets) == 3
""")
    result = pytester.runpytest("--avs-seed=1", "--avs-db=none", "-p", "no:xdist")
    result.assert_outcomes(passed=4)


def test_a_reset_without_arguments_is_called_too():
    class Recurrent:
        def __init__(self):
            self.hidden = "stale"

        def reset(self):
            self.hidden = None

        def predict(self, observation):
            assert self.hidden is None, "reset() was not called before the first step"
            return (0.0, 0.0), None

    policy = Recurrent()
    w = World(seed=0, name="test_reset_noarg", driver=policy)
    road = w.straight_road()
    w.ego(road.lane(0), s=0.0, speed=5.0)
    w.run(1.0)
    assert policy.hidden is None


def test_a_reset_that_raises_is_a_driver_error_naming_the_test_and_the_hook():
    class Broken:
        def reset(self, world):
            raise KeyError("map tile")

        def act(self, observation):
            return (0.0, 0.0)

    w = World(seed=0, name="tests/x.py::test_reset[2]", driver=Broken())
    road = w.straight_road()
    w.ego(road.lane(0), s=0.0, speed=5.0)
    with pytest.raises(DriverError) as err:
        w.run(1.0)
    msg = str(err.value)
    assert "tests/x.py::test_reset[2]" in msg and "reset(world) raised KeyError" in msg
    assert "map tile" in err.value.driver_traceback


def test_the_view_lists_every_lane_with_its_geometry_and_links():
    w = World(seed=0, name="test_view_lanes")
    inter = w.intersection(lanes=2)
    w.ego(inter.approach("south"), s=30.0, speed=8.0, route=inter.route("south", "left"))
    w.car(inter.approach("north"), s=20.0, speed=8.0)
    view = w.view()
    index = w.lane_index
    assert [l.id for l in view.lanes] == [l.id for l in index.order]
    assert view.frame.startswith("world: x east, y north")
    for lane, known in zip(view.lanes, index.order):
        g = known.geometry
        assert lane.index == known.index and lane.kind == known.kind
        assert lane.length == pytest.approx(g.length) and lane.width == pytest.approx(g.width_at(0))
        s = lane.length / 3
        np.testing.assert_allclose(lane.position(s, 0.5), g.position(s, 0.5))
        assert lane.heading_at(s) == pytest.approx(g.heading_at(s))
        assert lane.local_coordinates(g.position(s, 0.5)) == pytest.approx((s, 0.5))
        np.testing.assert_allclose(lane.centre_line[0], g.position(0, 0), atol=1e-9)
        np.testing.assert_allclose(lane.centre_line[-1], g.position(g.length, 0), atol=1e-9)
        assert set(lane.successors) == {l.id for l in index.successors[known.index]}
    turn = view.lane(inter.route("south", "left").lanes[1].id)
    assert len(turn.centre_line) > 2  # a curve is sampled along its length
    assert view.stop_marks and all(view.lane(m.lane) for m in view.stop_marks)


def test_the_view_shows_every_agent_on_the_road_and_cannot_change_the_world():
    w = World(seed=0, name="test_view_agents")
    road = w.two_way_road(lanes=1, length=300)
    w.ego(road.lane(0), s=20.0, speed=10.0)
    w.car(road.lane(0, "backward"), s=50.0, speed=10.0, name="oncoming")
    w.car(road.lane(0), s=60.0, speed=10.0, name="late", appear=1.0)
    w.parked_car(road.parking_lane, s=100.0)
    before = w.view()
    assert [a.name for a in before.agents] == ["ego", "oncoming", "parked1"]
    assert before.ego == "ego" and before.agent("ego").kind == "ego"
    assert dict(before.agent_lanes) == {"ego": "forward[0]", "oncoming": "backward[0]",
                                        "parked1": "parking.forward"}
    seen = []
    w.run(2.0, until=lambda world: seen.append(world.view()) and False)
    later = seen[-1]
    assert later.t == pytest.approx(2.0) and "late" in [a.name for a in later.agents]
    ego = later.agent("ego")
    assert ego.x == pytest.approx(float(w.agent("ego").position[0]))
    # read-only: frozen records, read-only arrays, copies of positions
    with pytest.raises(dataclasses.FrozenInstanceError):
        later.agents[0].x = 0.0  # type: ignore[misc]
    with pytest.raises(dataclasses.FrozenInstanceError):
        later.lanes[0].length = 1.0  # type: ignore[misc]
    with pytest.raises(TypeError):
        later.agent_lanes["ego"] = "x"  # type: ignore[index]
    with pytest.raises(ValueError):
        later.lanes[0].centre_line[0, 0] = 5.0
    p = later.lanes[0].position(10.0)
    p[:] = 99.0
    assert later.lanes[0].position(10.0)[0] != 99.0


def test_the_view_needs_a_road():
    w = World(seed=0, name="test_view_none")
    with pytest.raises(Exception, match="test_view_none.*build a road first"):
        w.view()


def test_a_driver_without_reset_runs_as_before():
    # a driver without reset() (the built-in ones) runs as before
    w = World(seed=3, name="test_no_hook", driver="idm")
    road = w.straight_road()
    w.ego(road.lane(0), s=0.0, speed=10.0)
    w.car(road.lane(0), s=40.0, speed=10.0, behavior=b.brake_at(1.0))
    tr = w.run(3.0)
    assert tr.n_steps == 31

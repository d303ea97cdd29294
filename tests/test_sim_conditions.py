"""Run-time conditions for opportunistic agents: near and past places and other agents."""

from pytest_avscenario.sim import World


def test_ego_past_an_agent_and_a_spot():
    w = World(seed=1, driver="idm", name="t")
    road = w.straight_road(lanes=1, length=400)
    w.ego(road.lane(0), s=20.0, speed=12.0)
    parked = w.parked_car(road.lane(0), s=60.0)
    w.car(road.lane(0), s=150.0, speed=12.0, name="lead")
    past_agent = w.ego_past(parked)
    past_spot = w.ego_past(road.lane(0).at(60.0))
    assert not past_agent(w) and not past_spot(w)
    assert w.ego_within(parked, 50.0)(w) and not w.ego_within(parked, 30.0)(w)  # 40 m apart
    w2 = World(seed=1, driver="idm", name="t")
    road2 = w2.straight_road(lanes=2, length=400)
    w2.ego(road2.lane(0), s=100.0, speed=12.0)
    behind = w2.car(road2.lane(1), s=60.0, speed=5.0, name="behind")
    assert w2.ego_past(behind)(w2)  # 40 m ahead of it: its whole length is past
    assert not w2.ego_past(behind, by=50.0)(w2)

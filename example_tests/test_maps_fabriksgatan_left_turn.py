"""Scenario 8 on a real map: the AV turns left at fabriksgatan's junction across an oncoming car
that goes straight on.

Situation: esmini's ``fabriksgatan.xodr`` (an urban four-way junction of single-lane roads
with paramPoly3 curves, copied in ``maps/``). The ego comes from the south on lane ``0/0/1``,
``d_ego`` m before the junction at ``ego_speed``, and turns left (west) through the junction
lane ``10/0/-1`` into ``3/0/1``; an oncoming car comes from the north on ``2/0/-1``, ``d_adv`` m
before the junction at ``adv_speed``, and drives straight through (``14/0/-1`` into
``0/0/-1``) without slowing for the ego. The junction has no signals or signs in the file:
the ego must yield to the oncoming car by itself. Units: m, m/s.

Parameters: ``d_ego`` [m] U(5, 40), ``ego_speed`` [m/s] U(3, 10), ``d_adv`` [m] U(10, 80),
``adv_speed`` [m/s] U(5, 14). Nominal: the ego 30 m out at 6 m/s, the oncoming car 20 m out
at 10 m/s — it is through the junction before the ego reaches it.

A failure: a collision, footprints closer than 1 m, TTC under 2 s with a 3 m circle (the
paper's 5 m between centres would count the oncoming car passing in its own lane, 3.5 m
beside the ego, on these narrow roads), no progress (11 m) or the ego off its lane centre by
0.5 m on average. Expected corners: the two arriving together, where
the autopilot — which reacts to agents on its path but has no yielding rule at a junction
the map does not regulate — turns in front of the oncoming car.
"""

from pytest_avscenario import Uniform, scenario
from pytest_avscenario.monitors import collision, distance, lane_keeping, progress, ttc


@scenario(
    d_ego=Uniform(5.0, 40.0, nominal=30.0, unit="m"),
    ego_speed=Uniform(3.0, 10.0, nominal=6.0, unit="m/s"),
    d_adv=Uniform(10.0, 80.0, nominal=20.0, unit="m"),
    adv_speed=Uniform(5.0, 14.0, nominal=10.0, unit="m/s"),
    samples=20,
    sampler=["halton", "mab"],
    monitors=[progress(11.0), distance(1.0, footprint=True), ttc(2.0),
              lane_keeping(0.5), collision()],
    priority=["collision", "distance", "ttc", "progress", "lane_keeping"],
)
def test_fabriksgatan_left_turn(case, world):
    town = world.map("maps/fabriksgatan.xodr")
    south, north = town.lane("0/0/1"), town.lane("2/0/-1")
    world.ego(south.at(south.length - case.d_ego), speed=case.ego_speed,
              route=town.route(south, "3/0/1"))
    world.car(north.at(north.length - case.d_adv), speed=case.adv_speed,
              route=town.route(north, "0/0/-1"), name="oncoming")
    world.run(seconds=10)

"""Scenario 7 (NHTSA, the paper's Table 1): the AV crosses an intersection while an oncoming car
turns left across its path.

Situation: a four-way, one-lane-per-approach intersection with stop lines on every arm and
5.5 m lanes (so that opposing cars passing each other are 5.5 m apart, outside the paper's 5-m
distance bound; with 3.5 m lanes every oncoming car that merely passed counted). The
ego comes from the south, ``d_ego`` m before its stop line at ``ego_speed``, and goes
straight on. An oncoming car comes from the north ``d_adv`` m before its stop line at
``adv_speed``; it creeps up to its line and, once the ego is within ``adv_go_within`` m of
the intersection centre, turns left (toward the east) across the ego's path without
yielding, at up to ``adv_speed`` (capped in the turn).

Parameters: ``d_ego`` [m] U(5, 50); ``ego_speed`` [m/s] U(5, 11); ``d_adv`` [m] U(5, 40);
``adv_speed`` [m/s] U(4, 11); ``adv_go_within`` [m] U(8, 40) — how late the adversary
commits (small: it turns when the ego is already in the box).

A failure means the AV came within 5 m (centres) of the turning car, was on course to
within 5 m in under 2 s, did not get through (progress), left its lane centre, or collided.
"""

from pytest_avscenario import Uniform, scenario
from pytest_avscenario.monitors import collision, distance, lane_keeping, progress, ran_stop, ttc
from pytest_avscenario.sim import behaviors as b


@scenario(
    d_ego=Uniform(5.0, 50.0, nominal=30.0, unit="m"),  # ego centre before its stop line
    ego_speed=Uniform(5.0, 11.0, nominal=8.0, unit="m/s"),
    d_adv=Uniform(5.0, 40.0, nominal=20.0, unit="m"),  # adversary centre before its stop line
    adv_speed=Uniform(4.0, 11.0, nominal=7.0, unit="m/s"),
    adv_go_within=Uniform(8.0, 40.0, nominal=35.0, unit="m"),  # ego-to-centre distance that releases it
    samples=60,
    sampler=["halton", "mab"],
    monitors=[progress(11.0), distance(5.0), ttc(2.0), lane_keeping(0.5), collision(), ran_stop()],
    priority=["collision", "distance", "ttc", "progress", "lane_keeping"],
)
def test_oncoming_left_turn(case, world):
    inter = world.intersection(lanes=1, lane_width=5.5)
    world.ego(inter.stop_line("south").before(case.d_ego), speed=case.ego_speed,
              target_speed=case.ego_speed, route=inter.route("south", "straight"))
    world.car(inter.stop_line("north").before(case.d_adv), speed=case.adv_speed,
              behavior=b.turn_across("left", speed=case.adv_speed,
                                     go_when_ego_within=case.adv_go_within))
    world.run(seconds=15)

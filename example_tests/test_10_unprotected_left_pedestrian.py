"""Scenario 10 (NHTSA, the paper's Table 1): the AV turns left, unprotected, while a pedestrian
crosses the road it turns into.

Situation: a four-way, one-lane-per-approach intersection with 5.5 m lanes (opposing cars
pass 5.5 m apart, outside the paper's 5-m distance bound). The ego comes from the south
``d_ego`` m before its stop line and turns left into the west arm. A pedestrian on the
crosswalk across the west arm, starting from the ``ped_from`` kerb, waits ``ped_wait`` s,
walks at ``ped_speed`` (+-10 % drawn every second from ``case.rng``), stands
``ped_wait_in_road`` s in the first lane it enters and walks on. An oncoming car from the
north goes straight after its stop (ordinary all-way-stop traffic: first to stop, first to
go).

Parameters: ``d_ego`` [m] U(5, 40); ``ped_from`` in {"south", "north"}; ``ped_wait`` [s]
U(0, 14); ``ped_speed`` [m/s] U(1.0, 2.2); ``ped_wait_in_road`` [s] U(0, 3); ``d_oncoming``
[m] U(10, 60).

A failure means the AV came within 5 m (centres) of the pedestrian or the car, was on course
to within 5 m in under 2 s, did not make its turn (progress), left its lane centre, or hit
someone.
"""

from pytest_avscenario import Choice, Uniform, scenario
from pytest_avscenario.monitors import collision, distance, lane_keeping, post_encroachment_time, progress, ran_stop, ttc
from pytest_avscenario.sim import behaviors as b

from subscenarios import pedestrian_crossing


@scenario(
    d_ego=Uniform(5.0, 40.0, nominal=20.0, unit="m"),  # ego centre before its stop line
    ped_from=Choice(["south", "north"]),
    ped_wait=Uniform(0.0, 14.0, nominal=10.0, unit="s"),
    ped_speed=Uniform(1.0, 2.2, nominal=1.4, unit="m/s"),
    ped_wait_in_road=Uniform(0.0, 3.0, nominal=0.0, unit="s"),
    d_oncoming=Uniform(10.0, 60.0, nominal=40.0, unit="m"),
    samples=60,
    sampler=["halton", "mab"],
    monitors=[progress(11.0), distance(5.0), ttc(2.0), lane_keeping(0.5), collision(), ran_stop(), post_encroachment_time(1.0)],
    priority=["collision", "distance", "ttc", "progress", "lane_keeping"],
)
def test_unprotected_left_pedestrian(case, world):
    inter = world.intersection(lanes=1, lane_width=5.5)
    world.ego(inter.stop_line("south").before(case.d_ego), speed=6.0, target_speed=9.0,
              route=inter.route("south", "left"))
    world.car(inter.stop_line("north").before(case.d_oncoming), speed=8.0,
              behavior=b.turn("straight", speed=8.0))
    pedestrian_crossing(world, inter.crosswalk("west"), side=case.ped_from, wait=case.ped_wait,
                        wait_in_road=case.ped_wait_in_road, speed=case.ped_speed, jitter=0.1)
    world.run(seconds=18)

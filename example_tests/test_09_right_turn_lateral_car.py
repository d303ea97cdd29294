"""Scenario 9 (NHTSA, the paper's Table 1): the AV turns right while a lateral car passes.

Situation: a four-way, one-lane-per-approach intersection. The ego comes from the south
``d_ego`` m before its stop line at ``ego_speed`` and turns right (to the east), into the
lane that a lateral car coming from the west, ``d_lateral`` m before its stop line, is about
to drive through straight at ``lateral_speed`` without stopping (it has the right of way;
its acceleration wobbles by N(0, 0.3) m/s^2 drawn every second from ``case.rng``).
The ego must stop and merge behind it, or turn in well ahead of it.

Parameters: ``d_ego`` [m] U(5, 40); ``ego_speed`` [m/s] U(4, 10); ``d_lateral`` [m] U(10, 90);
``lateral_speed`` [m/s] U(6, 14).

A failure means the AV came within 5 m (centres) of the lateral car, was on course to within
5 m in under 2 s (e.g. it turned in just ahead of it), did not get round the corner (progress),
left its lane centre, or collided.
"""

from pytest_avscenario import Uniform, scenario
from pytest_avscenario.monitors import collision, distance, lane_keeping, progress, ttc

from subscenarios import crossing_traffic


@scenario(
    d_ego=Uniform(5.0, 40.0, nominal=20.0, unit="m"),  # ego centre before its stop line
    ego_speed=Uniform(4.0, 10.0, nominal=7.0, unit="m/s"),
    d_lateral=Uniform(10.0, 90.0, nominal=40.0, unit="m"),  # lateral car before its stop line
    lateral_speed=Uniform(6.0, 14.0, nominal=10.0, unit="m/s"),
    samples=60,
    sampler=["halton", "mab"],
    monitors=[progress(11.0), distance(5.0), ttc(2.0), lane_keeping(0.5), collision()],
    priority=["collision", "distance", "ttc", "progress", "lane_keeping"],
)
def test_right_turn_lateral_car(case, world):
    inter = world.intersection(lanes=1)
    world.ego(inter.stop_line("south").before(case.d_ego), speed=case.ego_speed,
              target_speed=case.ego_speed, route=inter.route("south", "right"))
    stop_s = inter.stop_line("west").s
    crossing_traffic(world, inter, "west", first_s=stop_s - case.d_lateral,
                     speed=case.lateral_speed, jitter=0.3)
    world.run(seconds=15)

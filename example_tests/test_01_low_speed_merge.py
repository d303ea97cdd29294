"""Scenario 1 (NHTSA, the paper's Table 1): the AV merges at low speed into traffic at a four-way
intersection.

Situation: a four-way, one-lane-per-approach intersection; the ego's road has a stop line,
the cross street does not stop. The ego starts almost stopped (``ego_speed``) ``d_ego`` m
before its stop line on the south approach and turns right (east), merging into a platoon of
two cars coming from the west at ``platoon_speed``: the first ``d_first`` m before the west
stop line, the second ``platoon_gap`` m behind it. The ego must pick a gap: before the
platoon, between the two cars, or after it. The platoon drivers' accelerations wobble by
N(0, 0.3) m/s^2, redrawn every second from ``case.rng`` during the run.

Parameters: ``d_ego`` [m] U(1, 15); ``ego_speed`` [m/s] U(0, 4); ``d_first`` [m] U(5, 80);
``platoon_gap`` [m] U(10, 45) (centre to centre); ``platoon_speed`` [m/s] U(5, 12).

A failure means the AV came within 5 m (centres) of a platoon car, was on course to within
5 m in under 2 s (it cut in too tightly, or a platoon car closed on it after it merged),
did not get round the corner (progress), left its lane centre, or collided.
"""

from pytest_avscenario import Uniform, scenario
from pytest_avscenario.monitors import collision, distance, lane_keeping, progress, ran_stop, ttc

from subscenarios import crossing_traffic


@scenario(
    d_ego=Uniform(1.0, 15.0, nominal=5.0, unit="m"),  # ego centre before its stop line
    ego_speed=Uniform(0.0, 4.0, nominal=2.0, unit="m/s"),
    d_first=Uniform(5.0, 80.0, nominal=30.0, unit="m"),  # first platoon car before the west stop line
    platoon_gap=Uniform(10.0, 45.0, nominal=25.0, unit="m"),
    platoon_speed=Uniform(5.0, 12.0, nominal=9.0, unit="m/s"),
    samples=60,
    sampler=["halton", "mab"],
    monitors=[progress(11.0), distance(5.0), ttc(2.0), lane_keeping(0.5), collision(), ran_stop()],
    priority=["collision", "distance", "ttc", "progress", "lane_keeping"],
)
def test_low_speed_merge(case, world):
    inter = world.intersection(lanes=1)
    world.ego(inter.stop_line("south").before(case.d_ego), speed=case.ego_speed,
              target_speed=8.0, route=inter.route("south", "right"))
    stop_s = inter.stop_line("west").s
    crossing_traffic(world, inter, "west", first_s=stop_s - case.d_first, count=2,
                     spacing=case.platoon_gap, speed=case.platoon_speed, jitter=0.3)
    world.run(seconds=15)

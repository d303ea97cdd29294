"""Scenario 6 (NHTSA, the paper's Table 1): the AV responds to a pedestrian crossing a one-way road.

Situation: a one-lane one-way road with a marked crosswalk 120 m from its start. The ego
(the one car) drives at ``ego_speed``, starting ``d_ego`` m before the crosswalk. A pedestrian
stands on the south kerb, waits ``ped_wait`` s, walks north at ``ped_speed``, and once in
the lane stands still for ``ped_wait_in_road`` s (hesitating), then walks on; its pace
varies by +-10 % (1 sd), redrawn every second from ``case.rng`` during the run.

Parameters (the paper's three first): ``d_ego`` [m] U(25, 70) — the AV's distance from the
crosswalk; ``ped_wait`` [s] U(0, 8) — how long the pedestrian waits before crossing;
``ped_wait_in_road`` [s] U(0, 4) — how long it stands in the road; ``ped_speed`` [m/s]
U(1.0, 2.5); ``ego_speed`` [m/s] U(8, 14).

A failure means the AV came within 5 m of the pedestrian (centres), was on a
course to within 5 m in under 2 s, did not move at least 11 m (it may stop and wait, but must
go on), left its lane centre, or touched anyone (collision).
"""

from pytest_avscenario import Uniform, scenario
from pytest_avscenario.monitors import collision, distance, lane_keeping, post_encroachment_time, progress, ttc

from subscenarios import pedestrian_crossing

CROSSWALK_S = 120.0  # [m]
CROSSWALK_W = 5.0  # [m]


@scenario(
    d_ego=Uniform(25.0, 70.0, nominal=45.0, unit="m"),  # ego centre before the crosswalk centre
    ped_wait=Uniform(0.0, 8.0, nominal=6.0, unit="s"),
    ped_wait_in_road=Uniform(0.0, 4.0, nominal=1.0, unit="s"),
    ped_speed=Uniform(1.0, 2.5, nominal=1.4, unit="m/s"),
    ego_speed=Uniform(8.0, 14.0, nominal=11.0, unit="m/s"),
    samples=60,
    sampler=["halton", "mab"],
    monitors=[progress(11.0), distance(5.0), ttc(2.0), lane_keeping(0.5), collision(), post_encroachment_time(1.0)],
    priority=["collision", "distance", "ttc", "progress", "lane_keeping"],
)
def test_pedestrian_crossing(case, world):
    road = world.straight_road(lanes=1, length=300)
    crosswalk = road.crosswalk(CROSSWALK_S, width=CROSSWALK_W)
    s_ego = CROSSWALK_S - case.d_ego
    world.ego(road.lane(0), s=s_ego, speed=case.ego_speed, target_speed=case.ego_speed)
    pedestrian_crossing(world, crosswalk, side="south", wait=case.ped_wait,
                        wait_in_road=case.ped_wait_in_road, speed=case.ped_speed, jitter=0.1)
    world.run(seconds=15)

"""Composition: three sub-scenarios along one longer route, activated opportunistically.

Situation: a 520 m two-way road (5.5 m lanes, parking along the south kerb). The ego drives
east at ``ego_speed``. Along its way three reusable sub-scenarios (``subscenarios.py``) wait
for it, each activated when the ego comes within a trigger distance of its place — its agents
stand still until then and the clocks of their behaviours start at that moment — and judged
only from activation until the ego has passed its agent (``only_while_relevant`` masks the
recording outside that window):

1. ``parked_car_pulling_out`` at 140 m: activated 60 m before, it pulls out into the ego's
   lane ``pull_out_after`` s later and drives on at ``pull_out_speed`` (it stays ahead).
2. ``pedestrian_crossing`` at a crosswalk at 280 m: activated 50 m before, the pedestrian
   waits ``ped_wait`` s, crosses at 1.4 m/s, standing ``ped_wait_in_road`` s in the road.
3. ``oncoming_encroacher`` at 430 m: activated 110 m before, an oncoming car pulls away with
   ``throttle`` and drifts ``encroach`` m left of its lane centre for 3 s from
   ``encroach_after`` s after activation.

Parameters: ``ego_speed`` [m/s] U(9, 13); ``pull_out_after`` [s] U(0, 3); ``pull_out_speed``
[m/s] U(4, 10); ``ped_wait`` [s] U(0, 8); ``ped_wait_in_road`` [s] U(0, 3); ``throttle`` [-]
U(0.2, 1); ``encroach`` [m] U(0, 4); ``encroach_after`` [s] U(0, 6).

Limits (see README.md): the simulator has one road per world, so this is a single straight
road, not the two-intersection network the issue asks for, and agents cannot be spawned or
removed during a run: they are placed up front and only their relevance is opportunistic.
"""

from pytest_avscenario import Uniform, scenario
from pytest_avscenario.monitors import collision, distance, lane_keeping, progress, ttc

from subscenarios import (
    oncoming_encroacher,
    only_while_relevant,
    parked_car_pulling_out,
    pedestrian_crossing,
)

ROAD_LENGTH = 520.0  # [m]


@scenario(
    ego_speed=Uniform(9.0, 13.0, nominal=11.0),  # [m/s]
    pull_out_after=Uniform(0.0, 3.0, nominal=0.5),  # [s] after activation
    pull_out_speed=Uniform(4.0, 10.0, nominal=9.0),  # [m/s]
    ped_wait=Uniform(0.0, 8.0, nominal=6.0),  # [s] after activation
    ped_wait_in_road=Uniform(0.0, 3.0, nominal=1.0),  # [s]
    throttle=Uniform(0.2, 1.0, nominal=0.5),  # [-]
    encroach=Uniform(0.0, 4.0, nominal=1.5),  # [m]
    encroach_after=Uniform(0.0, 6.0, nominal=0.0),  # [s] after activation
    samples=60,
    sampler=["halton", "mab"],
    monitors=[progress(11.0), distance(5.0), ttc(2.0), lane_keeping(0.5), collision()],
    priority=["collision", "distance", "ttc", "progress", "lane_keeping"],
)
def test_composed_route(case, world):
    road = world.two_way_road(lanes=1, length=ROAD_LENGTH, lane_width=5.5, parking_width=2.5)
    world.ego(road.lane(0), s=10.0, speed=case.ego_speed, target_speed=case.ego_speed)
    kerb = road.parking_lane
    spot = kerb.at(140.0)
    crosswalk = road.crosswalk(280.0, width=5.0)
    meet = road.lane(0).at(430.0)
    agents = [
        parked_car_pulling_out(world, road, s=spot.s, at=case.pull_out_after,
                               speed=case.pull_out_speed, trigger=(spot, 60.0)),
        pedestrian_crossing(world, crosswalk, side="south", wait=case.ped_wait,
                            wait_in_road=case.ped_wait_in_road, trigger=(crosswalk, 50.0)),
        oncoming_encroacher(world, road, s=ROAD_LENGTH - 500.0, throttle=case.throttle,
                            offset=case.encroach, max_speed=12.0, at=case.encroach_after,
                            duration=3.0, trigger=(meet, 110.0)),
    ]
    world.run(seconds=48)
    return only_while_relevant(world, agents)

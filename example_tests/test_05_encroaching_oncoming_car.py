"""Scenario 5 (NHTSA, the paper's Table 1): the AV responds to an oncoming car encroaching.

Situation: a two-way road, one 5.5 m lane each way (so that an oncoming car keeping its lane
passes the ego's centre at 5.5 m, outside the paper's 5-m distance bound), approaching a
junction 200 m from the road's start (the paper's "intersection"; here only a reference point,
the road carries on). The ego drives east at ``ego_speed`` starting ``d_ego`` m before the
junction. An oncoming car waits ``d_adv`` m beyond the junction in the westbound lane, pulls
away with ``throttle`` (fraction of 3 m/s^2) up to 12 m/s and, from ``encroach_at`` s for
``encroach_for`` s, drifts ``encroach`` m left of its lane centre — over the centre line into
the ego's lane — then back (a driver cutting a bend or overtaking a cyclist).

Parameters (the paper's three first): ``d_adv`` [m] U(20, 70) — the adversary's distance
from the junction; ``throttle`` [-] U(0.2, 1.0) — its throttle; ``d_ego`` [m] U(20, 70) —
the AV's distance from the junction; ``encroach`` [m] U(0, 4) — how far left of its lane
centre it drives (1.75 m puts its left edge on the centre line, 3.5 m its left edge where
the ego's left edge is); ``encroach_at`` [s] U(0, 8); ``encroach_for`` [s] U(1, 5);
``ego_speed`` [m/s] U(8, 13).

A failure means the AV came within 5 m (centres) of the oncoming car, was on course to within
5 m in under 2 s, stopped for good (progress < 11 m), left its lane centre, or touched it.
The autopilot does not leave its lane (it shifts within it and brakes), so a car crossing far
enough over the line is a collision it can only mitigate; the distance and TTC metrics count
every oncoming car passed at under 5 m, i.e. any drift of more than 0.5 m toward the ego at
the moment they meet.
"""

from pytest_avscenario import Uniform, scenario
from pytest_avscenario.monitors import collision, distance, lane_keeping, progress, ttc

from subscenarios import oncoming_encroacher

JUNCTION_X = 200.0  # [m]
ROAD_LENGTH = 400.0  # [m]


@scenario(
    d_adv=Uniform(20.0, 70.0, nominal=50.0, unit="m"),  # adversary beyond the junction
    throttle=Uniform(0.2, 1.0, nominal=0.5),  # [-] of 3 m/s^2
    d_ego=Uniform(20.0, 70.0, nominal=50.0, unit="m"),  # ego before the junction
    encroach=Uniform(0.0, 4.0, nominal=2.0, unit="m"),  # left of its lane centre
    encroach_at=Uniform(0.0, 8.0, nominal=1.0, unit="s"),
    encroach_for=Uniform(1.0, 5.0, nominal=2.0, unit="s"),
    ego_speed=Uniform(8.0, 13.0, nominal=10.0, unit="m/s"),
    samples=60,
    sampler=["halton", "mab"],
    monitors=[progress(11.0), distance(5.0), ttc(2.0), lane_keeping(0.5), collision()],
    priority=["collision", "distance", "ttc", "progress", "lane_keeping"],
)
def test_encroaching_oncoming_car(case, world):
    road = world.two_way_road(lanes=1, length=ROAD_LENGTH, parking=False, lane_width=5.5)
    world.ego(road.lane(0), s=JUNCTION_X - case.d_ego, speed=case.ego_speed,
              target_speed=case.ego_speed)
    # backward lanes run from x = ROAD_LENGTH westwards: s is measured from the east end
    oncoming_encroacher(world, road.lane(0, "backward"),
                        s=ROAD_LENGTH - JUNCTION_X - case.d_adv,
                        throttle=case.throttle, offset=case.encroach, max_speed=12.0,
                        at=case.encroach_at, duration=case.encroach_for)
    world.run(seconds=12)

"""Scenario 2 on a real map: the AV follows a braking lead on CARLA's Town06, starting on any
of its driving lanes.

Situation: Town06 (a CARLA town of long multi-lane highways joined by junctions, copied in
``maps/`` with its attribution). The ego starts 10 m into ``lane`` — drawn from every driving
lane of the map at least 100 m long outside junctions (52 lanes: straight highway lanes,
curved ramps, lanes in either direction) — at 12 m/s, driven by the AV under test along the
map's default route (straight on, the least turning way through each junction); a lead car
starts ``gap`` m ahead along the same route at ``lead_speed`` and, ``brake_at`` s into the
run, brakes at ``lead_decel`` down to ``lead_final_speed``, with its acceleration perturbed by
N(0, 0.3) m/s^2 every second from ``case.rng`` (as in ``test_02_vehicle_following``). Units:
m, m/s, s, m/s^2.

Parameters: ``lane`` (categorical, the lane id ``road/section/lane``), ``gap`` [m] U(10, 40),
``lead_speed`` [m/s] U(5, 15), ``brake_at`` [s] U(1, 5), ``lead_decel`` [m/s^2] U(1, 8),
``lead_final_speed`` [m/s] U(0, 8). Nominal: the first lane, a lead 30 m ahead at 10 m/s
slowing gently to 5 m/s after 3 s.

A failure as in ``test_02_vehicle_following``: closer than 5 m, TTC under 2 s, no progress, or
off the lane centre; here the lane centre is the map's own (curves, varying widths), and the
route may run through a junction's lanes. Expected corners: those of the built road plus
the lanes whose route turns through a junction within the first 100 m.
"""

from pytest_avscenario import MapLane, Uniform, scenario
from pytest_avscenario.monitors import collision, distance, lane_keeping, progress, ttc

from subscenarios import slow_down, wobble


@scenario(
    lane=MapLane("maps/Town06.xodr", kind="driving", min_length=100),
    gap=Uniform(10.0, 40.0, nominal=30.0, unit="m"),
    lead_speed=Uniform(5.0, 15.0, nominal=10.0, unit="m/s"),
    brake_at=Uniform(1.0, 5.0, nominal=3.0, unit="s"),
    lead_decel=Uniform(1.0, 8.0, nominal=2.5, unit="m/s²"),
    lead_final_speed=Uniform(0.0, 8.0, nominal=5.0, unit="m/s"),
    samples=20,
    sampler=["halton", "mab"],
    monitors=[progress(11.0), distance(5.0), ttc(2.0), lane_keeping(0.5), collision()],
    priority=["collision", "distance", "ttc", "progress", "lane_keeping"],
)
def test_town06_vehicle_following(case, world):
    town = world.map("maps/Town06.xodr")
    start = town.lane(case.lane).at(10.0)
    world.ego(start, speed=12.0)
    world.car(town.ahead(start, case.gap), speed=case.lead_speed,
              behavior=wobble(slow_down(case.brake_at, case.lead_decel, case.lead_final_speed),
                              sd=0.3))
    world.run(seconds=12)

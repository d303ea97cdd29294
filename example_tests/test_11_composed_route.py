"""Composition: three reusable sub-scenarios along a route through two intersections.

Situation: a road network of two four-way all-way-stop intersections, A at (0, 0) and B 200 m
due north, each with 60 m arms of 3.5 m lanes and a 2 m median (so that traffic keeping its
own lane passes 5.5 m from the ego's centre, outside the paper's 5-m distance bound), A's
north arm linked to B's south arm by a 57 m two-way road. The ego starts on A's south
approach and drives straight through A, along the link and straight through B, about 330 m
at ``ego_speed``, stopping at both stop lines. Three sub-scenarios from ``subscenarios.py``
wait along the route; each one's agents *appear* when the ego comes within a trigger
distance of its place (their behaviours' clocks start then) and *disappear* once the ego is
15 m past them (recorded as absent, so the monitors judge each sub-scenario only while it
applies):

1. ``pedestrian_crossing`` on the crosswalk across A's south arm, triggered 45 m before it:
   the pedestrian waits ``ped_wait`` s, then crosses (pace +-10 % drawn every second from
   ``case.rng``), standing ``ped_wait_in_road`` s in the road.
2. ``oncoming_encroacher`` coming south from B, triggered when the ego is 20 m from A's
   centre: a car ``oncoming_d`` m down B's south exit pulls away with ``throttle`` and drifts
   ``encroach`` m toward the ego's lane for 3 s from ``encroach_after`` s after it appeared,
   meeting the ego on the link.
3. ``crossing_traffic`` from B's west arm, triggered when the ego is 35 m from B's centre: a
   car ``cross_d`` m before the west stop line crosses at ``cross_speed`` without stopping
   (acceleration noise N(0, 0.3) m/s^2 drawn every second from ``case.rng``).

Parameters: ``ego_speed`` [m/s] U(8, 13); ``ped_wait`` [s] U(0, 12); ``ped_wait_in_road`` [s]
U(0, 3); ``oncoming_d`` [m] U(0, 40); ``throttle`` [-] U(0.2, 1); ``encroach`` [m] U(0, 4);
``encroach_after`` [s] U(0, 6); ``cross_d`` [m] U(10, 50); ``cross_speed`` [m/s] U(6, 13).

A failure names the sub-scenario that broke it by the agent in the worst moment
(``pedestrian``, ``oncoming``, ``cross1``).
"""

from pytest_avscenario import Uniform, scenario
from pytest_avscenario.monitors import collision, distance, lane_keeping, progress, ttc

from subscenarios import crossing_traffic, oncoming_encroacher, pedestrian_crossing

ARM = 60.0  # [m] approach length of every arm
SPACING = 200.0  # [m] between the intersections' centres


@scenario(
    ego_speed=Uniform(8.0, 13.0, nominal=11.0, unit="m/s"),
    ped_wait=Uniform(0.0, 12.0, nominal=10.0, unit="s"),  # after it appeared
    ped_wait_in_road=Uniform(0.0, 3.0, nominal=1.0, unit="s"),
    oncoming_d=Uniform(0.0, 40.0, nominal=20.0, unit="m"),  # down B's south exit
    throttle=Uniform(0.2, 1.0, nominal=0.5),  # [-] of 3 m/s^2
    encroach=Uniform(0.0, 4.0, nominal=1.0, unit="m"),
    encroach_after=Uniform(0.0, 6.0, nominal=0.0, unit="s"),  # after it appeared
    cross_d=Uniform(10.0, 50.0, nominal=25.0, unit="m"),  # before B's west stop line
    cross_speed=Uniform(6.0, 13.0, nominal=9.0, unit="m/s"),
    samples=60,
    sampler=["halton", "mab"],
    monitors=[progress(11.0), distance(5.0), ttc(2.0), lane_keeping(0.5), collision()],
    priority=["collision", "distance", "ttc", "progress", "lane_keeping"],
)
def test_composed_route(case, world):
    net = world.road_network()
    a = net.intersection("A", at=(0.0, 0.0), approach_length=ARM, median=2.0)
    b = net.intersection("B", at=(0.0, SPACING), approach_length=ARM, median=2.0)
    net.connect(a, "north", b, "south")
    world.ego(a.approach("south"), s=5.0, speed=case.ego_speed, target_speed=case.ego_speed,
              route=net.route(a.route("south"), b.route("south")))
    crosswalk = a.crosswalk("south")
    pedestrian_crossing(world, crosswalk, side="west", wait=case.ped_wait,
                        wait_in_road=case.ped_wait_in_road, jitter=0.1, trigger=(crosswalk, 45.0))
    oncoming_encroacher(world, b.exit("south"), s=case.oncoming_d, throttle=case.throttle,
                        offset=case.encroach, max_speed=12.0, at=case.encroach_after,
                        duration=3.0, trigger=(a.centre, 20.0))
    crossing_traffic(world, b, "west", first_s=b.stop_line("west").s - case.cross_d,
                     speed=case.cross_speed, jitter=0.3, trigger=(b.centre, 35.0))
    world.run(seconds=42)

"""Merging on a real map: a car from an on-ramp merges in front of the AV on esmini's
``highway_example_with_merge_and_split.xodr``.

Situation: a two-lane carriageway (3 m lanes) that a single-lane on-ramp joins through a
junction; the ramp continues as an acceleration lane beside the right lane for 89 m, its
width shrinking to nothing (the file's own width polynomial). The ego drives in the right
lane (``5/0/2``) at ``ego_speed`` from 20 m, a car on the ramp (``8/0/1``) starts ``ramp_s``
m along it at ``ramp_speed`` and merges left into the ego's lane — only into a gap that is
safe by MOBIL's criterion, waiting at the end of its lane when there is none. Units: m, m/s.

Parameters: ``ego_speed`` [m/s] U(10, 25); ``ramp_s`` [m] U(0, 55); ``ramp_speed`` [m/s]
U(8, 20). Nominal: the ego at 16 m/s, the ramp car 40 m up its ramp at 14 m/s, reaching the
merge well ahead of the ego.

A failure: a collision, the ego's centre off the carriageway (``off_road``), footprints
closer than 1 m (``distance``), a TTC below 2 s with a 3.5 m circle, or the ego off its lane
centre by 0.5 m on average. Expected corners: a ramp car arriving beside the ego, which
merges as soon as the gap behind the ego is safe for it — sometimes just ahead of a faster
ego.
"""

from pytest_avscenario import Uniform, scenario
from pytest_avscenario.monitors import collision, distance, lane_keeping, off_road, ttc


@scenario(
    ego_speed=Uniform(10.0, 25.0, nominal=16.0, unit="m/s"),
    ramp_s=Uniform(0.0, 55.0, nominal=40.0, unit="m"),
    ramp_speed=Uniform(8.0, 20.0, nominal=14.0, unit="m/s"),
    samples=20,
    sampler=["halton", "mab"],
    monitors=[collision(), off_road(), distance(1.0, footprint=True), ttc(2.0),
              lane_keeping(0.5)],
    priority=["collision", "off_road", "distance", "ttc", "lane_keeping"],
)
def test_map_highway_merge(case, world):
    road = world.map("maps/highway_example_with_merge_and_split.xodr")
    world.ego(road.lane("5/0/2").at(20.0), speed=case.ego_speed, target_speed=case.ego_speed)
    world.car(road.lane("8/0/1").at(case.ramp_s), speed=case.ramp_speed, name="ramp")
    world.run(seconds=14)

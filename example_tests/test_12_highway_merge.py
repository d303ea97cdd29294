"""Highway merging (beyond the paper's table): traffic merges into the ego's carriageway
from an on-ramp and from a lane that ends after a bend.

Situation: a two-lane highway (3.75 m lanes, 130 km/h limit) east from the origin: 300 m
straight, a 25-degree bend to the left of 600 m radius (262 m), 150 m straight at whose end
the right lane ends (a lane drop, 712 m from the start), then one lane. An on-ramp joins the right lane at 150 m (S-bend,
then a 120 m acceleration lane). The ego drives in the left lane at ``ego_speed`` from 60 m;
a car in the right lane, ``right_slower`` m/s slower, is placed so that at constant speeds
it would reach the end of its lane ``right_lead`` s before the ego gets there (negative:
after), and has to merge into the ego's lane before its lane ends; a car on the ramp starts
``ramp_s`` m along it at ``ramp_speed`` and merges into the right lane. Both merge only into a gap that is safe by MOBIL's
criterion (nobody brakes harder than 3 m/s^2 by the IDM) and wait at the end of their lane
when there is none. Units: m, m/s, s.

Parameters: ``ego_speed`` [m/s] U(20, 32); ``right_slower`` [m/s] U(0, 10); ``right_lead``
[s] U(-2, 4); ``ramp_s`` [m] U(0, 90); ``ramp_speed`` [m/s] U(10, 25). Nominal: the ego at
27 m/s, the right-lane car 3 m/s slower arriving 3 s before it, the ramp car 45 m up the
ramp at 18 m/s.

A failure: a collision, the ego's centre off the carriageway (``off_road``), footprints
closer than 1 m (``distance``), a TTC below 2 s (footprints meeting in the ego's path, so traffic
in the next lane is not counted) or the ego off its lane centre by 0.5 m on average (``lane_keeping``).
Expected corners: a right-lane car just ahead of the
ego and slower than it, merging in late at the lane drop; the autopilot sees the merging car
only once its footprint overlaps the ego's path.
"""

from pytest_avscenario import Uniform, scenario
from pytest_avscenario.monitors import collision, distance, lane_keeping, off_road, ttc
from pytest_avscenario.sim.highway import arc, straight


@scenario(
    ego_speed=Uniform(20.0, 32.0, nominal=27.0, unit="m/s"),
    right_slower=Uniform(0.0, 10.0, nominal=3.0, unit="m/s"),
    right_lead=Uniform(-2.0, 4.0, nominal=3.0, unit="s"),
    ramp_s=Uniform(0.0, 90.0, nominal=45.0, unit="m"),
    ramp_speed=Uniform(10.0, 25.0, nominal=18.0, unit="m/s"),
    samples=30,
    sampler=["halton", "mab"],
    monitors=[collision(), off_road(), distance(1.0, footprint=True), ttc(2.0),
              lane_keeping(0.5)],
    priority=["collision", "off_road", "distance", "ttc", "lane_keeping"],
)
def test_highway_merge(case, world):
    road = world.highway(lanes=2, lane_width=3.75, speed_limit=36.1, segments=[
        straight(300.0), arc(radius=600.0, angle=25.0), straight(150.0), straight(400.0, lanes=1)])
    ramp = road.on_ramp(at=150.0, merge_length=120.0, ramp_length=100.0, bend_length=60.0)
    ego_s, drop = 60.0, road.length - 400.0  # [m] along lane 0
    world.ego(road.at(ego_s, lane=0), speed=case.ego_speed, target_speed=case.ego_speed)
    v_right = case.ego_speed - case.right_slower
    right_s = drop - v_right * ((drop - ego_s) / case.ego_speed - case.right_lead)
    world.car(road.at(max(right_s, 0.0), lane=1), speed=v_right, name="right")
    world.car(ramp, s=case.ramp_s, speed=case.ramp_speed, name="ramp")
    world.run(seconds=30)

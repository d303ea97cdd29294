"""Scenario 2 (NHTSA, the paper's Table 1): the AV follows a leading car on a one-way road.

The lead starts ``gap`` metres ahead of the ego's centre at ``lead_speed`` and brakes hard
(``lead_decel``) after ``brake_at`` seconds; the ego starts at 12 m/s behind it, driven by
the AV under test. Units: metres, metres per second, seconds, metres per second squared.

A failure means the AV came closer than 5 m (centre to centre) to the lead, predicted a
collision within 2 s (TTC), stopped making progress, or drifted out of its lane centre.
"""

from pytest_avscenario import Uniform, scenario
from pytest_avscenario.monitors import distance, lane_keeping, progress, ttc
from pytest_avscenario.sim import behaviors as b


@scenario(
    gap=Uniform(10.0, 40.0, nominal=30.0),  # [m] lead ahead of the ego
    lead_speed=Uniform(5.0, 15.0),  # [m/s]
    brake_at=Uniform(1.0, 5.0),  # [s]
    lead_decel=Uniform(3.0, 8.0, nominal=4.0),  # [m/s^2]
    samples=60,
    sampler=["halton", "mab"],
    monitors=[progress(11.0), distance(5.0), ttc(2.0), lane_keeping(0.5)],
)
def test_vehicle_following(case, world):
    road = world.straight_road(lanes=1, length=400)
    world.ego(road.lane(0), s=20.0, speed=12.0)
    world.car(road.lane(0), s=20.0 + case.gap, speed=case.lead_speed,
              behavior=b.brake_at(case.brake_at, decel=case.lead_decel))
    world.run(seconds=10)

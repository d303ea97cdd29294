"""Scenario 2 (NHTSA, the paper's Table 1): the AV follows a leading car on a one-way road.

Situation: a one-lane road; the ego starts at 12 m/s, driven by the AV under test; a lead
car starts ``gap`` m ahead (centre to centre) at ``lead_speed`` and, ``brake_at`` s into the
run, brakes at ``lead_decel`` down to ``lead_final_speed`` (0: a full stop), then holds that
speed. The lead driver is imprecise: every second its acceleration is perturbed by
N(0, 0.3) m/s^2 drawn during the run from ``case.rng``. Units: m, m/s, s, m/s^2.

Parameters: ``gap`` [m] U(10, 40) (as in the Scenic reference), ``lead_speed`` [m/s]
U(5, 15), ``brake_at`` [s] U(1, 5), ``lead_decel`` [m/s^2] U(1, 8), ``lead_final_speed``
[m/s] U(0, 8). Nominal: a lead 30 m ahead at 10 m/s slowing gently (2.5 m/s^2) to 5 m/s
after 3 s — ordinary traffic.

A failure means the AV came closer than 5 m (centre to centre) to the lead, was ever on a
course to be within 5 m in under 2 s (TTC), stopped making progress, or left its lane centre.
Expected corners: a short initial gap (the ego starts closing at up to 7 m/s), hard braking
to a stop (the autopilot's IDM time gap of 1.5 s leaves a TTC under 2 s while it closes in
on a car that stands), and the perception latency plus brake jerk of the autopilot.
"""

from pytest_avscenario import Uniform, scenario
from pytest_avscenario.monitors import collision, distance, lane_keeping, progress, ttc

from subscenarios import slow_down, wobble


@scenario(
    gap=Uniform(10.0, 40.0, nominal=30.0, unit="m"),  # lead centre ahead of the ego centre
    lead_speed=Uniform(5.0, 15.0, nominal=10.0, unit="m/s"),
    brake_at=Uniform(1.0, 5.0, nominal=3.0, unit="s"),
    lead_decel=Uniform(1.0, 8.0, nominal=2.5, unit="m/s²"),
    lead_final_speed=Uniform(0.0, 8.0, nominal=5.0, unit="m/s"),
    samples=60,
    sampler=["halton", "mab"],
    monitors=[progress(11.0), distance(5.0), ttc(2.0), lane_keeping(0.5), collision()],
    priority=["collision", "distance", "ttc", "progress", "lane_keeping"],
)
def test_vehicle_following(case, world):
    road = world.straight_road(lanes=1, length=400)
    world.ego(road.lane(0), s=20.0, speed=12.0)
    world.car(road.lane(0), s=20.0 + case.gap, speed=case.lead_speed,
              behavior=wobble(slow_down(case.brake_at, case.lead_decel, case.lead_final_speed),
                              sd=0.3))
    world.run(seconds=12)

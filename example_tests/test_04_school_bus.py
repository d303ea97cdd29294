"""Scenario 4 (NHTSA, the paper's Table 1): the AV detects and responds to a school bus.

Situation: a two-way road, one 5.5 m lane each way. The ego drives east at ``ego_speed``. A
school bus drives either ahead of it in its lane or toward it in the oncoming lane
(``bus_from``), starting ``d_bus`` m from the ego (centres, along the road) at ``bus_speed``;
after ``bus_stop_at`` s it brakes to a stop at ``bus_decel``, puts its stop arm out for
``arm_for`` s, then drives on. Traffic in both directions must stop and stay behind a bus with
its arm out.

Parameters: ``bus_from`` in {"ahead", "oncoming"}; ``d_bus`` [m] U(15, 110); ``bus_speed``
[m/s] U(4, 13); ``bus_decel`` [m/s^2] U(1.5, 6); ``bus_stop_at`` [s] U(0.5, 6); ``arm_for`` [s]
U(3, 10); ``ego_speed`` [m/s] U(8, 18).

A failure means the AV drove past the bus's near end (plus 2 m) while the arm was out
(``school_bus``; excused when the arm came out too late to stop after 0.5 s at 6 m/s^2),
came within 5 m (centres) of it, was on course to within 5 m in under 2 s,
made no progress at all (< 11 m), left its lane centre, or collided.
"""

from pytest_avscenario import Choice, Uniform, scenario
from pytest_avscenario.monitors import collision, distance, lane_keeping, progress, ttc

from subscenarios import passes_stopped_school_bus, school_bus_stop

ROAD_LENGTH = 400.0  # [m]
EGO_S = 20.0  # [m]


@scenario(
    bus_from=Choice(["ahead", "oncoming"]),
    d_bus=Uniform(15.0, 110.0, nominal=70.0, unit="m"),  # bus centre from the ego centre
    bus_speed=Uniform(4.0, 13.0, nominal=7.0, unit="m/s"),
    bus_decel=Uniform(1.5, 6.0, nominal=3.0, unit="m/s²"),
    bus_stop_at=Uniform(0.5, 6.0, nominal=3.0, unit="s"),
    arm_for=Uniform(3.0, 10.0, nominal=6.0, unit="s"),
    ego_speed=Uniform(8.0, 18.0, nominal=11.0, unit="m/s"),
    samples=60,
    sampler=["halton", "mab"],
    monitors=[progress(11.0), distance(5.0), ttc(2.0), lane_keeping(0.5), collision(),
              passes_stopped_school_bus("bus")],
    priority=["collision", "school_bus", "distance", "ttc", "progress", "lane_keeping"],
)
def test_school_bus(case, world):
    road = world.two_way_road(lanes=1, length=ROAD_LENGTH, parking=False, lane_width=5.5)
    world.ego(road.lane(0), s=EGO_S, speed=case.ego_speed, target_speed=case.ego_speed)
    if case.bus_from == "ahead":
        s_bus, direction = EGO_S + case.d_bus, "forward"
    else:  # backward lanes are measured from the east end
        s_bus, direction = ROAD_LENGTH - EGO_S - case.d_bus, "backward"
    school_bus_stop(world, road, direction=direction, s=s_bus, speed=case.bus_speed,
                    stop_at=case.bus_stop_at, duration=case.arm_for, decel=case.bus_decel)
    world.run(seconds=16)

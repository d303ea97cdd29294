"""Scenario 8 (NHTSA, the paper's Table 1): the AV turns left, unprotected, while a lateral car
cuts across the intersection.

Situation: a four-way, one-lane-per-approach intersection with 5.5 m lanes (opposing cars
pass 5.5 m apart, outside the paper's 5-m distance bound). The ego comes from the south
``d_ego`` m before its stop line and turns left (to the west). An oncoming car from the north
goes straight through after its stop: ordinary all-way-stop traffic, first to stop first to go
(the autopilot infers the arrival order from what it sees). A lateral car on the
``lateral_from`` approach, ``d_lateral`` m before its line, starts ``lateral_delay`` s into the
run and crosses straight at ``lateral_speed`` without stopping (a red-light / stop-sign runner;
its acceleration wobbles by N(0, 0.3) m/s^2 drawn every second from ``case.rng``) — across
the ego's turn.

Parameters: ``d_ego`` [m] U(5, 40); ``lateral_from`` in {"west", "east"}; ``d_lateral`` [m]
U(10, 80); ``lateral_speed`` [m/s] U(6, 14); ``lateral_delay`` [s] U(0, 4); ``d_oncoming`` [m]
U(10, 60).

A failure means the AV came within 5 m (centres) of either car, was on course to within 5 m
in under 2 s, did not complete enough of its turn (progress), left its lane centre, or collided.
"""

from pytest_avscenario import Choice, Uniform, scenario
from pytest_avscenario.monitors import collision, distance, lane_keeping, progress, ran_stop, ttc
from pytest_avscenario.sim import behaviors as b

from subscenarios import crossing_traffic


@scenario(
    d_ego=Uniform(5.0, 40.0, nominal=20.0, unit="m"),  # ego centre before its stop line
    lateral_from=Choice(["west", "east"]),
    d_lateral=Uniform(10.0, 80.0, nominal=70.0, unit="m"),  # lateral car before its stop line
    lateral_speed=Uniform(6.0, 14.0, nominal=10.0, unit="m/s"),
    lateral_delay=Uniform(0.0, 4.0, nominal=0.0, unit="s"),
    d_oncoming=Uniform(10.0, 60.0, nominal=40.0, unit="m"),  # oncoming car before its stop line
    samples=60,
    sampler=["halton", "mab"],
    monitors=[progress(11.0), distance(5.0), ttc(2.0), lane_keeping(0.5), collision(), ran_stop()],
    priority=["collision", "distance", "ttc", "progress", "lane_keeping"],
)
def test_unprotected_left_lateral_car(case, world):
    inter = world.intersection(lanes=1, lane_width=5.5)
    world.ego(inter.stop_line("south").before(case.d_ego), speed=6.0, target_speed=9.0,
              route=inter.route("south", "left"))
    world.car(inter.stop_line("north").before(case.d_oncoming), speed=8.0,
              behavior=b.turn("straight", speed=8.0))
    stop_s = inter.stop_line(case.lateral_from).s
    crossing_traffic(world, inter, case.lateral_from, first_s=stop_s - case.d_lateral,
                     speed=case.lateral_speed, start_at=case.lateral_delay, jitter=0.3)
    world.run(seconds=15)

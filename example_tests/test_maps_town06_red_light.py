"""A signalled junction on CARLA's Town06: the light turns amber as the AV approaches.

Situation: Town06 (``maps/``, with its attribution) has 19 traffic lights at 8 junctions,
read from the file's ``<signal>``/``<signalReference>``/``<controller>`` elements. The ego
drives east-west along road 49's lane ``49/0/-3`` toward junction 1162 and straight through
it, driven by the AV under test at ``speed`` (also its cruise speed) from 130 m before the
stop position of light 1238, which rules its lane. The junction runs the fixed-time plan of
``world.signals`` (10 s green, ``amber`` s amber, 2 s all-red, its two controllers taking
turns); the plan is shifted so that light 1238 turns amber when the ego, at its initial
speed, is ``time_to_line`` seconds from the stop position: the classic dilemma-zone
variable. A driver that can stop comfortably should; one that cannot should be able to clear
the line before red. An amber shorter than the approach speed needs (the ITE formula: 1 s +
v / (2 x 3 m/s^2)) leaves a zone where it can do neither. Units: m, m/s, s.

Parameters: ``speed`` [m/s] U(12, 25) (43-90 km/h), ``amber`` [s] U(1.5, 3.5),
``time_to_line`` [s] U(1.0, 4.0). Nominal: 14 m/s, a 3-s amber starting 4 s from the line
(it stops).

A failure: ``ran_red_light`` (CARLA's ``RunningRedLightTest``: the front bumper crosses the
stop position on red; ρ [m] is minus the room to stop it had when the light turned red), or
a collision. Expected corners: short ambers at high speed with the amber starting 2-3.5 s
from the line; the autopilot goes on when stopping would need more than its comfortable
3.5 m/s^2 and cannot clear the line in time.
"""

from pytest_avscenario import Uniform, scenario
from pytest_avscenario.monitors import collision, ran_red_light

START_M = 130.0  # [m] from the ego's front bumper to the stop position at t = 0


@scenario(
    speed=Uniform(12.0, 25.0, nominal=14.0, unit="m/s"),
    amber=Uniform(1.5, 3.5, nominal=3.0, unit="s"),
    time_to_line=Uniform(1.0, 4.0, nominal=4.0, unit="s"),
    samples=20,
    sampler=["halton", "mab"],
    monitors=[ran_red_light(), collision()],
    priority=["collision", "ran_red_light"],
)
def test_town06_red_light(case, world):
    town = world.map("maps/Town06.xodr")
    lights = world.signals(amber=case.amber)
    approach = town.lane("49/0/-3")
    route = town.default_route(approach)
    light = lights.first_on(route.lanes)  # "1238", at the start of the junction's lane
    lights.amber_at(light, START_M / case.speed - case.time_to_line)
    world.ego(approach, s=approach.length - START_M - 2.5, speed=case.speed,
              target_speed=case.speed, route=route)
    world.run(seconds=14)

"""UN R157 (ALKS) traffic disturbance: the lead vehicle decelerates in front of the ego.

Source: UN Regulation No. 157, Automated Lane Keeping Systems — original series
(ECE/TRANS/WP.29/2020/81, in force 22 January 2021; ego speed up to 60 km/h) and its 01
series of amendments (ECE/TRANS/WP.29/2022/59/Rev.1, 2022; up to 130 km/h). Annex 4,
Appendix 3 "Guidance on traffic disturbance critical scenarios for ALKS" names this one of
the three critical disturbances (lead deceleration, cut-in, cut-out) and defines the careful
and competent (C&C) driver whose performance the ALKS must at least match: it must avoid a
collision wherever that driver avoids one. Annex 5, 4.3 is the corresponding test
("following a lead vehicle", including its emergency braking).

The regulation's text gives the scenario qualitatively; the parameter ranges below follow
the public ASAM OpenSCENARIO interpretation of those tests, asam-oss/OSC-ALKS-scenarios
(BMW AG, MPL-2.0), file LogicalScenarios/ALKS_Scenario_4.3_2_FollowLeadVehicleEmergencyBrake_
Variation.xosc: ego speed 7.2-60 km/h with an initial time headway rising from 1.0 s to
1.6 s (the original series' minimum time gap at those speeds), lead deceleration 6 m/s^2,
straight roads and bends of 250 m and 1000 m radius. Here:

* ``ego_speed`` [km/h] U(20, 130): the 01 series' range (below 20 km/h the run is a crawl);
* ``headway`` [s] U(1.0, 2.0): bumper-to-bumper time gap at the start, both at ego speed;
* ``lead_decel`` [m/s^2] U(2, 6): up to the implementation's 6 m/s^2;
* ``brake_at`` [s] U(1, 4): when the lead starts braking (it brakes to a stop);
* ``curve``: "straight", or a 1000-m-radius bend "left"/"right" (30 degrees, see r157.py).

The lead follows a speed profile (hold, then brake linearly to a stop), the ego keeps the
middle lane of a three-lane motorway at its initial speed. Nominal: 100 km/h, 1.6 s, a
3 m/s^2 stop after 2 s on a straight road — a firm but ordinary stop.

A failure: a collision, the ego's centre off the carriageway at any step (``off_road``: an
agent that leaves the road fails here whatever else it does), the footprints closer than
1 m (``distance``), a TTC below the C&C driver's critical 2 s (``ttc``: footprints
meeting in the ego's path, so traffic in the next lane is not counted), or the ego off its lane centre by 0.5 m on
average (``lane_keeping``, for the bends). Every counterexample is also judged avoidable or
not by R157's C&C driver (the plugin's default reference driver); ``--avs-accept
avoidable`` applies the regulation's criterion: a counterexample counts only when that
driver avoids the same violation.
"""

from pytest_avscenario import Choice, Uniform, scenario
from pytest_avscenario.monitors import collision, distance, lane_keeping, off_road, ttc
from pytest_avscenario.sim import behaviors as b

from r157 import CC, EGO_LANE, EGO_S, KMH, motorway


@scenario(
    ego_speed=Uniform(20.0, 130.0, nominal=100.0, unit="km/h"),
    headway=Uniform(1.0, 2.0, nominal=1.6, unit="s"),
    lead_decel=Uniform(2.0, 6.0, nominal=3.0, unit="m/s²"),
    brake_at=Uniform(1.0, 4.0, nominal=2.0, unit="s"),
    curve=Choice(["straight", "left", "right"]),
    samples=30,
    sampler=["halton", "mab"],
    monitors=[collision(), off_road(), distance(1.0, footprint=True),
              ttc(CC.critical_ttc), lane_keeping(0.5)],
    priority=["collision", "off_road", "distance", "ttc", "lane_keeping"],
)
def test_r157_lead_deceleration(case, world):
    v = case.ego_speed * KMH
    road = motorway(world, case.curve)
    world.ego(road.at(EGO_S, lane=EGO_LANE), speed=v, target_speed=v)
    stop_at = case.brake_at + v / case.lead_decel
    world.car(road.at(EGO_S + 5.0 + case.headway * v, lane=EGO_LANE), speed=v, name="lead",
              behavior=b.speed_profile([(case.brake_at, v), (stop_at, 0.0)],
                                       max_decel=case.lead_decel + 1.0))
    world.run(seconds=stop_at + 4.0)

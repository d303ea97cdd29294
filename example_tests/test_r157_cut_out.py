"""UN R157 (ALKS) traffic disturbance: the lead vehicle cuts out, revealing a stopped or
slower vehicle ahead.

Source: UN Regulation No. 157, Automated Lane Keeping Systems — original series
(ECE/TRANS/WP.29/2020/81, in force 22 January 2021; ego speed up to 60 km/h) and its 01
series of amendments (ECE/TRANS/WP.29/2022/59/Rev.1, 2022; up to 130 km/h). Annex 4,
Appendix 3 "Guidance on traffic disturbance critical scenarios for ALKS" describes the
cut-out: the lead vehicle leaves the lane and reveals a vehicle that is stationary or much
slower; the careful and competent (C&C) driver perceives it as it is revealed, reacts
(0.4 s + 0.75 s) and brakes (0.774 g in 0.6 s). Annex 5, 4.5 is the corresponding test
("stationary obstacle after lane change of the lead vehicle").

The parameter ranges follow the public ASAM OpenSCENARIO interpretation of those tests,
asam-oss/OSC-ALKS-scenarios (BMW AG, MPL-2.0), file LogicalScenarios/ALKS_Scenario_4.5_1_
CutOutFullyBlocking_Variation.xosc: ego speed 5-60 km/h, the lead leaving to the left or
right when its front is 10-100 m from the blocking object, at a maximum lateral velocity of
0.5-3.0 m/s. Here:

* ``ego_speed`` [km/h] U(20, 130): the 01 series' range; the lead drives at it too;
* ``headway`` [s] U(1.0, 2.0): the ego's time gap to the lead at the start;
* ``side``: the lead leaves to the "left" or "right";
* ``reveal_ttc`` [s] U(2.5, 6.0): the lead starts out when its time gap to the revealed
  vehicle (gap over its own speed) is below this — the implementation's 10-100 m as time;
  below ~2.5 s a lead at the slowest lateral speed would hit the vehicle itself;
* ``lateral_speed`` [m/s] U(1.0, 3.0): how fast the lead moves across (the implementation
  goes down to 0.5 m/s, which with the shortest distances makes the lead crash itself);
* ``revealed_speed`` [km/h] U(0, 40): the revealed vehicle's speed; 0 is R157's
  stationary obstacle.

Nominal: 90 km/h, 1.6 s behind the lead, which leaves to the left 4 s before a stopped car
at 1.5 m/s. A failure: as in test_r157_lead_deceleration (collision, off the road,
footprints closer than 1 m, TTC below 2 s in the ego's path), without lane keeping (as in
the cut-in: swerving round the revealed vehicle is legitimate, leaving the road is not);
``--avs-accept avoidable`` applies the regulation's criterion: only counterexamples R157's
C&C driver avoids count.
"""

from pytest_avscenario import Choice, Uniform, scenario
from pytest_avscenario.monitors import collision, distance, off_road, ttc
from pytest_avscenario.sim import behaviors as b

from r157 import CC, EGO_LANE, EGO_S, KMH, motorway


@scenario(
    ego_speed=Uniform(20.0, 130.0, nominal=90.0, unit="km/h"),
    headway=Uniform(1.0, 2.0, nominal=1.6, unit="s"),
    side=Choice(["left", "right"]),
    reveal_ttc=Uniform(2.5, 6.0, nominal=4.0, unit="s"),
    lateral_speed=Uniform(1.0, 3.0, nominal=1.5, unit="m/s"),
    revealed_speed=Uniform(0.0, 40.0, nominal=0.0, unit="km/h"),
    samples=30,
    sampler=["halton", "mab"],
    monitors=[collision(), off_road(), distance(1.0, footprint=True),
              ttc(CC.critical_ttc)],
    priority=["collision", "off_road", "distance", "ttc"],
)
def test_r157_cut_out(case, world):
    v = case.ego_speed * KMH
    v_rev = case.revealed_speed * KMH
    road = motorway(world)
    world.ego(road.at(EGO_S, lane=EGO_LANE), speed=v, target_speed=v)
    lead_s = EGO_S + 5.0 + case.headway * v
    world.car(road.at(lead_s, lane=EGO_LANE), speed=v, name="lead",
              behavior=b.cut_out(time_gap=case.reveal_ttc, ahead="revealed", to=case.side,
                                 lateral_speed=case.lateral_speed))
    # the lead reaches its trigger point after about 3 s of closing in
    closing = max(v - v_rev, 1.0)
    revealed_s = lead_s + 5.0 + case.reveal_ttc * v + 3.0 * closing
    world.car(road.at(revealed_s, lane=EGO_LANE), speed=v_rev, name="revealed",
              behavior=b.keep_lane() if v_rev > 0 else b.stopped())
    world.run(seconds=3.0 + case.reveal_ttc + 8.0)

"""UN R157 (ALKS) traffic disturbance: a slower vehicle cuts into the ego's lane.

Source: UN Regulation No. 157, Automated Lane Keeping Systems — original series
(ECE/TRANS/WP.29/2020/81, in force 22 January 2021; ego speed up to 60 km/h) and its 01
series of amendments (ECE/TRANS/WP.29/2022/59/Rev.1, 2022; up to 130 km/h). Annex 4,
Appendix 3 "Guidance on traffic disturbance critical scenarios for ALKS" describes the
cut-in by the cutting vehicle's lateral velocity and the longitudinal distance (or TTC) to
it when it starts across, and defines the careful and competent (C&C) driver: it perceives
the cut-in once the vehicle leaves its lateral wandering zone (0.375 m) toward the ego's
lane, then reacts (0.4 s + 0.75 s) and brakes (0.774 g in 0.6 s). Annex 5, 4.4 is the
corresponding test ("lane change of another vehicle into the lane").

The parameter ranges follow the public ASAM OpenSCENARIO interpretation of those tests,
asam-oss/OSC-ALKS-scenarios (BMW AG, MPL-2.0), file LogicalScenarios/ALKS_Scenario_4.4_1_
CutInNoCollision_Variation.xosc: ego speed 20-60 km/h, the cutting vehicle 10-50 km/h
slower, from the lane left or right, starting across at a headway distance of 0-60 m, with
a maximum lateral velocity of 0.5-3.0 m/s. Here:

* ``ego_speed`` [km/h] U(20, 130): the 01 series' range;
* ``side``: the cutting vehicle comes from the lane "left" or "right" of the ego;
* ``slower_by`` [km/h] U(10, 50): its speed below the ego's (never below 10 km/h, the
  implementation's slowest cutting vehicle: slower combinations are clipped there);
* ``time_gap`` [s] U(0.3, 2.0): it starts across when the ego's time gap to it (bumper to
  bumper, at the ego's speed) drops below this — the implementation's 0-60 m expressed as
  time, which at 20-130 km/h covers 0-11 s; below 0.3 s no vehicle fits;
* ``lateral_speed`` [m/s] U(0.5, 3.0): how fast it moves across.

The ego keeps the middle lane of a three-lane motorway at its initial speed; the cutting
vehicle starts 2 s of closing before the trigger point ahead of it. Nominal: 90 km/h, a car
20 km/h slower from the left at 1.5 s moving across at 1 m/s — an ordinary cut-in.

A failure: as in test_r157_lead_deceleration (collision, off the road, footprints closer
than 1 m, TTC below 2 s in the ego's path), without lane keeping: changing lane away
from the cutting vehicle is a legitimate answer that the paper's mean lane offset would
count against the ego; ``off_road`` still fails an ego that leaves the carriageway.
Cut-ins closer than the C&C driver can handle are unavoidable by design (the Annex's
"unavoidable collision" cases); ``--avs-accept avoidable`` counts only counterexamples the
C&C driver avoids.
"""

from pytest_avscenario import Choice, Uniform, scenario
from pytest_avscenario.monitors import collision, distance, off_road, ttc
from pytest_avscenario.sim import behaviors as b

from r157 import CC, EGO_LANE, EGO_S, KMH, motorway


@scenario(
    ego_speed=Uniform(20.0, 130.0, nominal=90.0, unit="km/h"),
    side=Choice(["left", "right"]),
    slower_by=Uniform(10.0, 50.0, nominal=20.0, unit="km/h"),
    time_gap=Uniform(0.3, 2.0, nominal=1.5, unit="s"),
    lateral_speed=Uniform(0.5, 3.0, nominal=1.0, unit="m/s"),
    samples=30,
    sampler=["halton", "mab"],
    monitors=[collision(), off_road(), distance(1.0, footprint=True),
              ttc(CC.critical_ttc)],
    priority=["collision", "off_road", "distance", "ttc"],
)
def test_r157_cut_in(case, world):
    v = case.ego_speed * KMH
    v_cut = max(case.ego_speed - case.slower_by, 10.0) * KMH
    road = motorway(world)
    world.ego(road.at(EGO_S, lane=EGO_LANE), speed=v, target_speed=v)
    # ahead so that the trigger point is 2 s of closing away
    gap0 = case.time_gap * v + 2.0 * (v - v_cut) + 5.0
    lane = EGO_LANE - 1 if case.side == "left" else EGO_LANE + 1
    world.car(road.at(EGO_S + gap0, lane=lane), speed=v_cut, name="cutter",
              behavior=b.cut_in(time_gap=case.time_gap, lateral_speed=case.lateral_speed))
    world.run(seconds=2.0 + LANE_CROSSING / case.lateral_speed + 6.0)


LANE_CROSSING = 3.75  # [m] lateral distance the cutting vehicle covers

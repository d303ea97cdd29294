"""Shared pieces of the UN R157 (ALKS) example scenarios (``test_r157_*.py``).

The road: a three-lane motorway (3.75 m lanes, 130 km/h limit), the ego in the middle lane
so a vehicle can cut in or out on either side. Scenarios with a ``curve`` parameter run
through a 1000-m-radius bend to the left or right, the larger of the two radii the ASAM
OpenSCENARIO interpretation of the regulation's tests (asam-oss/OSC-ALKS-scenarios) varies
(its 250 m radius is for speeds below 60 km/h only).

The careful and competent driver's figures of R157 Annex 4 Appendix 3 (risk perception
0.4 s, reaction 0.75 s, 0.774 g in 0.6 s, lateral wandering 0.375 m, critical TTC 2 s) live
in :mod:`pytest_avscenario.sim.drivers.reference`; :data:`CC` is that driver's options, so a
scenario quotes the regulation's numbers from one place.
"""

from pytest_avscenario.sim.drivers.reference import CarefulDriverOptions
from pytest_avscenario.sim.highway import arc, straight

#: the careful and competent driver of R157 Annex 4 Appendix 3 (its figures as attributes)
CC = CarefulDriverOptions()

KMH = 1 / 3.6  # [m/s] per km/h
LANE_WIDTH = 3.75  # [m]
EGO_LANE = 1  # the middle one of three (0 leftmost)
EGO_S = 20.0  # [m] where the ego starts along the road
BEND_RADIUS = 1000.0  # [m]


def motorway(world, curve: str = "straight", length: float = 1400.0):
    """The three-lane motorway; ``curve`` "left"/"right" puts a 30-degree bend of
    :data:`BEND_RADIUS` 150 m after the start (~524 m long), "straight" none."""
    if curve == "straight":
        segments = [straight(length)]
    else:
        angle = 30.0 if curve == "left" else -30.0
        bend = BEND_RADIUS * 30.0 * 3.141592653589793 / 180.0
        segments = [straight(150.0), arc(BEND_RADIUS, angle), straight(length - 150.0 - bend)]
    return world.highway(lanes=3, segments=segments, lane_width=LANE_WIDTH,
                         speed_limit=130 * KMH)

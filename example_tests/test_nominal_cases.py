"""Guard: the nominal case of every example scenario passes against the built-in autopilot.

Not a scenario test (``-m scenario`` skips it): it runs each module's nominal parameters for
three behaviour seeds outside the sampler and checks every declared monitor, so a change to
the autopilot or the simulator that breaks an ordinary situation shows up as one plain
failure naming the scenario and the metric. Parallel parking is held to its own monitors
only: the paper's distance and TTC cannot hold for any driver there (see its module).
"""

import importlib
import math

import pytest

from scout import run_one, scenario_tests

MODULES = [
    "test_01_low_speed_merge", "test_02_vehicle_following", "test_03_parallel_parking",
    "test_04_school_bus", "test_05_encroaching_oncoming_car", "test_06_pedestrian_crossing",
    "test_07_oncoming_left_turn", "test_08_unprotected_left_lateral_car",
    "test_09_right_turn_lateral_car", "test_10_unprotected_left_pedestrian",
    "test_11_composed_route", "test_12_highway_merge", "test_r157_lead_deceleration", "test_r157_cut_in",
    "test_r157_cut_out", "test_maps_town06_following", "test_maps_fabriksgatan_left_turn",
    "test_maps_highway_merge",
]
EXEMPT = {"test_03_parallel_parking": {"distance", "ttc"}}


@pytest.mark.parametrize("seed", [0, 1, 2])
@pytest.mark.parametrize("module", MODULES)
def test_nominal_case_passes(module, seed):
    from pytest_avscenario.space import FeatureSpace

    ((name, fn, spec),) = scenario_tests(importlib.import_module(module))
    params = FeatureSpace(spec.parameters).nominal()
    verdict, _, error, _ = run_one(fn, spec, params, seed, "autopilot")
    assert error is None, error
    bad = {m: rho for m, rho in verdict.rho.items()
           if rho < 0 and m not in EXEMPT.get(module, set())}
    assert not bad, (f"{module} nominal case (seed {seed}) violates "
                     + ", ".join(f"{m} (rho={r:+.3f})" for m, r in bad.items())
                     + f"; parameters {params}")
    assert all(not math.isnan(r) for r in verdict.rho.values())

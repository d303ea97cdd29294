"""Budgeted shrinking toward the nominal scenario (pytest_avscenario.shrink).

Synthetic predicates with known failure boundaries stand in for simulations; every test
counts the predicate's calls itself rather than trusting ShrinkResult.sims.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import warnings

import pytest

from pytest_avscenario.shrink import ShrinkSeedingWarning, minimize
from pytest_avscenario.space import Choice, FeatureSpace, IntRange, SpaceError, Uniform

GAP_BOUNDARY = 17.3  # fails iff gap < 17.3 (nominal 30, failing 12)
SPEED_BOUNDARY = 11.2  # fails iff speed > 11.2 (nominal 10, failing 14)


def following_space():
    return FeatureSpace({
        "gap": Uniform(10.0, 40.0, nominal=30.0),
        "speed": Uniform(5.0, 15.0),  # nominal 10
        "road": Choice(["dry", "wet", "icy"]),
        "lanes": 2,
    })


FAILING = {"gap": 12.0, "speed": 14.0, "road": "wet", "lanes": 2}


class Counting:
    """A predicate that records every call (the "simulations")."""

    def __init__(self, fails):
        self.fails = fails
        self.calls: list[dict] = []

    def __call__(self, params):
        self.calls.append(dict(params))
        return self.fails(params)


def both(p):
    return p["gap"] < GAP_BOUNDARY and p["speed"] > SPEED_BOUNDARY


def either(p):
    return p["gap"] < GAP_BOUNDARY or p["speed"] > SPEED_BOUNDARY


def assert_near(value, boundary, nominal, failing, side):
    """Within 5 % of the boundary (relative to it, and to the nominal→failing path), on
    the failing side."""
    assert side(value)
    assert abs(value - boundary) <= 0.05 * abs(boundary)
    assert abs(value - boundary) <= 0.05 * abs(failing - nominal)


def test_lands_at_both_boundaries_within_default_budget():
    pred = Counting(both)
    r = minimize(following_space(), FAILING, pred)
    assert r.budget == 20 and r.sims == len(pred.calls) <= 20
    assert_near(r.minimized["gap"], GAP_BOUNDARY, 30.0, 12.0, lambda v: v < GAP_BOUNDARY)
    assert_near(r.minimized["speed"], SPEED_BOUNDARY, 10.0, 14.0, lambda v: v > SPEED_BOUNDARY)
    # the road does not matter, so it went back to the nominal option; constants untouched
    assert r.minimized["road"] == "dry" and r.minimized["lanes"] == 2
    assert r.improved and r.original == FAILING
    assert both(r.minimized)
    assert [p for p, _ in r.candidates] == pred.calls
    assert all(v == both(p) for p, v in r.candidates)


def test_a_coordinate_that_does_not_matter_goes_back_to_nominal():
    pred = Counting(either)
    r = minimize(following_space(), FAILING, pred)
    assert r.minimized["gap"] == 30.0  # the speed alone keeps it failing
    assert r.minimized["road"] == "dry"
    assert_near(r.minimized["speed"], SPEED_BOUNDARY, 10.0, 14.0, lambda v: v > SPEED_BOUNDARY)
    assert r.sims == len(pred.calls) <= 20


@pytest.mark.parametrize("budget", [1, 2, 3, 7, 20, 33])
def test_the_budget_is_exact(budget):
    pred = Counting(both)
    r = minimize(following_space(), FAILING, pred, budget=budget)
    assert r.sims == len(pred.calls) <= budget
    assert r.exhausted == (r.sims == budget)  # this case needs ~35 to converge
    assert both(r.minimized)


def test_budget_zero_returns_the_original_without_simulating():
    pred = Counting(both)
    r = minimize(following_space(), FAILING, pred, budget=0)
    assert pred.calls == [] and r.sims == 0 and r.candidates == ()
    assert r.minimized == r.original == FAILING and not r.improved and not r.exhausted


def test_unbounded_converges_and_stops_on_its_own():
    pred = Counting(both)
    r = minimize(following_space(), FAILING, pred, budget=10_000)
    assert not r.exhausted and r.sims == len(pred.calls) < 60
    assert GAP_BOUNDARY - 18 / 1000 < r.minimized["gap"] < GAP_BOUNDARY
    assert SPEED_BOUNDARY < r.minimized["speed"] < SPEED_BOUNDARY + 4 / 1000


def test_categorical_shrinks_to_the_nominal_option_when_that_still_fails():
    space = FeatureSpace({"weather": Choice(["clear", "rain", "fog"]), "gap": Uniform(10, 40)})
    r = minimize(space, {"weather": "fog", "gap": 25.0}, Counting(lambda p: True))
    assert r.minimized == {"weather": "clear", "gap": 25.0} and r.sims == 1

    # ... and keeps the failing option when the failure needs it (the gap's nominal 25
    # already fails with fog, so the gap goes back to it)
    pred = Counting(lambda p: p["weather"] == "fog" and p["gap"] > 20)
    r = minimize(space, {"weather": "fog", "gap": 40.0}, pred)
    assert r.minimized == {"weather": "fog", "gap": 25.0}
    assert r.sims <= 3  # flags, then the all-nominal case


def test_integer_parameter_shrinks_to_the_exact_boundary():
    space = FeatureSpace({"vehicles": IntRange(1, 40, nominal=2)})
    pred = Counting(lambda p: p["vehicles"] >= 7)
    r = minimize(space, {"vehicles": 31}, pred)
    assert r.minimized == {"vehicles": 7}
    assert all(isinstance(p["vehicles"], int) for p in pred.calls)
    assert len({p["vehicles"] for p in pred.calls}) == len(pred.calls)


def test_memoized_no_candidate_twice_and_never_the_original():
    pred = Counting(both)
    minimize(following_space(), FAILING, pred, budget=500)
    keys = [json.dumps(p, sort_keys=True) for p in pred.calls]
    assert len(keys) == len(set(keys))
    assert FAILING not in pred.calls


def test_every_simulated_candidate_lies_in_the_space_between_nominal_and_failing():
    space = following_space()
    pred = Counting(both)
    minimize(space, FAILING, pred, budget=100)
    for p in pred.calls:
        space.validate(p)
        assert 12.0 <= p["gap"] <= 30.0 and 10.0 <= p["speed"] <= 14.0
        assert p["road"] in ("dry", "wet")


def test_nothing_to_shrink():
    space = following_space()
    pred = Counting(both)
    nominal = space.nominal()
    r = minimize(space, nominal, pred)
    assert r.sims == 0 and r.minimized == nominal and not r.improved


def test_failing_case_outside_the_space_is_refused():
    with pytest.raises(SpaceError, match="gap"):
        minimize(following_space(), dict(FAILING, gap=99.0), both)


def test_an_exception_in_still_fails_stops_shrinking_and_propagates():
    calls = []

    def broken(p):
        calls.append(p)
        if len(calls) == 3:
            raise RuntimeError("simulator crashed")
        return both(p)

    with pytest.raises(RuntimeError, match="simulator crashed"):
        minimize(following_space(), FAILING, broken)
    assert len(calls) == 3


def test_deterministic_in_process():
    a = minimize(following_space(), FAILING, both, budget=13, seed=4)
    b = minimize(following_space(), FAILING, both, budget=13, seed=4)
    assert a == b


_SUBPROCESS = """
import json, sys
sys.path.insert(0, {tests!r})
from test_shrink import FAILING, both, following_space
from pytest_avscenario.shrink import minimize
r = minimize(following_space(), FAILING, both, budget=13, seed=4)
print(json.dumps([r.minimized, r.sims, [c for c in r.candidates]], sort_keys=True))
"""


def test_deterministic_across_processes():
    r = minimize(following_space(), FAILING, both, budget=13, seed=4)
    here = json.dumps([r.minimized, r.sims, [c for c in r.candidates]], sort_keys=True)
    code = _SUBPROCESS.format(tests=os.path.dirname(__file__))
    env = dict(os.environ, PYTHONHASHSEED="12345")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         env=env, timeout=120, check=True)
    assert out.stdout.strip() == here
    assert out.stderr == ""  # no Hypothesis output


def test_quiet(capfd):
    minimize(following_space(), FAILING, both)
    out, err = capfd.readouterr()
    assert out == "" and err == ""


def test_does_not_touch_the_users_hypothesis_database(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    minimize(following_space(), FAILING, both)
    assert not (tmp_path / ".hypothesis").exists()


# ----------------------------------------------------------------- Hypothesis canary
# These fail when a new Hypothesis version changes what the seeding relies on. Fix
# pytest_avscenario/shrink.py (_choices_bytes / _run_hypothesis) before raising the pin.


def test_canary_choice_bytes_round_trip():
    from hypothesis.database import choices_from_bytes

    from pytest_avscenario.shrink import _choices_bytes

    seq = [True, False, True, True]
    assert choices_from_bytes(_choices_bytes(seq)) == tuple(seq)


def test_canary_hypothesis_still_shrinks_a_seeded_case():
    import hypothesis

    space = FeatureSpace({"x": Uniform(0.0, 1.0, nominal=0.0)})
    pred = Counting(lambda p: p["x"] > 0.3)
    with warnings.catch_warnings():
        warnings.simplefilter("error", ShrinkSeedingWarning)
        r = minimize(space, {"x": 1.0}, pred, budget=11)
    assert r.improved, (
        f"hypothesis {hypothesis.__version__} no longer shrinks the seeded failing case"
    )
    # The departure flag, then one simulation per binary digit, most significant first
    # (10 digits for resolution 1000): a bisection, so 11 simulations land within 1/1023.
    assert r.sims == 11
    assert 0.3 < r.minimized["x"] <= 0.3 + 1 / 1023, (
        f"hypothesis {hypothesis.__version__} no longer bisects: the trivial-span pass "
        f"changed order; candidates were {[c[0]['x'] for c in r.candidates]}"
    )


def test_canary_survives_a_forced_hypothesis_seed(monkeypatch):
    # pytest --hypothesis-seed=N sets this; without an explicit database key it would
    # switch the example database (and so the seeding) off.
    import hypothesis.core

    monkeypatch.setattr(hypothesis.core, "global_force_seed", 1234, raising=False)
    with warnings.catch_warnings():
        warnings.simplefilter("error", ShrinkSeedingWarning)
        r = minimize(following_space(), FAILING, both)
    assert r.improved


def test_numpy_and_float_valued_inputs_are_recognised_as_the_original():
    import numpy as np

    space = FeatureSpace({"gap": Uniform(10.0, 40.0, nominal=30.0), "n": IntRange(1, 40, nominal=2)})
    failing = {"gap": np.float64(12.0), "n": 31.0}
    pred = Counting(lambda p: p["gap"] < GAP_BOUNDARY and p["n"] >= 7)
    r = minimize(space, failing, pred, budget=200)
    assert all(not (p["gap"] == 12.0 and p["n"] == 31) for p in pred.calls)
    assert r.minimized["n"] == 7 and GAP_BOUNDARY - 0.02 < r.minimized["gap"] < GAP_BOUNDARY


def test_broken_seeding_keeps_the_original_and_warns(monkeypatch):
    # what a Hypothesis with another database format would do: nothing replayed
    from pytest_avscenario import shrink

    monkeypatch.setattr(shrink, "_choices_bytes", lambda choices: b"\xff\xff")
    pred = Counting(both)
    with pytest.warns(ShrinkSeedingWarning, match="did not replay"):
        r = minimize(following_space(), FAILING, pred)
    assert r.minimized == FAILING and not r.improved and pred.calls == []

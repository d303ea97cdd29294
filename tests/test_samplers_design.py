"""The corner design an active sampler starts from: corners of the box, spread out, the same
for the same seed, kept across state/restore; categorical parameters get any category."""

from __future__ import annotations

import json

import numpy as np
import pytest

from pytest_avscenario import samplers
from pytest_avscenario.samplers.design import corner_design
from pytest_avscenario.space import Choice, FeatureSpace, IntRange, Uniform

BOX5 = {f"x{i}": Uniform(0.0, 10.0) for i in range(5)}
MIXED = {"gap_m": Uniform(5.0, 50.0), "lane": IntRange(0, 3), "weather": Choice(["dry", "wet"])}


def test_the_first_two_corners_are_opposite_and_the_next_ones_far_from_both():
    D = corner_design(FeatureSpace.coerce(BOX5), 6, np.random.default_rng(3))
    assert set(np.unique(D)) <= {0.0, 1.0}
    assert len({tuple(r) for r in D.tolist()}) == 6  # no corner twice
    assert np.abs(D[0] - D[1]).sum() == 5  # opposite corners
    # every coordinate has met both its low and its high end in the first two
    assert (D[:2].min(0) == 0).all() and (D[:2].max(0) == 1).all()
    # the third is as far as a corner can be from both (Hamming 2 and 3, min 2)
    assert min(np.abs(D[2] - D[0]).sum(), np.abs(D[2] - D[1]).sum()) == 2


def test_bo_asks_its_corners_first_at_the_bounds_of_each_parameter():
    s = samplers.make("bo", BOX5, seed=0)
    firsts = [s.ask() for _ in range(5)]
    for p in firsts[:3]:
        assert set(p.values()) <= {0.0, 10.0}
    # the rest of the initial cases are uniform inside the box
    assert all(0.0 < v < 10.0 for p in firsts[3:] for v in p.values())
    assert firsts[0] == {k: 10.0 - v for k, v in firsts[1].items()}


def test_the_same_seed_asks_the_same_corners_and_another_seed_other_ones():
    a = [samplers.make("bo", BOX5, seed=1).ask() for _ in range(2)]
    b = [samplers.make("bo", BOX5, seed=1).ask() for _ in range(2)]
    assert a == b
    firsts = {tuple(samplers.make("bo", BOX5, seed=seed).ask().values()) for seed in range(8)}
    assert len(firsts) > 1


def test_corners_zero_starts_uniform_as_before():
    s = samplers.make("bo", BOX5, seed=0, corners=0)
    assert all(0.0 < v < 10.0 for _ in range(5) for v in s.ask().values())


def test_on_a_mixed_space_integers_take_their_extremes_and_categories_any_value():
    s = samplers.make("bo", MIXED, seed=2)
    ps = [s.ask() for _ in range(3)]
    assert all(p["gap_m"] in (5.0, 50.0) and p["lane"] in (0, 3) for p in ps)
    assert {p["lane"] for p in ps} == {0, 3}
    assert all(p["weather"] in ("dry", "wet") for p in ps)


def test_a_state_taken_during_the_design_continues_with_the_same_corners():
    s = samplers.make("bo", BOX5, seed=4)
    p = s.ask()
    s.tell(p, 1.0)
    # restored into a sampler made with another seed: the design travels in the state
    t = samplers.make("bo", BOX5, seed=99)
    t.restore(json.loads(json.dumps(s.state(), allow_nan=False)))
    assert [s.ask() for _ in range(4)] == [t.ask() for _ in range(4)]


def test_a_sampler_told_a_history_first_skips_the_design():
    s = samplers.make("bo", BOX5, seed=0)
    rng = np.random.default_rng(0)
    for u in rng.random((8, 5)):
        s.tell_unit(u, float(np.abs(u - 0.4).sum()))
    p = s.ask()
    assert not set(p.values()) <= {0.0, 10.0}


@pytest.mark.parametrize("bad", [-1, 1.5, "3", True])
def test_a_bad_corners_option_says_what_was_wrong(bad):
    with pytest.raises(samplers.SamplerError, match="bo corners"):
        samplers.make("bo", BOX5, corners=bad)


def test_a_space_with_fewer_corners_than_the_design_asks_each_corner_once():
    from pytest_avscenario import samplers
    from pytest_avscenario.space import FeatureSpace, Uniform

    s = samplers.make("bo", FeatureSpace({"gap": Uniform(5.0, 40.0)}), seed=0, metrics=["distance"])
    asked = []
    for _ in range(5):
        p = s.ask()
        asked.append(p["gap"])
        s.tell(p, {"distance": 1.0})
    assert sorted(asked[:2]) == [5.0, 40.0] and asked.count(5.0) == 1 and asked.count(40.0) == 1


def test_a_corner_of_a_range_that_rounds_past_its_bound_stays_inside_it():
    # lo + 1.0 * (hi - lo) is 0.0 here, above hi: the corner must be hi itself
    from pytest_avscenario import samplers
    from pytest_avscenario.space import FeatureSpace, Uniform

    space = FeatureSpace({"gap": Uniform(-713.0537694440146, -4.239979768241903e-121)})
    s = samplers.make("bo", space, seed=0, metrics=["distance"])
    for _ in range(4):
        p = s.ask()
        space.validate(p)
        s.tell(p, {"distance": 1.0})
    assert space.parameters["gap"].from_unit(1.0) == -4.239979768241903e-121

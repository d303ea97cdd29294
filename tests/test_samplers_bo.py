"""The ``bo`` sampler's bookkeeping: every told case meets its ask, whatever the parameter
types, so the GP learns from exactly the cases told (GP internals and search power are in
test_samplers.py and test_samplers_search.py)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from pytest_avscenario import samplers
from pytest_avscenario.space import Choice, IntRange, Uniform

MIXED = {
    "gap_m": Uniform(5.0, 50.0),
    "lane": IntRange(0, 3),
    "weather": Choice(["dry", "wet", "icy"], weights=[0.5, 0.3, 0.2]),
}
DISCRETE = {"lane": IntRange(0, 1), "weather": Choice(["dry", "wet"])}


def rho(p):
    return float(p["gap_m"] / 10.0 - p["lane"] - (p["weather"] == "icy"))


def pairs(s, n, f=rho):
    for _ in range(n):
        p = s.ask()
        s.tell(p, f(p))


def told(s):
    return np.asarray(s.X, dtype=float).reshape(-1, s.d)


def test_on_a_mixed_space_every_told_case_meets_its_ask_and_the_gp_sees_each_once():
    s = samplers.make("bo", MIXED, seed=0)
    pairs(s, 40)
    assert s.pending == []
    assert len(told(s)) == 40
    s.ask()  # fitted before this ask joins the pending list
    assert len(s.gp.X) == 40


def test_a_told_case_is_learned_at_the_point_it_was_asked_as():
    s = samplers.make("bo", MIXED, seed=1)
    for _ in range(8):
        p = s.ask()
        asked = list(s.pending[-1])
        s.tell(p, rho(p))
        assert told(s)[-1].tolist() == asked  # bit for bit, not the stratum centre


def test_asks_told_out_of_order_or_invalid_all_meet_their_ask():
    s = samplers.make("bo", MIXED, seed=2, init=3)
    pairs(s, 4)
    asked = [s.ask() for _ in range(5)]  # a cluster asks ahead
    assert len(s.pending) == 5
    for i in (3, 0, 4, 1, 2):
        s.tell(asked[i], None if i == 4 else rho(asked[i]))
    assert s.pending == []
    assert s.n_invalid == 1


def test_asks_with_the_same_parameters_are_matched_one_each():
    s = samplers.make("bo", DISCRETE, seed=3, init=2)
    asked = [s.ask() for _ in range(6)]  # 4 distinct cases: some repeat
    assert len({tuple(p.values()) for p in asked}) < 6
    for p in asked:
        s.tell(p, float(p["lane"]))
    assert s.pending == []


def test_a_case_that_was_never_asked_is_learned_and_leaves_the_asks_pending():
    s = samplers.make("bo", MIXED, seed=4)
    p = s.ask()
    s.tell({"gap_m": 7.5, "lane": 2, "weather": "wet"}, 0.3)  # e.g. replayed from the db
    assert len(s.pending) == 1 and len(told(s)) == 1
    s.tell(p, rho(p))
    assert s.pending == []


def test_tell_unit_of_the_stratum_centre_meets_its_ask():
    s = samplers.make("bo", MIXED, seed=5)
    u = s.ask_unit()
    s.tell_unit(s._unit(s._params(u)), 1.0)  # what tell(params) computes
    assert s.pending == []


def test_a_pending_ask_survives_state_and_restore():
    s = samplers.make("bo", MIXED, seed=6)
    pairs(s, 6)
    p = s.ask()
    t = samplers.make("bo", MIXED, seed=99)
    t.restore(json.loads(json.dumps(s.state(), allow_nan=False)))
    t.tell(p, rho(p))
    assert t.pending == []


@pytest.mark.parametrize("name", ["mab", "ce", "sa"])
def test_other_active_samplers_learn_the_told_case_in_the_asked_stratum(name):
    # they learn per bucket (mab, ce) or walk from the told point (sa): the stratum centre
    # that tell computes is the same case as the asked point
    s = samplers.make(name, MIXED, seed=7)
    space_d = s.d
    for _ in range(30):
        u = s.ask_unit()
        back = np.asarray(s._unit(s._params(u)))
        assert s._params(back) == s._params(u)
        assert back.shape == (space_d,)
        s.tell(s._params(u), 1.0)

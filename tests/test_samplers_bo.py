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


# -- bounded cost: a fitting subset and hyperparameters refitted on a schedule ------------------

BOX = {"x": Uniform(0.0, 1.0), "y": Uniform(0.0, 1.0)}


def bowl(u):
    return float((u[0] - 0.3) ** 2 + (u[1] - 0.7) ** 2)


def with_history(n, seed=0, **opts):
    s = samplers.make("bo", BOX, seed=seed, **opts)
    for u in np.random.default_rng(100 + seed).random((n, 2)):
        s.tell_unit(u, bowl(u))
    return s


def test_the_fit_holds_at_most_max_points_with_the_best_and_the_latest_cases():
    s = with_history(300, max_points=30)
    best = told(s)[np.argmin([bowl(u) for u in told(s)])]
    latest = told(s)[-10:]
    s.ask()
    fitted = {tuple(x) for x in np.asarray(s.gp.X).tolist()}
    assert len(fitted) == 30
    assert tuple(best) in fitted
    assert all(tuple(u) in fitted for u in latest.tolist())


def test_part_of_the_fit_covers_the_space_the_search_has_left():
    s = samplers.make("bo", BOX, seed=0, max_points=40)
    rng = np.random.default_rng(0)
    # a few cases anywhere, then the search crowded the corner where rho is lowest
    pts = np.vstack([rng.random((30, 2)), 0.2 * rng.random((270, 2))])
    for u in pts:
        s.tell_unit(u, float(np.hypot(*u)))
    s.ask()
    fitted = np.asarray(s.gp.X)
    quadrants = {(bool(x > 0.5), bool(y > 0.5)) for x, y in fitted}
    assert len(quadrants) == 4


def test_hyperparameters_are_refitted_on_a_schedule_not_at_every_ask():
    s = with_history(200, max_points=30)
    for _ in range(30):
        u = s.ask_unit()
        s.tell_unit(u, bowl(u))
    assert 1 <= s.gp.n_fits <= 3  # every 20 cases at this size


def test_with_a_long_history_the_search_still_converges():
    s = with_history(200, seed=1, max_points=30)
    best = np.inf
    for _ in range(15):
        u = s.ask_unit()
        best = min(best, bowl(u))
        s.tell_unit(u, bowl(u))
    assert best < 1e-3


def test_a_long_campaign_restored_from_its_state_continues_the_same_asks():
    s = samplers.make("bo", MIXED, seed=8, max_points=12)
    pairs(s, 40)
    t = samplers.make("bo", MIXED, seed=0, max_points=12)
    t.restore(json.loads(json.dumps(s.state(), allow_nan=False)))
    a, b = [], []
    for _ in range(6):
        p, q = s.ask(), t.ask()
        a.append(p)
        b.append(q)
        s.tell(p, rho(p))
        t.tell(q, rho(q))
    assert a == b


CODE = """
import numpy as np
from pytest_avscenario import samplers
from pytest_avscenario.space import Choice, IntRange, Uniform
space = {"gap_m": Uniform(5.0, 50.0), "lane": IntRange(0, 3),
         "weather": Choice(["dry", "wet", "icy"], weights=[0.5, 0.3, 0.2])}
s = samplers.make("bo", space, seed=9, max_points=12)
out = []
for _ in range(40):
    p = s.ask()
    out.append(repr(p["gap_m"]) + str(p["lane"]) + p["weather"])
    s.tell(p, p["gap_m"] / 10.0 - p["lane"] - (p["weather"] == "icy"))
print(" ".join(out))
"""


def test_a_long_campaign_asks_the_same_cases_bit_for_bit_in_another_process():
    import subprocess
    import sys

    here = []
    s = samplers.make("bo", MIXED, seed=9, max_points=12)
    for _ in range(40):
        p = s.ask()
        here.append(repr(p["gap_m"]) + str(p["lane"]) + p["weather"])
        s.tell(p, rho(p))
    out = subprocess.run([sys.executable, "-c", CODE], capture_output=True, text=True,
                         check=True)
    assert out.stdout.split() == here

"""The samplers' protocol and mechanics: registry, determinism, JSON state, bad input,
invalid feedback, and each active sampler's core rule (bucket choice, pattern dominance,
elite update, acceptance rule, GP posterior)."""

import json
import math
import subprocess
import sys

import numpy as np
import pytest

from pytest_avscenario import samplers
from pytest_avscenario.samplers import SamplerError
from pytest_avscenario.samplers.base import scalar_rho
from pytest_avscenario.samplers.priority import PriorityOrder
from pytest_avscenario.space import Choice, FeatureSpace, IntRange, Uniform

ACTIVE = ["mab", "ce", "sa", "bo"]
ALL = ["random", "halton"] + ACTIVE

MIXED = {
    "gap": Uniform(10.0, 40.0),
    "speed": Uniform(5.0, 15.0),
    "weather": Choice(["dry", "wet", "icy"], weights=[0.5, 0.3, 0.2]),
    "lane": IntRange(0, 2),
    "road": "straight",
}


def synthetic_rho(p):
    """A cheap monitor over MIXED: fails for a short gap at high speed on ice."""
    slip = {"dry": 1.0, "wet": 0.5, "icy": 0.0}[p["weather"]]
    return float(p["gap"] - 12.0 - 0.8 * (p["speed"] - 5.0) + 8 * slip + abs(p["lane"] - 1))


def drive(s, n, rho=synthetic_rho):
    out = []
    for i in range(n):
        p = s.ask()
        out.append(p)
        s.tell(p, rho(p))
    return out


# -- registry and protocol -------------------------------------------------------------------

def test_registry_names_every_sampler_and_active_flags():
    assert set(ALL) <= set(samplers.available())
    for name in ALL:
        s = samplers.make(name, MIXED, seed=0)
        assert s.active == (name in ACTIVE), name
        assert samplers.base.is_active(name) == s.active


def test_import_is_light():
    code = ("import sys, pytest_avscenario.samplers as s; from pytest_avscenario.space import "
            "Uniform; s.make('mab', {'a': Uniform(0, 1)}); s.make('ce', {'a': Uniform(0, 1)}); "
            "s.make('sa', {'a': Uniform(0, 1)}); print('scipy' in sys.modules)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"


@pytest.mark.parametrize("name", ALL)
def test_ask_gives_valid_parameters_including_constants(name):
    space = FeatureSpace(MIXED)
    s = samplers.make(name, MIXED, seed=3)
    for p in drive(s, 12):
        space.validate(p)
        assert p["road"] == "straight"
        assert list(p) == list(MIXED)


@pytest.mark.parametrize("name", ALL)
def test_deterministic_given_seed_and_feedback(name):
    a = drive(samplers.make(name, MIXED, seed=7), 15)
    b = drive(samplers.make(name, MIXED, seed=7), 15)
    c = drive(samplers.make(name, MIXED, seed=8), 15)
    assert a == b
    if name != "halton":  # unscrambled Halton is the same sequence for every seed
        assert a != c


@pytest.mark.parametrize("name", ALL)
def test_state_is_strict_json_and_restore_continues_the_same_sequence(name):
    s = samplers.make(name, MIXED, seed=11)
    drive(s, 13)
    s.tell(s.ask(), None)
    s.tell(s.ask(), {"x": math.inf})  # +inf must survive strict JSON
    blob = json.dumps(s.state(), allow_nan=False)
    t = samplers.make(name, MIXED, seed=999)
    t.restore(json.loads(blob))
    assert drive(s, 8) == drive(t, 8)


@pytest.mark.parametrize("name", ACTIVE)
def test_invalid_feedback_is_counted_and_never_breaks_the_sampler(name):
    s = samplers.make(name, MIXED, seed=1)
    space = FeatureSpace(MIXED)
    for i in range(25):
        p = s.ask()
        space.validate(p)
        s.tell(p, None if i % 2 else {"a": float("nan"), "b": 1.0})
    assert s.n_invalid == 25
    drive(s, 5)  # still works after only-invalid feedback


def test_mab_invalid_case_counts_a_pull_but_moves_no_mean():
    s = samplers.make("mab", {"x": Uniform(0, 1)}, seed=0, buckets=4)
    s.tell_unit(np.array([0.1]), 0.5)
    before = s.arm_values()[0, 0]
    pulls = s.pulls[0]
    s.tell_unit(np.array([0.1]), None)
    assert s.arm_values()[0, 0] == pytest.approx(before)
    assert s.pulls[0] == pulls + 1


def test_batch_conversion_equals_the_feature_space_mapping():
    space = FeatureSpace(MIXED)
    s = samplers.make("random", MIXED, seed=0)
    U = np.random.default_rng(0).random((200, space.d))
    U[:3] = [[0.0, 1.0, 0.5, 1.0], [1.0, 0.0, 0.0, 0.999999], [-0.1, 1.2, 0.3, 0.5]]
    assert s._params_many(U) == [space.from_unit(u) for u in U]
    assert [s._params(u) for u in U] == [space.from_unit(u) for u in U]
    assert np.allclose([s._unit(space.from_unit(u)) for u in U[3:]],
                       [space.to_unit(space.from_unit(u)) for u in U[3:]])


@pytest.mark.parametrize("name", ACTIVE)
def test_a_case_told_from_outside_the_space_counts_at_its_face(name):
    s = samplers.make(name, {"x": Uniform(0, 1), "y": Uniform(0, 1)}, seed=0)
    for x in (-5.0, 7.0, 1e9):
        s.tell({"x": x, "y": 0.5}, 0.3)
    assert s._unit({"x": -5.0, "y": 2.0}) == [0.0, 1.0]
    drive(s, 5, rho=lambda p: p["x"])
    with pytest.raises(SamplerError, match="'x' is NaN"):
        s.tell({"x": float("nan"), "y": 0.5}, 1.0)


def test_scalar_rho_nan_anywhere_is_invalid_whatever_the_order():
    assert scalar_rho({"a": 1.0, "b": float("nan")}) is None
    assert scalar_rho({"a": float("nan"), "b": 1.0}) is None
    assert scalar_rho({"a": 2.0, "b": -1.0}) == -1.0
    assert scalar_rho(math.inf) == math.inf
    assert scalar_rho(None) is None


# -- bad input -------------------------------------------------------------------------------

@pytest.mark.parametrize("name", ALL)
def test_unknown_option_is_an_error_naming_it(name):
    with pytest.raises(SamplerError, match="bukets"):
        samplers.make(name, MIXED, bukets=3)


@pytest.mark.parametrize("name", ["mab", "ce"])
@pytest.mark.parametrize("bad", [0, -2, 2.5, True, "5"])
def test_bucket_count_below_one_or_not_an_int_is_an_error(name, bad):
    with pytest.raises(SamplerError, match="buckets"):
        samplers.make(name, MIXED, buckets=bad)


@pytest.mark.parametrize("name", ACTIVE)
def test_every_active_sampler_checks_metrics_and_priority(name):
    ok = samplers.make(name, MIXED, metrics=["dist", "ttc"], priority=["dist", "ttc"])
    assert ok.active
    with pytest.raises(SamplerError, match="unknown metric.*'lane'"):
        samplers.make(name, MIXED, metrics=["dist", "ttc"], priority=["dist", "lane"])
    with pytest.raises(SamplerError, match="cycle"):
        samplers.make(name, MIXED, priority=[("a", "b"), ("b", "c"), ("c", "a")])
    with pytest.raises(SamplerError, match="twice"):
        samplers.make(name, MIXED, priority=["a", "b", "a"])
    with pytest.raises(SamplerError, match="pairs"):
        samplers.make(name, MIXED, priority=[("a", "b", "c")])
    with pytest.raises(SamplerError, match="unknown metric"):
        ok.tell(ok.ask(), {"dist": 1.0, "speeding": -1.0})


def test_cycle_message_names_the_cycle():
    with pytest.raises(SamplerError, match=r"a > b > a|b > a > b"):
        PriorityOrder.parse([("a", "b"), ("b", "a")], metrics=["a", "b", "c"])
    with pytest.raises(SamplerError, match="cycle"):
        PriorityOrder.parse([("a", "a")])


@pytest.mark.parametrize("opts", [dict(exploration=-1), dict(near_miss=2.0),
                                  dict(jitter=float("nan"))])
def test_mab_option_ranges(opts):
    with pytest.raises(SamplerError):
        samplers.make("mab", MIXED, **opts)


@pytest.mark.parametrize("opts", [dict(elite=0), dict(smoothing=1.5), dict(batch=0)])
def test_ce_option_ranges(opts):
    with pytest.raises(SamplerError):
        samplers.make("ce", MIXED, **opts)


@pytest.mark.parametrize("opts", [dict(step=0), dict(cooling=1.5), dict(restart=0)])
def test_sa_option_ranges(opts):
    with pytest.raises(SamplerError):
        samplers.make("sa", MIXED, **opts)


@pytest.mark.parametrize("opts", [dict(kernel="linear"), dict(acquisition="pi"), dict(init=0)])
def test_bo_option_ranges(opts):
    with pytest.raises(SamplerError):
        samplers.make("bo", MIXED, **opts)


@pytest.mark.parametrize("name", ["ce", "sa", "bo"])
def test_single_objective_samplers_chase_the_top_priority_metric(name):
    s = samplers.make(name, {"x": Uniform(0, 1)}, metrics=["a", "b"], priority=["a", "b"])
    seen = []
    s._learn = lambda u, r, rho: seen.append(r)
    s.tell_unit(np.array([0.5]), {"a": 2.0, "b": -1.0})
    t = samplers.make(name, {"x": Uniform(0, 1)}, metrics=["a", "b"])
    t._learn = lambda u, r, rho: seen.append(r)
    t.tell_unit(np.array([0.5]), {"a": 2.0, "b": -1.0})
    assert seen == [2.0, -1.0]


# -- mab: bucket choice ----------------------------------------------------------------------

def test_mab_plays_the_bucket_with_the_highest_upper_confidence_bound():
    s = samplers.make("mab", {"x": Uniform(0, 1), "y": Uniform(0, 1)}, seed=0, buckets=4,
                      exploration=0.0, jitter=0.0, near_miss=1.0)
    # one near-miss in bucket 2 of x and bucket 1 of y, far misses in two other buckets;
    # x's bucket 1 and y's bucket 0 are never played
    s.tell_unit(np.array([0.6, 0.3]), 0.0)
    for u in ([0.1, 0.9], [0.9, 0.6]):
        s.tell_unit(np.array(u), 100.0)
    for _ in range(20):
        u = s.ask_unit()
        assert 0.5 <= u[0] < 0.75 and 0.25 <= u[1] < 0.5
    # with a large exploration constant the never-played arms' bonus wins instead
    s.exploration = 50.0
    u = s.ask_unit()
    assert 0.25 <= u[0] < 0.5 and u[1] < 0.25


def test_mab_ucb_values_follow_the_formula():
    s = samplers.make("mab", {"x": Uniform(0, 1)}, seed=0, buckets=2, near_miss=1.0)
    for rho in (1.0, 3.0):  # scale = mean |rho| = 2 after both
        s.tell_unit(np.array([0.2]), rho)
    s.tell_unit(np.array([0.7]), -1.0)  # a counterexample: reward 1
    # arm 0: pseudo-pull 0 + exp(-1/1) [scale was 1 then] + exp(-3/2)
    expect0 = (math.exp(-1.0) + math.exp(-3.0 / 2.0)) / 3.0
    assert s.arm_values()[0] == pytest.approx([expect0, 1.0 / 2.0])


def test_mab_categorical_and_integer_dimensions_get_one_arm_per_value():
    s = samplers.make("mab", MIXED, buckets=5)
    assert list(s.grid.k) == [5, 5, 3, 3]
    # the categorical arms are its weighted strata
    assert s.grid.width[2, :3] == pytest.approx([0.5, 0.3, 0.2])


def test_mab_learns_from_near_misses_before_any_counterexample():
    # rho >= 0.05 everywhere (never violated): a bandit with 0/1 rewards stays uniform,
    # this one concentrates on the bucket nearest the minimum
    s = samplers.make("mab", {"x": Uniform(0, 1), "y": Uniform(0, 1)}, seed=0, buckets=5)
    pts = [s.ask_unit() for _ in range(0)]
    for _ in range(300):
        u = s.ask_unit()
        pts.append(u)
        s.tell_unit(u, 0.05 + abs(u[0] - 0.9) + abs(u[1] - 0.1))
    last = np.array(pts[-100:])
    assert ((last[:, 0] >= 0.8) & (last[:, 1] < 0.2)).mean() > 0.4


def test_mab_dimensions_do_not_move_in_lock_step():
    # regression: with a deterministic argmax every dimension kept the same statistics up to
    # a permutation and only `buckets` cells of the grid were ever visited
    s = samplers.make("mab", {f"x{i}": Uniform(0, 1) for i in range(3)}, seed=1, buckets=5)
    cells = set()
    for _ in range(300):
        u = s.ask_unit()
        cells.add(tuple((u * 5).astype(int)))
        s.tell_unit(u, float(np.linalg.norm(u - 0.37)) + 0.2)
    assert len(cells) > 15


# -- mab: multi-objective patterns -----------------------------------------------------------

# three metrics: collision outranks both ttc and lane; ttc and lane are unordered
DAG = [("collision", "ttc"), ("collision", "lane")]


def P(*names):
    return frozenset(names)


def test_pattern_dominance_on_a_three_metric_priority_dag():
    order = PriorityOrder.parse(DAG, metrics=["lane", "ttc", "collision"])
    d = order.dominates
    assert d(P("collision"), P("ttc", "lane"))          # outranks everything it lacks
    assert d(P("ttc", "lane"), P("ttc"))                # superset
    assert d(P("collision", "ttc"), P("collision"))
    assert not d(P("ttc"), P("lane")) and not d(P("lane"), P("ttc"))  # unordered
    assert not d(P("ttc"), P("collision"))
    assert not d(P("ttc"), P("ttc"))
    assert sorted(map(sorted, order.maximal([P("ttc"), P("lane")]))) == [["lane"], ["ttc"]]
    assert order.maximal([P("ttc"), P("lane"), P("collision")]) == [P("collision")]
    assert order.maximal([P(), P("lane")]) == [P("lane")]  # no violation is no counterexample


def test_patterns_are_indexed_by_metric_name_not_by_traversal_order():
    # the same order declared with metrics and edges listed in other orders must judge alike
    # (the reference indexes the pattern tuple by DFS position and gets this wrong)
    a = PriorityOrder.parse(DAG, metrics=["collision", "ttc", "lane"])
    b = PriorityOrder.parse(list(reversed(DAG)), metrics=["lane", "ttc", "collision"])
    pats = [P(), P("lane"), P("ttc"), P("collision"), P("ttc", "lane"), P("collision", "lane")]
    for p in pats:
        for q in pats:
            assert a.dominates(p, q) == b.dominates(p, q), (p, q)
    chain = PriorityOrder.parse(["c", "b", "a"], metrics=["a", "b", "c"])
    assert chain.dominates(P("c"), P("a", "b"))
    assert chain.outranks("c", "a") and not chain.outranks("a", "c")


def test_mab_rewards_only_buckets_whose_pattern_is_still_maximal():
    s = samplers.make("mab", {"x": Uniform(0, 1)}, seed=0, buckets=4, near_miss=0.0,
                      metrics=["lane", "ttc", "collision"], priority=DAG)
    assert s.multi
    ok = {"collision": 1.0, "ttc": 1.0, "lane": 1.0}
    s.tell_unit(np.array([0.1]), {**ok, "lane": -0.2})   # bucket 0 violates lane
    s.tell_unit(np.array([0.4]), {**ok, "ttc": -0.2})    # bucket 1 violates ttc (unordered)
    assert s.maximal == {P("lane"), P("ttc")}
    # credit = share of the priority weight: collision 1, ttc and lane 1/2 each (of 2)
    assert s.arm_values()[0, :2] == pytest.approx([0.25 / 2, 0.25 / 2])
    s.tell_unit(np.array([0.9]), {**ok, "collision": -1.0})  # bucket 3: the top metric
    assert s.maximal == {P("collision")}
    assert s.arm_values()[0] == pytest.approx([0.0, 0.0, 0.0, 0.5 / 2])
    # a later lesser pattern earns no counterexample credit
    s.tell_unit(np.array([0.6]), {**ok, "lane": -0.5})
    assert s.arm_values()[0, 2] == 0.0


def test_mab_multi_objective_state_round_trips():
    s = samplers.make("mab", {"x": Uniform(0, 1)}, seed=0, metrics=["a", "b", "c"],
                      priority=[("a", "b"), ("a", "c")])
    for i in range(30):
        p = s.ask()
        s.tell(p, {"a": p["x"] - 0.9, "b": 0.5 - p["x"], "c": 0.2})
    t = samplers.make("mab", {"x": Uniform(0, 1)}, seed=5, metrics=["a", "b", "c"],
                      priority=[("a", "b"), ("a", "c")])
    t.restore(json.loads(json.dumps(s.state(), allow_nan=False)))
    assert t.maximal == s.maximal
    assert np.allclose(t.arm_values(), s.arm_values())


# -- ce: elite update ------------------------------------------------------------------------

def test_ce_moves_each_dimension_toward_the_elite_buckets():
    s = samplers.make("ce", {"x": Uniform(0, 1), "y": Uniform(0, 1)}, seed=0, buckets=4,
                      batch=10, elite=0.2, smoothing=0.5, floor=0.0)
    us = [[0.1, 0.1], [0.6, 0.9]] + [[0.4, 0.4]] * 8
    rhos = [-1.0, -0.5] + [1.0] * 8  # the two lowest rho are the elites (20% of 10)
    for u, r in zip(us, rhos):
        s.tell_unit(np.array(u), r)
    # elites: x in buckets 0 and 2, y in buckets 0 and 3, each with frequency 1/2
    assert s.prob[0] == pytest.approx([0.5 * 0.25 + 0.25, 0.125, 0.125 + 0.25, 0.125])
    assert s.prob[1] == pytest.approx([0.125 + 0.25, 0.125, 0.125, 0.125 + 0.25])
    # and the next batch is drawn from the new distribution
    draws = np.array([s.ask_unit() for _ in range(400)])
    assert np.mean(draws[:, 0] < 0.25) == pytest.approx(0.375, abs=0.08)


def test_ce_learns_from_the_first_batch_without_any_counterexample():
    s = samplers.make("ce", {"x": Uniform(0, 1)}, seed=0, buckets=5, batch=5)
    for _ in range(5):
        u = s.ask_unit()
        s.tell_unit(u, 10.0 + float(u[0]))  # all positive rho
    assert not np.allclose(s.prob, 0.2)


def test_ce_distributions_stay_normalized_with_a_zero_weight_choice():
    sp = {"w": Choice(["never", "a", "b"], weights=[0, 1, 1]), "x": Uniform(0, 1)}
    s = samplers.make("ce", sp, seed=0, batch=5)
    for p in drive(s, 200, rho=lambda p: p["x"] + (p["w"] == "a")):
        assert p["w"] != "never"
    assert s.prob.sum(1) == pytest.approx([1.0, 1.0])
    assert s.prob[0, 0] == 0.0 and s.prob[0, 2] > 0.8


def test_degenerate_spaces_work_for_every_sampler():
    for sp in ({"road": "x"}, {}, {"w": Choice(["a"])}, {"n": IntRange(0, 500)}):
        for name in ALL:
            s = samplers.make(name, sp, seed=0)
            for i in range(12):
                p = s.ask()
                s.tell(p, 1.0 if i % 3 else None)
            t = samplers.make(name, sp, seed=1)
            t.restore(json.loads(json.dumps(s.state(), allow_nan=False)))
            assert [s.ask() for _ in range(3)] == [t.ask() for _ in range(3)], (name, sp)


def test_ce_floor_keeps_every_bucket_alive():
    s = samplers.make("ce", {"x": Uniform(0, 1)}, seed=0, buckets=5, floor=0.1, smoothing=1.0)
    for _ in range(200):
        u = s.ask_unit()
        s.tell_unit(u, float(u[0]))
    assert s.prob.min() >= 0.1 / 5 - 1e-12


# -- sa: acceptance rule ---------------------------------------------------------------------

def test_sa_metropolis_acceptance_rule():
    s = samplers.make("sa", {"x": Uniform(0, 1)}, seed=0)
    assert s.accepts(1.0, 0.5) and s.accepts(1.0, 1.0)
    assert s.accepts(math.inf, 3.0)           # anything finite beats "holds trivially"
    assert not s.accepts(1.0, math.inf)
    s._dsum, s._dn, s.temp = 1e7, 10**7, 1.0  # scale 1 (and stays ~1), temperature 1
    rate = np.mean([s.accepts(0.0, 0.7) for _ in range(4000)])
    assert rate == pytest.approx(math.exp(-0.7), abs=0.04)
    s.temp = 0.0
    assert not any(s.accepts(0.0, 0.01) for _ in range(50))


def test_sa_moves_locally_and_actually_moves():
    s = samplers.make("sa", {f"x{i}": Uniform(0, 1) for i in range(3)}, seed=0, restart=1000)
    pts = []
    for _ in range(60):
        u = s.ask_unit()
        pts.append(u)
        s.tell_unit(u, float(np.linalg.norm(u - 0.8)))
    steps = np.linalg.norm(np.diff(np.array(pts[1:]), axis=0), axis=1)
    assert steps.mean() < 0.35            # uniform random pairs are ~0.66 apart in 3-D
    assert s.n_accepted >= 10
    assert np.linalg.norm(s.x - 0.8) < np.linalg.norm(pts[0] - 0.8)
    assert s.step < 0.15                   # the proposal shrank


def test_sa_restarts_after_stalling():
    s = samplers.make("sa", {"x": Uniform(0, 1)}, seed=0, restart=5)
    for _ in range(30):
        s.tell_unit(s.ask_unit(), 1.0)   # flat: never improves
    assert s.n_restarts >= 4


# -- bo: GP posterior ------------------------------------------------------------------------

def test_gp_posterior_on_a_known_function():
    from pytest_avscenario.samplers.bo import GaussianProcess

    f = lambda x: np.sin(6.0 * x[:, 0]) + 0.5 * x[:, 1]  # noqa: E731
    rng = np.random.default_rng(0)
    X = rng.random((40, 2))
    for kernel in ("matern", "rbf"):
        gp = GaussianProcess(kernel, 2)
        gp.fit(X, f(X))
        T = rng.random((200, 2))
        mu, sd = gp.predict(T)
        assert np.sqrt(np.mean((mu - f(T)) ** 2)) < 0.05, kernel
        assert gp.ell[1] > gp.ell[0]  # the slowly varying input gets the longer scale
        _, sd_train = gp.predict(X[:5])
        assert sd_train.max() < 0.05 and sd.max() > sd_train.max()


def test_gp_gradients_match_finite_differences():
    from scipy.optimize import approx_fprime

    from pytest_avscenario.samplers.bo import GaussianProcess

    rng = np.random.default_rng(1)
    X, y = rng.random((15, 3)), rng.standard_normal(15)
    for kernel in ("matern", "rbf"):
        gp = GaussianProcess(kernel, 3)
        th = np.array([-1.0, -0.5, 0.2, 0.3, math.log(1e-2)])
        g = gp.nll(th, X, y)[1]
        assert np.allclose(g, approx_fprime(th, lambda t: gp.nll(t, X, y)[0], 1e-6), rtol=1e-3,
                           atol=1e-4)
        gp.theta = th
        gp.fit(X, y, optimize=False)
        Z = rng.random((3, 3))
        mu, sd, dmu, dsd = gp.predict(Z, grad=True)
        for k in range(3):
            Zk = Z.copy()
            Zk[:, k] += 1e-6
            mu2, sd2 = gp.predict(Zk)
            assert np.allclose(dmu[:, k], (mu2 - mu) / 1e-6, rtol=1e-3, atol=1e-4)
            assert np.allclose(dsd[:, k], (sd2 - sd) / 1e-6, rtol=1e-2, atol=1e-3)


def test_bo_starts_random_then_converges_to_the_minimum():
    s = samplers.make("bo", {"x": Uniform(0, 1), "y": Uniform(0, 1)}, seed=0, init=4)
    best = math.inf
    for i in range(16):
        u = s.ask_unit()
        r = float((u[0] - 0.3) ** 2 + (u[1] - 0.7) ** 2)
        best = min(best, r)
        s.tell_unit(u, r)
    assert best < 1e-3


def test_bo_spreads_asks_that_are_not_told_yet():
    s = samplers.make("bo", {"x": Uniform(0, 1)}, seed=0, init=3)
    for x in (0.1, 0.5, 0.9):
        s.tell_unit(np.array([x]), abs(x - 0.45))
    a, b = s.ask_unit(), s.ask_unit()
    assert abs(a[0] - b[0]) > 1e-3


# -- passive samplers ------------------------------------------------------------------------

def test_halton_blocks_match_the_scipy_sequence_and_restore_from_a_generator_seed():
    from scipy.stats import qmc

    sp = {"a": Uniform(0, 1), "b": Uniform(0, 1)}
    e = qmc.Halton(2, scramble=False)
    e.fast_forward(1)
    s = samplers.make("halton", sp)
    got = np.vstack([[s.ask_unit() for _ in range(7)], s.sample_unit(300),
                     [s.ask_unit() for _ in range(293)]])
    assert np.allclose(got, e.random(600))
    s = samplers.make("halton", sp, seed=np.random.default_rng(3), scramble=True)
    [s.ask_unit() for _ in range(5)]
    st = json.loads(json.dumps(s.state()))
    t = samplers.make("halton", sp, seed=np.random.default_rng(4), scramble=True)
    t.restore(st)
    assert np.allclose([s.ask_unit() for _ in range(300)], [t.ask_unit() for _ in range(300)])

"""Each active sampler finds the failure region of a cheap synthetic monitor in fewer samples
than random sampling, on average over seeds (generous margins: a broken learner fails these,
an unlucky seed does not)."""

import math
import statistics

import numpy as np
import pytest

from pytest_avscenario import samplers
from pytest_avscenario.space import Choice, IntRange, Uniform

BALL_R = 0.12
BALL = {f"x{i}": Uniform(0.0, 1.0) for i in range(3)}
# random sampling needs 1 / P(ball) samples on average
RANDOM_MEAN_BALL = 1.0 / (4.0 / 3.0 * math.pi * BALL_R**3)  # ~138


def first_counterexample(name, space, rho, seed, budget, **opts):
    s = samplers.make(name, space, seed=seed, **opts)
    for i in range(budget):
        p = s.ask()
        r = rho(p, seed)
        s.tell(p, r)
        if r < 0:
            return i + 1
    return budget


def ball_rho(p, seed):
    c = np.random.default_rng(1000 + seed).uniform(0.2, 0.8, 3)
    return math.dist((p["x0"], p["x1"], p["x2"]), c) - BALL_R


# bo gets a small budget (it is cubic in the samples) and so a stricter bar: a random
# search cut off at 60 samples averages ~50, which must not pass
@pytest.mark.parametrize("name,budget,margin",
                         [("mab", 400, 0.5), ("ce", 400, 0.5), ("sa", 400, 0.5), ("bo", 60, 0.2)])
def test_active_sampler_finds_the_ball_faster_than_random(name, budget, margin):
    firsts = [first_counterexample(name, BALL, ball_rho, seed, budget) for seed in range(10)]
    # random needs ~138 on average
    assert statistics.mean(firsts) < margin * RANDOM_MEAN_BALL, firsts


def test_random_is_not_beaten_by_the_margin_itself():
    # the same check on random fails, so the margin above is informative
    firsts = [first_counterexample("random", BALL, ball_rho, seed, 2000) for seed in range(10)]
    assert statistics.mean(firsts) > 0.5 * RANDOM_MEAN_BALL, firsts


MIXED = {
    "gap": Uniform(5.0, 50.0),
    "speed": Uniform(0.0, 30.0),
    "weather": Choice(["dry", "wet", "icy"]),
    "lane": IntRange(0, 3),
}
FRICTION = {"dry": 0.8, "wet": 0.5, "icy": 0.3}


def braking_rho(p, seed):
    """Gap left after braking to a stop from `speed` [m/s], 1 s reaction, minus a margin
    that depends on the lane; fails (~1 % of the space) for icy roads, fast and close."""
    stop_m = p["speed"] * 1.0 + p["speed"] ** 2 / (2 * 9.81 * FRICTION[p["weather"]])
    return float(p["gap"] + 125.0 + 15.0 * abs(p["lane"] - (seed % 4)) - stop_m)


def random_mean_braking():
    """1 / P(failure) under uniform sampling, estimated once from 20000 seeded draws."""
    rng = np.random.default_rng(0)
    s = samplers.make("random", MIXED, seed=0)
    hits = np.mean([braking_rho(s.ask(), int(rng.integers(4))) < 0 for _ in range(20000)])
    assert 0.005 < hits < 0.03  # rare, but not so rare that the test gets slow
    return 1.0 / hits  # ~70


def test_random_needs_about_the_expected_number_on_the_mixed_space():
    firsts = [first_counterexample("random", MIXED, braking_rho, seed, 2000) for seed in range(10)]
    assert statistics.mean(firsts) > 0.6 * random_mean_braking(), firsts


@pytest.mark.parametrize("name", ["mab", "ce", "sa"])
def test_active_sampler_beats_random_on_a_mixed_space(name):
    firsts = [first_counterexample(name, MIXED, braking_rho, seed, 600) for seed in range(10)]
    assert statistics.mean(firsts) < 0.6 * random_mean_braking(), firsts

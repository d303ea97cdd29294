"""The shared geometry and right-of-way rule give one answer wherever they are asked."""

import math

import numpy as np
import pytest

from pytest_avscenario.sim import geometry as geo
from pytest_avscenario.sim import right_of_way as row


def test_wrap_to_pi_is_bit_identical_to_highway_envs():
    from pytest_avscenario.sim._hwenv import load_core

    load_core()
    from highway_env.utils import wrap_to_pi as hw_wrap

    rng = np.random.default_rng(0)
    values = list(rng.uniform(-50, 50, 2000)) + [0.0, math.pi, -math.pi, 2 * math.pi, 1e-17,
                                                  -1e-17, 3 * math.pi / 2]
    for x in values:
        for v in (float(x), np.float64(x)):
            ours, theirs = geo.wrap_to_pi(v), hw_wrap(v)
            assert ours == theirs or (math.isnan(ours) and math.isnan(theirs))
            assert -math.pi <= ours < math.pi


def test_box_overlap_scalar_and_vectorized_agree_away_from_touching():
    rng = np.random.default_rng(1)
    half, half_w = 2.5, 1.0
    boxes = [(0.0, 0.0, 2.4, 1.1), (6.0, -1.0, 2.4, 1.1)]
    x, y = rng.uniform(-8, 12, 400), rng.uniform(-5, 5, 400)
    h = rng.uniform(-math.pi, math.pi, 400)
    hit = geo.poses_hit_boxes(x, y, h, half, half_w, boxes)
    for k in range(400):
        car = geo.box_corners(x[k], y[k], h[k], half, half_w)
        scalar = any(geo.boxes_overlap(car, geo.box_corners(bx, by, 0.0, bhx, bhy))
                     for bx, by, bhx, bhy in boxes)
        assert scalar == bool(hit[k])


@pytest.mark.parametrize("t_other, h_other, expected", [
    (0.0, 0.0, "earlier"),               # stopped 1 s before us
    (1.1, -math.pi / 2, "right"),        # a tie, heading south (from the north) while we head west
    (1.0, -math.pi, "facing"),           # a tie, coming the other way
    (0.9, math.pi / 2, "left"),          # a tie, heading north: it comes from our left
    (1.5, 0.0, "later"),
])
def test_precedence_first_to_stop_then_the_one_on_the_right(t_other, h_other, expected):
    # we came to rest at t = 1 s heading west (pi)
    assert row.precedence(1.0, math.pi, t_other, h_other) == expected


def test_at_the_line_and_inside_share_their_thresholds():
    assert row.waiting_at_line(-row.PAST, 0.0, 0.0) and row.waiting_at_line(row.BEFORE, 0.0, 0.0)
    assert not row.waiting_at_line(0.0, 0.0, row.STANDING)
    assert not row.waiting_at_line(row.BEFORE + 0.01, 0.0, 0.0)
    assert row.has_entered(-row.PAST - 0.01, 0.0) and not row.has_entered(-row.PAST, 0.0)
    # the same answer measured to another reference (the autopilot measures to the box centre)
    assert row.waiting_at_line(12.0 + 3.0, 12.0, 0.1) == row.waiting_at_line(3.0, 0.0, 0.1)

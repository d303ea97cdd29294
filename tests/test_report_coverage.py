"""ε-coverage: the paper's estimator, the mesh covering radius and the covered fraction,
checked against brute force and against values known in closed form."""

import math
import subprocess
import sys

import numpy as np
import pytest

from pytest_avscenario.report.coverage import (
    covering_radius,
    covering_radius_bounds,
    epsilon_coverage,
    fraction_within,
    mesh_points,
)


def _cell_centres(k: int) -> np.ndarray:
    g = (np.arange(k) + 0.5) / k
    return np.array(np.meshgrid(g, g)).reshape(2, -1).T


def _full_mesh(m: int, d: int) -> np.ndarray:
    axes = [np.linspace(0.0, 1.0, m)] * d
    return np.array(np.meshgrid(*axes, indexing="ij")).reshape(d, -1).T


def _nearest(mesh: np.ndarray, pts: np.ndarray) -> np.ndarray:
    # Brute force on purpose: every mesh node against every sample, no tree, no chunks.
    diff = mesh[:, None, :] - pts[None, :, :]
    return np.sqrt((diff**2).sum(-1)).min(axis=1)


def _brute_estimator(pts: np.ndarray, tol: float) -> float:
    """The paper's binary search written as plainly as possible (whole mesh at once)."""
    d = pts.shape[1]
    lo, hi = 0.0, math.sqrt(d)
    while hi - lo > tol:
        mid = (lo + hi) / 2
        m = max(2, math.ceil(1 / mid - 1e-12) + 1)
        if _nearest(_full_mesh(m, d), pts).max() <= mid * (1 + 1e-9) + 1e-12:
            hi = mid
        else:
            lo = mid
    return hi


@pytest.mark.parametrize("k", [1, 2, 3, 5, 8])
def test_cell_centres_have_the_known_covering_radius(k):
    # k×k samples at the cell centres of the unit square: every cell corner is farthest,
    # at half a cell diagonal sqrt(2)/(2k); a mesh whose nodes include the corners sees it.
    pts = _cell_centres(k)
    expected = math.sqrt(2) / (2 * k)
    assert covering_radius(pts, resolution=4 * k + 1) == pytest.approx(expected, rel=1e-12)
    lower, upper = covering_radius_bounds(pts, resolution=4 * k + 1)
    assert lower == pytest.approx(expected) and upper > expected
    eps = epsilon_coverage(pts, tol=0.001)
    assert expected - 0.001 <= eps <= expected + 0.002


@pytest.mark.parametrize("seed", range(6))
@pytest.mark.parametrize("d", [1, 2, 3])
def test_estimator_matches_brute_force_on_small_random_cases(seed, d):
    rng = np.random.default_rng(seed)
    pts = rng.random((int(rng.integers(1, 25)), d))
    for tol in (0.05, 0.01):
        assert epsilon_coverage(pts, tol=tol) == pytest.approx(_brute_estimator(pts, tol), abs=1e-12)


@pytest.mark.parametrize("seed", range(4))
@pytest.mark.parametrize("d", [2, 3])
def test_mesh_covering_radius_matches_brute_force_and_brackets_the_truth(seed, d):
    rng = np.random.default_rng(100 + seed)
    pts = rng.random((15, d))
    m = 9 if d == 3 else 17
    # A small chunk forces many chunks: the answer must not depend on the chunking.
    assert covering_radius(pts, m, chunk=7) == pytest.approx(_nearest(_full_mesh(m, d), pts).max())
    fine = _nearest(_full_mesh(33 if d == 3 else 257, d), pts).max()
    lower, upper = covering_radius_bounds(pts, m)
    assert lower <= fine + 1e-12 <= upper + 1e-12


def test_one_dimension_against_the_closed_form():
    pts = np.array([0.1, 0.35, 0.9])
    # In 1-D the farthest point is an end of the interval or the middle of the widest gap.
    exact = max(0.1, 1 - 0.9, (0.35 - 0.1) / 2, (0.9 - 0.35) / 2)
    lower, upper = covering_radius_bounds(pts, 1001)
    assert lower <= exact <= upper and upper - lower < 1e-3
    # The paper's estimator only probes an ε′-spaced mesh, so it may undershoot (here the
    # 0.25-mesh misses the gap's middle at 0.625), but never by more than the mesh allows:
    # feasibility at ε′ means every point is within ε′ + ε′/2 of a sample; and every
    # ε′ ≥ the true radius is feasible, so it overshoots by less than the tolerance.
    eps = epsilon_coverage(pts, tol=0.001)
    assert exact / 1.5 <= eps < exact + 0.001


@pytest.mark.parametrize("seed", range(5))
def test_estimator_brackets_the_true_radius(seed):
    pts = np.random.default_rng(200 + seed).random((30, 2))
    lower, upper = covering_radius_bounds(pts, 513)
    eps = epsilon_coverage(pts, tol=0.01)
    assert eps < upper + 0.01
    assert lower <= eps * (1 + math.sqrt(2) / 2) + 1e-12


def test_more_samples_never_cover_worse():
    rng = np.random.default_rng(7)
    pts = rng.random((400, 2))
    radii = [covering_radius(pts[:n], 129) for n in (25, 100, 400)]
    assert radii[0] >= radii[1] >= radii[2]
    assert epsilon_coverage(pts[:25]) > epsilon_coverage(pts)


def test_fraction_within_known_areas():
    centre = np.array([[0.5, 0.5]])
    assert fraction_within(centre, 0.3) == pytest.approx(math.pi * 0.09, abs=0.01)
    assert fraction_within(centre, 0.0) == 0.0
    assert fraction_within(centre, math.sqrt(2) / 2 + 1e-9) == 1.0
    pts = _cell_centres(4)
    assert fraction_within(pts, covering_radius(pts, 17)) == 1.0


def test_six_dimensions_stay_cheap_and_sane():
    pts = np.random.default_rng(3).random((300, 6))
    eps = epsilon_coverage(pts)
    lower, upper = covering_radius_bounds(pts, 6)
    assert 0 < eps < math.sqrt(6) and lower <= upper
    assert 0 < fraction_within(pts, eps / 2) < 1


def test_mesh_points_are_generated_in_pieces_consistently():
    whole = mesh_points(5, 3)
    parts = np.vstack([mesh_points(5, 3, s, s + 11) for s in range(0, 125, 11)])
    assert np.array_equal(whole, parts)
    assert np.array_equal(whole, _full_mesh(5, 3))


@pytest.mark.parametrize(
    "bad, match",
    [
        (np.zeros((0, 2)), "at least one sampled point"),
        (np.zeros((3, 0)), "continuous dimension"),
        (np.array([[0.5, 1.5]]), r"\[0, 1\]"),
        (np.array([[np.nan, 0.5]]), "NaN"),
    ],
)
def test_bad_input_is_refused_with_a_reason(bad, match):
    with pytest.raises(ValueError, match=match):
        epsilon_coverage(bad)


def test_importing_the_report_package_stays_light():
    code = (
        "import sys, pytest_avscenario.report as r, pytest_avscenario.report.coverage;"
        "print(sorted(m for m in ('matplotlib', 'scipy', 'pandas') if m in sys.modules))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"

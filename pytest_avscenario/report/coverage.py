"""ε-coverage of a sampled feature space, the way the Scenic + VerifAI report measured it.

A scenario's continuous parameters are scaled to the unit cube ``[0, 1]^d``; the sampled
cases are points in it. The *covering radius* of those points is the smallest ε such that
ε-balls around them cover the cube — how far a failure could hide from every sample. The
paper estimates it by binary search on a mesh width ε′: place a mesh of spacing ε′ on the
cube, find each mesh point's nearest sample (k-d tree), and call ε′ feasible when every
mesh point lies within ε′ of a sample; the answer is the smallest feasible ε′ to a
tolerance (:func:`epsilon_coverage`). Two companions give a cross-check:
:func:`covering_radius` computes the exact largest nearest-sample distance over one fixed
mesh (a lower bound on the true radius that is exact whenever the farthest point is a mesh
node, and within ``h·√d/2`` of it otherwise), and :func:`fraction_within` the share of the
cube's volume within a given radius of some sample.

Every function walks the mesh in chunks, so memory stays bounded (a few MB) whatever the
mesh size; the number of mesh points visited near the answer grows like the number of
samples, which keeps d up to 6 practical. scipy is imported inside the functions, so
importing this module costs nothing.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

__all__ = [
    "epsilon_coverage",
    "covering_radius",
    "covering_radius_bounds",
    "fraction_within",
    "mesh_points",
    "DEFAULT_TOL",
]

#: Default tolerance of the binary search on ε′. The paper used 0.05; 0.01 resolves the
#: differences between samplers that matter at the sample counts of a test run.
DEFAULT_TOL = 0.01

# Rows of mesh points generated and queried at once: 65536 × 6 float64 ≈ 3 MB, big enough
# that the k-d tree query dominates the Python overhead.
_CHUNK = 1 << 16

# A mesh larger than this is never enumerated: the caller gets an error naming the size
# instead of a process that runs for hours.
_MAX_MESH_POINTS = 1 << 34


def _as_points(points_unit: Any) -> np.ndarray:
    """Validate and return an (n, d) float array inside the unit cube."""
    pts = np.asarray(points_unit, dtype=float)
    if pts.ndim == 1:
        # A flat list of numbers is n points of a 1-D space, the least surprising reading.
        pts = pts.reshape(-1, 1)
    if pts.ndim != 2:
        raise ValueError(f"points must be an (n, d) array, got shape {pts.shape}")
    if pts.shape[0] == 0:
        raise ValueError("ε-coverage needs at least one sampled point, got none")
    if pts.shape[1] == 0:
        raise ValueError("ε-coverage needs at least one continuous dimension (report '—' instead)")
    if not np.all(np.isfinite(pts)):
        raise ValueError("points contain NaN or infinity; scale parameters to [0, 1] first")
    lo, hi = float(pts.min()), float(pts.max())
    if lo < -1e-9 or hi > 1 + 1e-9:
        raise ValueError(f"points must lie in [0, 1]^d (got values in [{lo:g}, {hi:g}])")
    return np.clip(pts, 0.0, 1.0)


def _tree(pts: np.ndarray):
    from scipy.spatial import cKDTree

    return cKDTree(pts)


def mesh_points(nodes_per_axis: int, d: int, start: int = 0, stop: int | None = None) -> np.ndarray:
    """Rows ``start:stop`` of the regular mesh with ``nodes_per_axis`` nodes per axis.

    Nodes sit at ``i / (nodes_per_axis - 1)`` (both faces included: the corners of the cube
    are where a sample set most often leaves its largest hole). Rows are in C order of the
    multi-index, computed arithmetically so no full mesh is ever built.
    """
    m = int(nodes_per_axis)
    if m < 1:
        raise ValueError("a mesh needs at least one node per axis")
    total = m**d
    stop = total if stop is None else min(int(stop), total)
    flat = np.arange(start, stop, dtype=np.int64)
    out = np.empty((flat.shape[0], d), dtype=float)
    scale = 1.0 / (m - 1) if m > 1 else 0.0
    # Node 0 of a one-node mesh sits at the cube's centre, its most representative point.
    offset = 0.5 if m == 1 else 0.0
    for axis in range(d - 1, -1, -1):
        out[:, axis] = (flat % m) * scale + offset
        flat //= m
    return out


def _chunks(total: int, chunk: int, strided: bool):
    """Yield (start, stop) of mesh chunks.

    ``strided`` visits the chunks in a bit-reversal-like spread order instead of front to
    back: an infeasibility check stops at the first far mesh point, and holes are spread over
    the whole cube, so sampling chunks from everywhere finds one sooner.
    """
    n = -(-total // chunk)
    order = range(n)
    if strided and n > 2:
        step = max(1, int(n * 0.6180339887498949)) | 1
        while math.gcd(step, n) != 1:
            step += 2
        order = ((i * step) % n for i in range(n))
    for i in order:
        yield i * chunk, min((i + 1) * chunk, total)


def _nodes_for_width(width: float) -> int:
    # The finest mesh including both faces whose spacing does not exceed ``width``.
    return max(2, int(math.ceil(1.0 / width - 1e-12)) + 1)


def _check_mesh_size(m: int, d: int) -> None:
    if m**d > _MAX_MESH_POINTS:
        raise ValueError(
            f"a mesh of {m}^{d} = {m**d:.3g} points is too large to enumerate; "
            "use a coarser resolution / tolerance or fewer continuous dimensions"
        )


def _feasible(tree, d: int, width: float, chunk: int) -> bool:
    """True when every node of the width-``width`` mesh lies within ``width`` of a sample."""
    m = _nodes_for_width(width)
    _check_mesh_size(m, d)
    # distance_upper_bound makes the tree prune everything farther than we care about;
    # a node with no sample within the bound comes back as inf. The tiny slack keeps nodes
    # at exactly ``width`` (the k×k cell-centre case) on the feasible side.
    bound = width * (1 + 1e-9) + 1e-12
    for start, stop in _chunks(m**d, chunk, strided=True):
        dist, _ = tree.query(mesh_points(m, d, start, stop), k=1, distance_upper_bound=bound)
        if not np.all(np.isfinite(dist)):
            return False
    return True


def epsilon_coverage(
    points_unit: Any,
    tol: float = DEFAULT_TOL,
    *,
    chunk: int = _CHUNK,
) -> float:
    """The paper's ε-coverage estimate of ``points_unit`` (shape (n, d), inside [0, 1]^d).

    Binary search on the mesh width ε′ over ``[0, √d]`` until the bracket is narrower than
    ``tol``; returns the smallest ε′ found feasible (every node of an ε′-spaced mesh within
    ε′ of a sample). Every ε′ at or above the true covering radius r is feasible, so the
    estimate is below ``r + tol``; because only mesh nodes are probed it can undershoot, but
    feasibility puts every point of the cube within ε′ + ε′·√d/2 of a sample, so
    ``r <= estimate * (1 + √d/2)``. Use :func:`covering_radius_bounds` for a tight bracket.
    """
    pts = _as_points(points_unit)
    tol = float(tol)
    if not (tol > 0 and math.isfinite(tol)):
        raise ValueError(f"tol must be a positive number, got {tol!r}")
    d = pts.shape[1]
    tree = _tree(pts)
    # At ε′ = √d the mesh is the 2^d corners, each within √d of any sample: always feasible.
    lo, hi = 0.0, math.sqrt(d)
    while hi - lo > tol:
        mid = 0.5 * (lo + hi)
        if _feasible(tree, d, mid, chunk):
            hi = mid
        else:
            lo = mid
    return float(hi)


def _default_resolution(d: int, budget: int = 1 << 20) -> int:
    # As fine as about a million nodes allows: 1025 per axis in 2-D, 33 in 4-D, 11 in 6-D.
    return max(2, int(math.floor(budget ** (1.0 / d) + 1e-9)))


def covering_radius(points_unit: Any, resolution: int | None = None, *, chunk: int = _CHUNK) -> float:
    """Exact largest distance from a node of a regular mesh to its nearest sample.

    ``resolution`` is the number of mesh nodes per axis (both faces included, spacing
    ``1/(resolution-1)``); default about a million nodes in total. VerifAI's 51³ mesh is
    ``resolution=51``. This is the covering radius of the mesh by the samples: a lower bound
    on the covering radius of the cube, exact when the farthest point of the cube is a mesh
    node (e.g. ``k×k`` cell-centre samples with ``resolution-1`` a multiple of ``k``).
    """
    pts = _as_points(points_unit)
    d = pts.shape[1]
    m = _default_resolution(d) if resolution is None else int(resolution)
    if m < 2:
        raise ValueError("resolution must be at least 2 nodes per axis")
    _check_mesh_size(m, d)
    tree = _tree(pts)
    worst = 0.0
    for start, stop in _chunks(m**d, chunk, strided=False):
        dist, _ = tree.query(mesh_points(m, d, start, stop), k=1)
        worst = max(worst, float(dist.max()))
    return worst


def covering_radius_bounds(
    points_unit: Any, resolution: int | None = None, *, chunk: int = _CHUNK
) -> tuple[float, float]:
    """A certified bracket ``(lower, upper)`` on the true covering radius of the cube.

    Every point of the cube lies within half a cell diagonal ``h·√d/2`` of a mesh node, so
    the true radius is at most the mesh's covering radius plus that.
    """
    pts = _as_points(points_unit)
    d = pts.shape[1]
    m = _default_resolution(d) if resolution is None else int(resolution)
    lower = covering_radius(pts, m, chunk=chunk)
    return lower, lower + math.sqrt(d) / (2.0 * (m - 1))


def fraction_within(
    points_unit: Any,
    radius: float,
    *,
    n_probe: int = 1 << 16,
    seed: int = 0,
    chunk: int = _CHUNK,
) -> float:
    """Share of the unit cube's volume within ``radius`` of some sample (0..1).

    Estimated on ``n_probe`` scrambled-Sobol probe points (deterministic for a given
    ``seed``), whose error shrinks about like 1/n_probe for smooth regions — about 0.2 % at
    the default in up to 6-D, which is plenty for a report.
    """
    pts = _as_points(points_unit)
    radius = float(radius)
    if not radius >= 0:
        raise ValueError(f"radius must be a non-negative number, got {radius!r}")
    from scipy.stats import qmc

    d = pts.shape[1]
    tree = _tree(pts)
    # A power of two keeps Sobol's balance properties (and silences scipy's warning).
    m = max(1, int(math.ceil(math.log2(max(2, int(n_probe))))))
    probes = qmc.Sobol(d, scramble=True, seed=seed).random_base2(m)
    inside = 0
    for start in range(0, probes.shape[0], chunk):
        dist, _ = tree.query(
            probes[start : start + chunk], k=1, distance_upper_bound=radius * (1 + 1e-12) + 1e-15
        )
        inside += int(np.count_nonzero(np.isfinite(dist)))
    return inside / probes.shape[0]

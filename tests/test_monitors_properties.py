"""Properties of the metrics on random scenes (Hypothesis): the sign of rho agrees with the
boolean definition, and distance/TTC do not depend on where the scene is or how it is turned."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import assume, example, given, settings
from hypothesis import strategies as st

from pytest_avscenario.monitors import always, collision, distance, gap, ttc, ttc_to
from pytest_avscenario.trajectory import Trajectory

coord = st.floats(-60, 60, allow_nan=False, allow_infinity=False)
# speeds below 1 µm/s are zero: with subnormal closing speeds the textbook quadratic's
# leading coefficient underflows and numpy.roots loses a root the closed form keeps
vel = st.floats(-25, 25, allow_nan=False, allow_infinity=False).map(
    lambda v: 0.0 if abs(v) < 1e-6 else v)


@st.composite
def scenes(draw):
    """Random (A, T) scene as plain arrays, some agents absent at some steps."""
    A = draw(st.integers(2, 4))
    T = draw(st.integers(1, 6))
    arr = lambda s: np.array(draw(st.lists(s, min_size=A * T, max_size=A * T))).reshape(A, T)
    x, y, vx, vy = arr(coord), arr(coord), arr(vel), arr(vel)
    heading = arr(st.floats(-math.pi, math.pi))
    present = arr(st.booleans())
    present[0] = True  # the ego is recorded at every step
    return dict(x=x, y=y, vx=vx, vy=vy, heading=heading, present=present)


def build(s):
    A, T = s["x"].shape
    agents = {}
    for a in range(A):
        d = {k: np.where(s["present"][a], s[k][a], np.nan) for k in ("x", "y", "vx", "vy", "heading")}
        d["present"] = s["present"][a]
        agents["ego" if a == 0 else f"car{a}"] = d
    return Trajectory.from_arrays(np.arange(T) * 0.1, agents)


def pairs(s):
    """(other agent, step) for every step where ego and the other are both present."""
    A, T = s["x"].shape
    return [(a, k) for a in range(1, A) for k in range(T) if s["present"][a, k]]


def ttc_textbook(s, a, k, r=5.0):
    """TTC straight from the definition, solving the quadratic with numpy.roots."""
    dp = np.array([s["x"][a, k] - s["x"][0, k], s["y"][a, k] - s["y"][0, k]])
    dv = np.array([s["vx"][a, k] - s["vx"][0, k], s["vy"][a, k] - s["vy"][0, k]])
    if dp @ dp <= r * r:
        return 0.0
    roots = np.roots([dv @ dv, 2 * dp @ dv, dp @ dp - r * r])
    real = sorted(z.real for z in roots if abs(z.imag) < 1e-12)
    if len(real) < 2 or real[1] <= 0:
        return math.inf
    return real[0]


def closest_approach(s, a, k):
    dp = np.array([s["x"][a, k] - s["x"][0, k], s["y"][a, k] - s["y"][0, k]])
    dv = np.array([s["vx"][a, k] - s["vx"][0, k], s["vy"][a, k] - s["vy"][0, k]])
    if dv @ dv == 0:
        return float(np.hypot(*dp))
    tau = -(dp @ dv) / (dv @ dv)
    return float(np.hypot(*(dp + dv * tau)))


@settings(max_examples=150, deadline=None)
@given(scenes())
def test_distance_sign_agrees_with_boolean_definition(s):
    rho = distance(5.0, kind="centre").evaluate(build(s)).rho
    dists = [math.hypot(s["x"][a, k] - s["x"][0, k], s["y"][a, k] - s["y"][0, k])
             for a, k in pairs(s)]
    holds = all(d >= 5.0 for d in dists)
    assert (rho >= 0) == holds
    if dists:
        assert rho == pytest.approx(min(dists) - 5.0, rel=1e-12, abs=1e-12)
    else:
        assert rho == math.inf


@settings(max_examples=150, deadline=None)
@given(scenes())
def test_ttc_sign_agrees_with_boolean_definition(s):
    # requirement per pair and step: never inside, and (t1 >= 2 or t2 <= 0 or no real root)
    ps = pairs(s)
    # numpy.roots and the closed form may disagree on a root that exists only by rounding
    assume(all(abs(closest_approach(s, a, k) - 5.0) > 1e-6 for a, k in ps))
    rho = ttc(2.0, kind="centre").evaluate(build(s)).rho
    ttcs = [ttc_textbook(s, a, k) for a, k in ps]
    assume(all(abs(v - 2.0) > 1e-6 for v in ttcs))
    assert (rho >= 0) == all(v >= 2.0 for v in ttcs)
    if ttcs and min(ttcs) < math.inf:
        assert rho == pytest.approx(min(ttcs) - 2.0, rel=1e-6, abs=1e-6)
    else:
        assert rho == math.inf


def swept_polygons(traj, a, k, u, span=True):
    """Shapely footprints of agent ``a`` at fractions ``u`` of recorded interval k (centre and
    heading interpolated linearly, the heading the shorter way round), or at step k alone
    (``span`` False, or k the last step)."""
    import shapely

    x0, y0, h0 = traj.x[a, k], traj.y[a, k], traj.heading[a, k]
    if span and k + 1 < traj.n_steps:
        dh = (traj.heading[a, k + 1] - h0 + math.pi) % (2 * math.pi) - math.pi
        x = x0 + u * (traj.x[a, k + 1] - x0)
        y = y0 + u * (traj.y[a, k + 1] - y0)
        h = h0 + u * dh
    else:
        x, y, h = np.full_like(u, x0), np.full_like(u, y0), np.full_like(u, h0)
    hl, hw = traj.length[a] / 2, traj.width[a] / 2
    corners = np.array([[hl, hw], [hl, -hw], [-hl, -hw], [-hl, hw]])
    c, sn = np.cos(h)[:, None], np.sin(h)[:, None]
    px = x[:, None] + corners[:, 0] * c - corners[:, 1] * sn
    py = y[:, None] + corners[:, 0] * sn + corners[:, 1] * c
    return shapely.polygons(np.stack([px, py], axis=-1))


@settings(max_examples=100, deadline=None)
@given(scenes())
# two passes through each other about equally deep: the moment named is the first contact
@example(s={"x": np.zeros((2, 6)), "vx": np.zeros((2, 6)), "vy": np.zeros((2, 6)),
            "heading": np.zeros((2, 6)),
            "y": np.array([[0.0, -3.0, 0.0, 0.0, 0.0, 0.0], [0.0, 0.0, -2.0, 2.0, 0.0, 0.0]]),
            "present": np.array([[True] * 6, [False, True, True, True, False, False]])})
def test_collision_agrees_with_shapely_on_interpolated_sub_steps(s):
    """The monitor sees an overlap exactly when the footprints, moved linearly between the
    recorded steps and checked with shapely on 250 sub-steps per step, overlap; the moment
    it names is an overlap, and for an overlap between steps none comes before it."""
    import shapely

    traj = build(s)
    r = collision(use_crash_flag=False).evaluate(traj)
    assume(abs(r.rho) > 1e-3)
    u = np.linspace(0.0, 1.0, 251)
    first = {}  # agent -> first sub-step time with an overlap deeper than the tolerance
    for a in range(1, traj.n_agents):
        for k in range(traj.n_steps):
            if not traj.present[a, k]:
                continue
            # between two steps only where both agents are recorded at both ends
            span = k + 1 < traj.n_steps and traj.present[a, k + 1]
            uu = u if span else u[:1]
            ego, other = swept_polygons(traj, 0, k, uu, span), swept_polygons(traj, a, k, uu, span)
            area = np.zeros(uu.size)
            meet = shapely.intersects(ego, other)
            area[meet] = shapely.area(shapely.intersection(ego[meet], other[meet]))
            # an overlap of area > 0.01 m² is over 1.9 mm deep (its width times the 5.4 m
            # diagonal bounds the area): beyond the search's 0.5 mm
            hit = np.flatnonzero(area > 1e-2)
            if hit.size and a not in first:
                first[a] = traj.t[k] + uu[hit[0]] * (traj.t[min(k + 1, traj.n_steps - 1)] - traj.t[k])
    if r.rho >= 0:
        assert not first
        return
    a = traj.names.index(r.agent)
    k = int(np.searchsorted(traj.t, r.t, side="right")) - 1
    frac = np.array([0.0 if k + 1 >= traj.n_steps else (r.t - traj.t[k]) / (traj.t[k + 1] - traj.t[k])])

    span = k + 1 < traj.n_steps and traj.present[a, k + 1]
    ego_at = swept_polygons(traj, 0, k, frac, span)[0]
    other_at = swept_polygons(traj, a, k, frac, span)[0]
    assert ego_at.distance(other_at) < 1e-9  # the named moment is an overlap
    if a in first and "between the recorded steps" in r.detail:
        assert r.t <= first[a] + 1e-9  # and none of that agent comes before it


def transform(s, theta, dx, dy):
    c, sn = math.cos(theta), math.sin(theta)
    out = dict(s)
    out["x"] = c * s["x"] - sn * s["y"] + dx
    out["y"] = sn * s["x"] + c * s["y"] + dy
    out["vx"] = c * s["vx"] - sn * s["vy"]
    out["vy"] = sn * s["vx"] + c * s["vy"]
    out["heading"] = s["heading"] + theta
    return out


@settings(max_examples=150, deadline=None)
@given(scenes(), st.floats(-math.pi, math.pi), coord, coord)
def test_distance_and_ttc_invariant_under_rotation_and_translation(s, theta, dx, dy):
    # exclude scenes that graze the 5-m circle: there "touches" vs "misses" is decided by
    # the last bit of a rotated coordinate
    assume(all(abs(closest_approach(s, a, k) - 5.0) > 1e-6 for a, k in pairs(s)))
    a, b = build(s), build(transform(s, theta, dx, dy))
    for m in (distance(5.0), ttc(2.0), distance(1.0, footprint=True), collision()):
        ra, rb = m.evaluate(a).rho, m.evaluate(b).rho
        if math.isinf(ra):
            assert rb == ra, m.name
        else:
            assert rb == pytest.approx(ra, rel=1e-6, abs=1e-6), m.name


@settings(max_examples=80, deadline=None)
@given(scenes())
def test_stl_formulas_agree_with_the_builtin_metrics(s):
    traj = build(s)
    assert always(gap() >= 5.0).evaluate(traj).rho == distance(5.0, kind="centre").evaluate(traj).rho
    assert always(ttc_to() >= 2.0).evaluate(traj).rho == ttc(2.0, kind="centre").evaluate(traj).rho


@settings(max_examples=100, deadline=None)
@given(scenes())
def test_footprint_gap_matches_shapely(s):
    import shapely

    from pytest_avscenario.monitors.metrics import footprint_gap

    traj = build(s)
    ours = footprint_gap(traj)
    for a, k in pairs(s):
        polys = traj.footprints(k)
        assert ours[a - 1, k] == pytest.approx(shapely.distance(polys[0], polys[a]), abs=1e-9)
    absent = ~(traj.present[0] & traj.present[1:])
    assert np.all(ours[absent] == math.inf)

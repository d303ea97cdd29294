"""STL operators: cross-checked against RTAMT and a brute-force reference on random signals."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from pytest_avscenario.monitors import (
    MonitorError,
    MonitorSet,
    always,
    and_,
    as_monitor,
    distance,
    ego_speed,
    eventually,
    gap,
    implies,
    lane_offset,
    not_,
    or_,
    predicate,
    signal,
    ttc_to,
    until,
)
from pytest_avscenario.trajectory import Trajectory


def sig_traj(a, b, t=None):
    n = len(a)
    t = np.arange(n, dtype=float) if t is None else np.asarray(t, dtype=float)
    return Trajectory.from_arrays(t, {"ego": {"x": np.zeros(n), "y": np.zeros(n)}},
                                  signals={"a": a, "b": b})


A = signal("a") >= 0
B = signal("b") >= 0


# -- brute-force reference: the textbook definitions, one step at a time --------------------

def ref_window(t, k, lo, hi):
    return [j for j in range(len(t)) if lo - 1e-9 <= t[j] - t[k] <= hi + 1e-9]


def ref_always(x, t, lo=0.0, hi=math.inf):
    return np.array([min([x[j] for j in ref_window(t, k, lo, hi)], default=math.inf)
                     for k in range(len(x))])


def ref_eventually(x, t, lo=0.0, hi=math.inf):
    return np.array([max([x[j] for j in ref_window(t, k, lo, hi)], default=-math.inf)
                     for k in range(len(x))])


def ref_until(x, y, t, lo=0.0, hi=math.inf):
    out = []
    for k in range(len(x)):
        best = -math.inf
        for j in ref_window(t, k, lo, hi):
            best = max(best, min([y[j]] + [x[i] for i in range(k, j)]))
        out.append(best)
    return np.array(out)


signals = st.integers(2, 25).flatmap(lambda n: st.tuples(
    st.lists(st.floats(-10, 10, allow_nan=False), min_size=n, max_size=n),
    st.lists(st.floats(-10, 10, allow_nan=False), min_size=n, max_size=n),
))
windows = st.one_of(
    st.none(),
    st.tuples(st.integers(0, 6), st.integers(0, 8)).map(lambda p: (p[0], p[0] + p[1])),
)


# -- RTAMT cross-check ------------------------------------------------------------------------

try:
    import warnings

    with warnings.catch_warnings():  # its antlr runtime imports the deprecated typing.io
        warnings.simplefilter("ignore", DeprecationWarning)
        import rtamt
except ImportError:  # pragma: no cover - rtamt is a test dependency
    rtamt = None


def rtamt_eval(spec_text, a, b):
    spec = rtamt.StlDiscreteTimeSpecification()
    spec.declare_var("a", "float")
    spec.declare_var("b", "float")
    spec.spec = spec_text
    spec.parse()
    out = spec.evaluate({"time": list(range(len(a))), "a": list(a), "b": list(b)})
    return np.array([v for _, v in out], dtype=float)


def _w(win):
    return "" if win is None else f"[{win[0]},{win[1]}]"


@pytest.mark.skipif(rtamt is None, reason="rtamt not installed (test extra)")
@settings(max_examples=40, deadline=None)
@given(signals, windows, windows)
def test_operators_match_rtamt_on_random_signals(ab, w1, w2):
    a, b = ab
    traj = sig_traj(a, b)
    cases = [
        (f"always{_w(w1)}(a >= 0)", always(A, w1)),
        (f"eventually{_w(w1)}(a >= 0)", eventually(A, w1)),
        (f"(a >= 0) until{_w(w1)} (b >= 0)", until(A, B, w1)),
        (f"always{_w(w1)}((a >= 0) -> eventually{_w(w2)}(b >= 0))",
         always(implies(A, eventually(B, w2)), w1)),
        (f"not(always{_w(w2)}((a >= 0) and not (b >= 0))) or (b >= 0)",
         or_(not_(always(and_(A, not_(B)), w2)), B)),
    ]
    for text, formula in cases:
        ours, _ = formula.series(traj)
        np.testing.assert_array_equal(ours, rtamt_eval(text, a, b), err_msg=text)


# -- brute-force cross-check (also on non-uniform time and fractional windows) ----------------

@settings(max_examples=60, deadline=None)
@given(signals, st.data())
def test_operators_match_brute_force_on_nonuniform_time(ab, data):
    a, b = map(np.asarray, ab)
    n = len(a)
    steps = data.draw(st.lists(st.sampled_from([0.05, 0.1, 0.2, 0.5]), min_size=n, max_size=n))
    t = np.cumsum(steps) - steps[0]
    lo = data.draw(st.sampled_from([0.0, 0.1, 0.25, 0.5]))
    hi = lo + data.draw(st.sampled_from([0.0, 0.1, 0.3, 1.0, math.inf]))
    traj = sig_traj(a, b, t)
    np.testing.assert_array_equal(always(A, (lo, hi)).series(traj)[0], ref_always(a, t, lo, hi))
    np.testing.assert_array_equal(eventually(A, (lo, hi)).series(traj)[0],
                                  ref_eventually(a, t, lo, hi))
    np.testing.assert_array_equal(until(A, B, (lo, hi)).series(traj)[0], ref_until(a, b, t, lo, hi))


@settings(max_examples=60, deadline=None)
@given(signals, windows)
def test_not_always_not_is_eventually(ab, w):
    a, b = ab
    traj = sig_traj(a, b)
    np.testing.assert_array_equal(not_(always(not_(A), w)).series(traj)[0],
                                  eventually(A, w).series(traj)[0])
    np.testing.assert_array_equal(not_(eventually(not_(A), w)).series(traj)[0],
                                  always(A, w).series(traj)[0])


def test_empty_windows_give_plus_inf_for_always_and_minus_inf_for_eventually():
    traj = sig_traj([1.0, 2.0, 3.0], [0.0, 0.0, 0.0])
    # the window [5, 6] s lies beyond the 2-s trace at every step
    assert always(A, (5, 6)).evaluate(traj).rho == math.inf
    assert eventually(A, (5, 6)).evaluate(traj).rho == -math.inf
    assert until(A, B, (5, 6)).evaluate(traj).rho == -math.inf


def test_window_is_in_seconds_of_the_trajectory_time():
    t = np.arange(50) * 0.1
    a = np.where(t > 2.05, 1.0, -1.0)  # becomes true at t = 2.1 s
    traj = sig_traj(a, a, t)
    assert eventually(A, (0, 2.0)).evaluate(traj).rho == -1.0
    assert eventually(A, (0, 2.1)).evaluate(traj).rho == 1.0


# -- signals over a trajectory ----------------------------------------------------------------

def following(n=21, dt=0.5):
    t = np.arange(n) * dt
    return Trajectory.from_arrays(t, {
        "ego": {"x": 10 * t, "y": 0 * t, "vx": 10.0, "vy": 0.0, "lane_offset": 0.2},
        "lead": {"x": 30 + 8 * t, "y": 0 * t, "vx": 8.0, "vy": 0.0},
        "parked": {"x": 60 + 0 * t, "y": 4 + 0 * t, "vx": 0.0, "vy": 0.0},
    })


def test_gap_to_nearest_agent_reports_time_and_agent():
    traj = following()
    # gap to lead = 30 - 2t; at t = 10 s: 10 m; parked is 4 m to the side at x=60 (t=6 s)
    r = always(gap() >= 5.0).evaluate(traj)
    assert r.rho == pytest.approx(4.0 - 5.0)
    assert (r.t, r.agent) == (6.0, "parked")
    r2 = always(gap("lead") >= 5.0).evaluate(traj)
    assert r2.rho == pytest.approx(10.0 - 5.0) and (r2.t, r2.agent) == (10.0, "lead")


def test_speed_and_lane_offset_signals():
    traj = following()
    assert always(ego_speed() <= 12.0).evaluate(traj).rho == pytest.approx(2.0)
    assert always(lane_offset() <= 0.5).evaluate(traj).rho == pytest.approx(0.3)
    # signal arithmetic: relative closing speed 10 - 8 = 2 m/s
    closing = ego_speed() - signal(lambda tr: tr.speed[1], name="lead_speed")
    assert always(closing <= 3.0).evaluate(traj).rho == pytest.approx(1.0)


def test_ttc_signal_matches_ttc_monitor():
    from pytest_avscenario.monitors import ttc

    traj = following()
    assert always(ttc_to() >= 2.0).evaluate(traj).rho == pytest.approx(ttc(kind="centre").evaluate(traj).rho)


def test_until_on_a_trajectory_reports_the_deciding_step():
    t = np.arange(10) * 1.0
    speed = np.array([20, 18, 15, 12, 9, 6, 3, 0, 0, 0], dtype=float)
    traj = Trajectory.from_arrays(t, {"ego": {"x": np.cumsum(speed), "y": 0 * t, "speed": speed}},
                                  signals={"stop_arm": (t >= 3).astype(float)})
    # the ego must be moving slower than 25 m/s until it is stopped, within 8 s
    f = until(ego_speed() <= 25.0, ego_speed() <= 0.5, (0, 8))
    r = f.evaluate(traj)
    assert r.rho == pytest.approx(0.5) and r.t == 7.0


def test_formulas_work_as_monitors_in_a_set_with_names():
    traj = following()
    phi = always(implies(gap() <= 15.0, ego_speed() <= 9.0)).named("slow_when_close")
    ms = MonitorSet([phi, distance(kind="centre")])
    v = ms.evaluate(traj)
    assert "slow_when_close" in v.results and v.results["slow_when_close"].rho < 0
    assert always(ego_speed() >= 5).name == "always(ego_speed >= 5)"
    assert eventually(A, (0, 3)).name == "eventually[0,3](a >= 0)"


def test_absent_other_agent_is_infinitely_far_for_gap():
    t = np.arange(4) * 1.0
    traj = Trajectory.from_arrays(t, {
        "ego": {"x": 0 * t, "y": 0 * t},
        "ped": {"x": [np.nan, np.nan, 3.0, 4.0], "y": 0 * t,
                "present": [False, False, True, True]},
    })
    assert always(gap() >= 1.0).evaluate(traj).rho == pytest.approx(2.0)
    assert eventually(gap() <= 3.0).evaluate(traj).rho == pytest.approx(0.0)


def test_nan_signal_is_an_error_with_the_time():
    traj = sig_traj([1.0, np.nan, 2.0], [0, 0, 0])
    with pytest.raises(MonitorError, match="t=1.000"):
        always(A).evaluate(traj)
    with pytest.raises(MonitorError, match="NaN"):
        MonitorSet([always(A)]).evaluate(traj)


def test_user_predicate_function():
    traj = sig_traj([1.0, -2.0, 3.0], [0, 0, 0])
    f = always(predicate(lambda tr: tr.signals["a"] + 1.0, name="a_plus_1"))
    assert f.evaluate(traj).rho == -1.0


@pytest.mark.parametrize("build, match", [
    (lambda: always(ego_speed()), "signal, not a formula"),
    (lambda: always(distance()), "one number per trajectory"),
    (lambda: always(A, (3, 1)), "ends before it starts"),
    (lambda: always(A, (-1, 1)), "window start"),
    (lambda: eventually(A, "soon"), "pair"),
    (lambda: ego_speed() >= "5", "number"),
    (lambda: and_(), "at least one"),
    (lambda: always(gap), "factory"),
])
def test_bad_formulas_fail_at_construction(build, match):
    with pytest.raises(MonitorError, match=match):
        build()


def test_unknown_recorded_signal_names_the_available_ones():
    traj = sig_traj([1.0, 2.0], [0.0, 0.0])
    with pytest.raises(MonitorError, match="'a', 'b'"):
        always(signal("speed_limit") >= 0).evaluate(traj)


def test_plain_function_of_series_is_a_monitor_too():
    traj = sig_traj([1.0, 2.0], [0.0, 0.0])
    m = as_monitor(lambda tr: float(tr.signals["a"].min()) - 0.5, name="a_min")
    assert m.evaluate(traj).rho == 0.5


@settings(max_examples=80, deadline=None)
@given(signals, windows, windows)
def test_sign_of_rho_agrees_with_boolean_semantics(ab, w1, w2):
    # the boolean reading of each formula, built from the same brute-force references on
    # 0/1 truth values (min/max of truth values = and/or; an empty always is true)
    a, b = map(np.asarray, ab)
    assume(np.all(a != 0) and np.all(b != 0))
    t = np.arange(len(a), dtype=float)
    traj = sig_traj(a, b)
    ta, tb = (a >= 0).astype(float), (b >= 0).astype(float)
    win = lambda w: (0.0, math.inf) if w is None else w
    cases = [
        (always(A, w1), ref_always(ta, t, *win(w1))),
        (eventually(B, w1), ref_eventually(tb, t, *win(w1))),
        (until(A, B, w1), ref_until(ta, tb, t, *win(w1))),
        (always(implies(A, eventually(B, w2)), w1),
         ref_always(np.maximum(1 - ta, ref_eventually(tb, t, *win(w2))), t, *win(w1))),
    ]
    for formula, truth in cases:
        rho = formula.evaluate(traj).rho
        assert (rho >= 0) == (truth[0] >= 1), formula.name

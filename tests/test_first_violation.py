"""Issue #17: a counterexample's time is its first violation, not its worst moment.

For invariants (distance, TTC, collision, ...) the first step at which the requirement was
already violated; for others (progress, a mean lane offset) the monitor's deciding moment.
"""

from __future__ import annotations

import numpy as np

from pytest_avscenario.monitors import distance, lane_keeping, progress
from pytest_avscenario.monitors.base import first_violation
from pytest_avscenario.trajectory import Trajectory


def _approach(gaps):
    t = np.arange(len(gaps)) * 0.1
    return Trajectory.from_arrays(t, {
        "ego": {"x": np.zeros(len(gaps)), "y": np.zeros(len(gaps))},
        "lead": {"x": np.asarray(gaps, float), "y": np.zeros(len(gaps))},
    })


def test_the_first_step_below_the_threshold_not_the_worst():
    gaps = [20, 12, 8, 4.9, 4.0, 2.0, 3.0, 6.0, 9.0]  # first below 5 m at step 3, worst at 5
    traj = _approach(gaps)
    m = distance(5.0, kind="centre")
    res = m.evaluate(traj)
    assert res.t == traj.t[5]
    assert first_violation(m, traj, res) == (traj.t[3], "lead")
    assert first_violation(m, _approach([20, 10, 6])) is None  # holds: no violation


def test_every_length_of_approach_gives_its_own_first_step():
    for k in range(1, 30):
        gaps = [10.0] * k + [1.0] * 5
        traj = _approach(gaps)
        assert first_violation(distance(5.0), traj)[0] == traj.t[k]


def test_monitors_that_are_not_invariants_keep_their_deciding_moment():
    traj = _approach([20, 19, 18, 17])  # the ego never moves: progress fails
    m = progress(5.0)
    res = m.evaluate(traj)
    assert res.rho < 0 and first_violation(m, traj, res) == (res.t, res.agent)
    assert lane_keeping(0.5).invariant is False


def test_time_series_of_a_case_marks_its_first_violation_and_thresholds(tmp_path):
    from PIL import Image

    from pytest_avscenario.monitors import ttc
    from pytest_avscenario.report.casefigs import critical_agent, plot_case_timeseries

    traj = _approach([20, 12, 8, 4.9, 4.0, 2.0, 3.0, 6.0, 9.0])
    assert critical_agent(traj, "lead") == 1 and critical_agent(traj, None, 0.5) == 1
    a = plot_case_timeseries(tmp_path / "a.png", traj, first_t=0.3, monitors=[distance(5.0, kind="centre"), ttc(2.0, kind="centre")])
    b = plot_case_timeseries(tmp_path / "b.png", traj, first_t=0.3, monitors=[distance(9.0, kind="centre"), ttc(2.0, kind="centre")])
    c = plot_case_timeseries(tmp_path / "c.png", traj, first_t=0.6, monitors=[distance(5.0, kind="centre"), ttc(2.0, kind="centre")])
    pix = {p: Image.open(p).convert("RGB").tobytes() for p in (a, b, c)}
    assert len(set(pix.values())) == 3  # the threshold and the marked moment are drawn
    assert a.stat().st_size < 40_000  # ~600 counterexamples per example-suite report

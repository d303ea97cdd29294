"""Evidence in one place: each monitor gives its own ρ per step (``Monitor.series``), the
monitors package names the critical agent and the values toward it, and the terminal and the
card write ρ and parameter values the same way."""

import html
import math

import numpy as np
import pytest

from pytest_avscenario.codec import fmt_rho, fmt_value
from pytest_avscenario.monitors import as_monitor, distance, lane_keeping, progress, ttc
from pytest_avscenario.monitors.evidence import TTC_RADIUS_M, case_evidence, threshold_lines, ttc_radius
from pytest_avscenario.trajectory import Trajectory

T = np.arange(0.0, 3.0, 0.5)


def _traj():
    # the lead closes from 20 m to 5 m ahead; the walker stands 7 m to the side, then leaves
    return Trajectory.from_arrays(T, {
        "ego": {"x": 0 * T, "y": 0 * T, "vx": 0 * T, "vy": 0 * T},
        "lead": {"x": 20 - 6 * T, "y": 0 * T, "vx": -6 + 0 * T, "vy": 0 * T},
        "walker": {"x": 0 * T, "y": 7 + 0 * T, "vx": 0 * T, "vy": 0 * T,
                   "present": T < 2.0},
    })


def test_a_pairwise_monitor_gives_rho_at_every_step_and_its_minimum_is_the_runs_rho():
    traj = _traj()
    m = distance(5.0, kind="centre")
    per = m.series(traj)
    nearest = np.minimum(20 - 6 * T, np.where(T < 2.0, 7.0, np.inf))
    np.testing.assert_allclose(per, nearest - 5.0)
    assert per.min() == pytest.approx(m.evaluate(traj).rho)
    t_series = ttc(2.0).series(traj)
    assert t_series.shape == T.shape and t_series.min() == pytest.approx(ttc(2.0).evaluate(traj).rho)


def test_a_whole_run_metric_or_a_plain_function_has_no_series():
    traj = _traj()
    assert progress(11.0).series(traj) is None
    assert lane_keeping(0.5).series(traj) is None
    assert as_monitor(lambda tr: 1.0, name="mine").series(traj) is None


def test_the_evidence_names_the_critical_agent_and_the_violated_monitors_series():
    traj = _traj()
    ev = case_evidence(traj, [distance(8.0), progress(11.0)], agent="walker", t=0.0,
                       violated=["distance", "progress"])
    assert traj.names[ev.critical] == "walker"
    np.testing.assert_allclose(ev.distance_m[T < 2.0], 7.0)
    assert set(ev.rho_t) == {"distance"}  # progress has no value per step
    nearest = case_evidence(traj, [], t=2.5)  # no name: the nearest at t
    assert traj.names[nearest.critical] == "lead" and nearest.rho_t == {}
    assert case_evidence(Trajectory.from_arrays(T, {"ego": {"x": T, "y": 0 * T}})).critical is None


def test_the_ttc_radius_comes_from_the_tests_ttc_monitor_else_the_papers():
    assert ttc_radius([distance(5.0)]) == TTC_RADIUS_M == 5.0
    assert ttc_radius([ttc(1.0), ttc(2.0, kind="centre", radius=3.0, name="c")]) == 3.0
    assert ttc_radius([ttc(1.0)]) == TTC_RADIUS_M  # a path TTC has no circle
    assert [q for q, *_ in threshold_lines([distance(5.0), ttc(2.0), progress()])] == ["distance", "ttc"]


def test_rho_and_values_are_written_one_way():
    assert [fmt_rho(v) for v in (0.5, -1.23456, math.inf, -math.inf, None)] == \
        ["+0.500", "-1.235", "+inf", "-inf", "—"]
    assert [fmt_value(v) for v in ("left", 12.3456789, 3, True, None)] == \
        ["'left'", "12.3457", "3", "True", "None"]


SCENARIO = """
from pytest_avscenario import scenario, Uniform, Choice
from pytest_avscenario.monitors import distance, ttc
from pytest_avscenario.trajectory import Trajectory

@scenario(x=Uniform(0, 1), side=Choice(["left"]), samples=2, monitors=[distance(50.0), ttc(2.0)])
def test_near(case):
    # both stand still: always within 50 m (violated), never on a collision course (TTC +inf)
    return Trajectory.from_arrays([0.0, 0.1], {
        "ego": {"x": [0.0, 0.0], "y": [0.0, 0.0], "vx": [0.0, 0.0], "vy": [0.0, 0.0]},
        "lead": {"x": [20.0, 20.0], "y": [0.0, 0.0], "vx": [0.0, 0.0], "vy": [0.0, 0.0]}})
"""


def test_the_terminal_and_the_card_write_a_case_the_same_way(pytester):
    pytester.makepyfile(test_near=SCENARIO)
    result = pytester.runpytest("-v", "--avs-db=none", "--avs-shrink-budget=0", "-p", "no:cacheprovider")
    out = result.stdout.str()
    assert "+inf" in out and "'left'" in out  # every metric with -v; the parameters
    (card, *_) = sorted((pytester.path / "avs-report" / "cases").glob("*.html"))
    page = card.read_text()
    assert ">+inf<" in page  # the TTC cell of the metrics table
    assert f">{html.escape(chr(39) + 'left' + chr(39))}<" in page  # the parameter table: 'left'


def test_an_stl_formula_gives_its_rho_at_every_step_of_the_recording():
    # an STL formula's own series is (rho, times) over the kept steps: the recording places it
    # on its steps instead of failing the card's replay (found by the declaration fuzz test)
    import numpy as np

    from pytest_avscenario.monitors import always, gap
    from pytest_avscenario.monitors.evidence import case_evidence
    from pytest_avscenario.trajectory import Trajectory

    t = np.arange(0.0, 2.0, 0.1)
    traj = Trajectory.from_arrays(t, agents={
        "ego": {"x": 10.0 * t, "y": 0 * t, "vx": 10.0, "vy": 0.0},
        "lead": {"x": -1.0 + 8.0 * t, "y": 0 * t, "vx": 8.0, "vy": 0.0}})
    formula = always(gap("lead") >= 5.0).named("gap5")
    ev = case_evidence(traj, [formula], violated=["gap5"], agent="lead", t=0.0)
    rho = ev.rho_t["gap5"]
    assert rho.shape == (traj.n_steps,)
    assert np.allclose(rho, formula.series(traj)[0])

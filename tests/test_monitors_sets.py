"""MonitorSet, as_monitor and the serialization of ±inf robustness in reports."""

from __future__ import annotations

import csv
import io
import json
import math
import xml.etree.ElementTree as ET

import numpy as np
import pytest

from pytest_avscenario.monitors import (
    Monitor,
    MonitorError,
    MonitorResult,
    MonitorSet,
    Verdict,
    as_monitor,
    distance,
    lane_keeping,
    progress,
    rho_from_json,
    rho_from_str,
    rho_to_json,
    rho_to_str,
    ttc,
)
from pytest_avscenario.trajectory import Trajectory


def following(gap0=30.0):
    t = np.arange(11) * 1.0
    return Trajectory.from_arrays(t, {
        "ego": {"x": 10 * t, "y": 0 * t, "vx": 10.0, "vy": 0.0, "lane_offset": 0.1},
        "lead": {"x": gap0 + 8 * t, "y": 0 * t, "vx": 8.0, "vy": 0.0},
    })


# -- MonitorSet -------------------------------------------------------------------------------

def test_set_evaluates_every_member_into_a_verdict():
    ms = MonitorSet([distance(kind="centre"), ttc(kind="centre"), progress(), lane_keeping()])
    assert ms.names == ("distance", "ttc", "progress", "lane_keeping")
    v = ms.evaluate(following())
    assert isinstance(v, Verdict)
    # gap 30 - 2t -> 10 m at t=10 s: distance rho 5; TTC (gap - 5) / 2 -> (10-5)/2 = 2.5 s
    assert v.rho == pytest.approx({"distance": 5.0, "ttc": 0.5, "progress": 89.0,
                                   "lane_keeping": 0.4})
    assert v.ok and v.violated == []
    assert list(v.results) == list(ms.names)
    np.testing.assert_allclose(v.vector, [5.0, 0.5, 89.0, 0.4])


def test_any_violated_member_fails_the_verdict():
    v = MonitorSet([distance(kind="centre"), ttc(kind="centre"), progress(200.0)]).evaluate(following(gap0=12.0))
    assert not v.ok
    assert v.violated == ["distance", "ttc", "progress"]
    assert v.worst.name == "progress"


def test_priority_list_becomes_a_chain_of_edges():
    ms = MonitorSet([distance(kind="centre"), ttc(kind="centre"), progress(), lane_keeping()],
                    priority=["ttc", "distance", "lane_keeping"])
    assert ms.priority_edges == (("ttc", "distance"), ("distance", "lane_keeping"))
    # a topological order; unranked members slot in by member order
    assert ms.priority_order == ("ttc", "distance", "progress", "lane_keeping")
    assert ms.rank() == {"ttc": 0, "progress": 0, "distance": 1, "lane_keeping": 2}


def test_priority_dag_edges():
    ms = MonitorSet([distance(kind="centre"), ttc(kind="centre"), progress(), lane_keeping()],
                    priority=[("distance", "progress"), ("ttc", "progress"),
                              ("progress", "lane_keeping")])
    assert ms.priority_order == ("distance", "ttc", "progress", "lane_keeping")
    assert ms.rank()["lane_keeping"] == 2


@pytest.mark.parametrize("priority, match", [
    (["ttc", "speeding"], "'speeding'.*not in the set"),
    ([("ttc", "distance"), ("distance", "ttc")], "cycle.*'distance'"),
    ([("ttc", "ttc")], "'ttc' above itself"),
    (["ttc", "ttc"], "'ttc' more than once"),
    (["ttc", ("ttc", "distance")], "not a mix"),
    ("ttc", "list"),
])
def test_bad_priorities_name_the_monitor(priority, match):
    with pytest.raises(MonitorError, match=match):
        MonitorSet([distance(kind="centre"), ttc(kind="centre")], priority=priority)


def test_duplicate_names_are_rejected_with_a_fix():
    with pytest.raises(MonitorError, match="'distance'.*named"):
        MonitorSet([distance(5.0, kind="centre"), distance(2.0, kind="centre")])
    ms = MonitorSet([distance(5.0, kind="centre"), distance(2.0, kind="centre").named("distance_2m")])
    assert ms.names == ("distance", "distance_2m")


def test_nan_from_a_member_is_an_error_naming_it_never_a_pass():
    def flaky(traj):
        return float("nan")

    ms = MonitorSet([distance(kind="centre"), flaky])
    with pytest.raises(MonitorError, match="'flaky'.*NaN"):
        ms.evaluate(following())


def test_a_raising_user_monitor_is_a_monitor_error_naming_it():
    def broken(traj):
        raise ZeroDivisionError("oops")

    with pytest.raises(MonitorError, match="'broken' raised ZeroDivisionError") as info:
        MonitorSet([broken]).evaluate(following())
    assert isinstance(info.value.__cause__, ZeroDivisionError)


def test_nan_trajectory_in_a_builtin_metric_is_an_error_with_the_member_name():
    t = np.arange(3) * 1.0
    traj = Trajectory.from_arrays(t, {"ego": {"x": [0.0, np.nan, 2.0], "y": 0 * t},
                                      "lead": {"x": 20 + t, "y": 0 * t}})
    with pytest.raises(MonitorError, match="'distance'"):
        MonitorSet([distance(kind="centre")]).evaluate(traj)


# -- as_monitor ---------------------------------------------------------------------------------

def test_plain_function_is_a_monitor_named_after_it():
    def min_speed(traj):
        return float(np.min(traj.speed[0])) - 5.0

    m = as_monitor(min_speed)
    assert isinstance(m, Monitor) and m.name == "min_speed"
    r = m.evaluate(following())
    assert r.rho == pytest.approx(5.0) and r.name == "min_speed"
    assert as_monitor(lambda tr: 1.0, name="custom").name == "custom"


def test_as_monitor_passes_monitors_through():
    d = distance(kind="centre")
    assert as_monitor(d) is d


@pytest.mark.parametrize("obj, match", [
    (5.0, "got float"),
    ("distance", "got str"),
    (distance, r"factory.*distance\(\)"),
    (lambda a, b: 0.0, "one argument"),
    (MonitorResult, "class"),
])
def test_as_monitor_rejects_everything_else_clearly(obj, match):
    with pytest.raises(MonitorError, match=match):
        as_monitor(obj)
    assert issubclass(MonitorError, ValueError)


def test_function_returning_a_bool_is_rejected_at_evaluation():
    m = as_monitor(lambda tr: True, name="looks_ok")
    with pytest.raises(MonitorError, match="bool"):
        m.evaluate(following())


def test_evaluate_refuses_a_non_trajectory():
    with pytest.raises(MonitorError, match="Trajectory"):
        distance(kind="centre").evaluate({"x": [0.0]})


# -- ±inf in every report ---------------------------------------------------------------------

VALUES = [0.0, -0.0, 1.5, -2.25, 0.1 + 0.2, 1e-300, -1e300, math.inf, -math.inf]


@pytest.mark.parametrize("x", VALUES)
def test_rho_round_trips_through_json_exactly(x):
    text = json.dumps({"rho": rho_to_json(x)}, allow_nan=False)  # strict JSON, no Infinity
    back = rho_from_json(json.loads(text)["rho"])
    assert back == x and math.copysign(1, back) == math.copysign(1, x)


@pytest.mark.parametrize("x", VALUES)
def test_rho_round_trips_through_csv_and_junit_text(x):
    buf = io.StringIO()
    csv.writer(buf).writerow(["distance", rho_to_str(x)])
    row = next(csv.reader(io.StringIO(buf.getvalue())))
    assert rho_from_str(row[1]) == x
    prop = ET.Element("property", name="rho.ttc", value=rho_to_str(x))
    parsed = ET.fromstring(ET.tostring(prop))
    assert rho_from_str(parsed.get("value")) == x


def test_infinite_values_are_written_explicitly():
    assert rho_to_json(math.inf) == "inf" and rho_to_json(-math.inf) == "-inf"
    assert rho_to_str(math.inf) == "inf" and rho_to_str(-math.inf) == "-inf"
    assert math.isnan(rho_from_str("nan")) and rho_to_str(float("nan")) == "nan"
    with pytest.raises(ValueError, match="not a robustness"):
        rho_from_str("fast")


def test_verdict_json_round_trip_keeps_infinities():
    traj = Trajectory.from_arrays([0.0, 1.0], {
        "ego": {"x": [0, 20], "y": [0, 0], "lane_offset": 0.0},
        "lead": {"x": [50, 80], "y": [0, 0]},
    })
    v = MonitorSet([distance(kind="centre"), ttc(kind="centre"), progress()]).evaluate(traj)
    assert v.rho["ttc"] == math.inf
    text = json.dumps(v.to_json(), allow_nan=False)
    back = Verdict.from_json(json.loads(text))
    assert back.rho == v.rho and back.results["ttc"] == v.results["ttc"]


def test_builtin_monitors_pickle_for_worker_processes():
    import pickle

    from pytest_avscenario.monitors import collision, off_road, reaches, time_headway

    traj = following()
    for m in (distance(kind="centre"), ttc(kind="centre"), progress(), lane_keeping(), collision(), time_headway(),
              off_road(), reaches((50, 0), radius=2.0), MonitorSet([distance(kind="centre"), ttc(kind="centre")])):
        clone = pickle.loads(pickle.dumps(m))
        assert clone.evaluate(traj) == m.evaluate(traj)


@pytest.mark.parametrize("bad", ["", 5, None])
def test_monitor_names_must_be_non_empty_strings(bad):
    with pytest.raises(MonitorError, match="name"):
        distance(name=bad)
    with pytest.raises(MonitorError, match="name"):
        distance().named(bad)

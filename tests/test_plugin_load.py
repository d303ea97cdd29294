"""Loading the plugin is nearly free: a repository that has it installed but no scenario test
pays for a few small modules — no report module, no numpy, no campaign — in every pytest run
(bench/bench_load.py measures the time)."""

import json

import pytest

LISTER = """
import json, sys

def pytest_sessionfinish(session):
    with open("modules.json", "w") as fh:
        json.dump(sorted(m for m in sys.modules if m.startswith(("pytest_avscenario", "numpy"))), fh)
"""


def _loaded(pytester, *args):
    # a real process: this one has the whole package (and numpy) loaded already
    pytester.makeconftest(LISTER)
    result = pytester.runpytest_subprocess("-p", "no:cacheprovider", *args)
    return result, json.loads((pytester.path / "modules.json").read_text())


def test_a_run_without_scenario_tests_loads_no_report_module_and_no_numpy(pytester):
    pytester.makepyfile(test_plain="def test_x():\n    assert 1 + 1 == 2\n")
    result, loaded = _loaded(pytester)
    result.assert_outcomes(passed=1)
    assert "pytest_avscenario.pytest_plugin.hooks" in loaded  # the plugin was loaded ...
    assert [m for m in loaded if m.startswith("pytest_avscenario.report")] == []  # ... lightly
    assert [m for m in loaded if m == "numpy" or m.startswith("numpy.")] == []
    assert "pytest_avscenario.campaign.pipeline" not in loaded
    assert "pytest_avscenario.pytest_plugin.collect" not in loaded


def test_the_listing_sees_what_a_scenario_run_loads(pytester):
    # negative control: the same probe on a run with a scenario test lists the report and numpy
    pytester.makepyfile(test_gap="""
        from pytest_avscenario import scenario, Uniform
        from pytest_avscenario.monitors import distance
        from pytest_avscenario.trajectory import Trajectory

        @scenario(x=Uniform(0, 1), samples=2, monitors=[distance(5.0, kind="centre")])
        def test_gap(case):
            return Trajectory.from_arrays([0.0, 0.1], {"ego": {"x": [0.0, 0.0], "y": [0.0, 0.0]},
                                                       "lead": {"x": [50.0, 50.0], "y": [0.0, 0.0]}})
    """)
    result, loaded = _loaded(pytester, "--avs-db=none")
    result.assert_outcomes(passed=2)
    assert "numpy" in loaded and "pytest_avscenario.campaign.pipeline" in loaded
    assert any(m.startswith("pytest_avscenario.report") for m in loaded)


def test_the_public_names_still_import_from_the_package():
    # the package's names load on first use; what users import keeps working
    import pytest_avscenario
    from pytest_avscenario import Case, Choice, Uniform, example, scenario  # noqa: F401

    assert set(pytest_avscenario.__all__) <= set(dir(pytest_avscenario))
    with pytest.raises(AttributeError):
        pytest_avscenario.no_such_name  # noqa: B018

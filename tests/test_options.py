"""Settings: read once per session, each bad value a usage error naming the option and where
it came from (command line or ini), never an internal error later in the run."""

import pytest

SCENARIO = """
from pytest_avscenario import scenario, Uniform

@scenario(x=Uniform(0, 1), samples=2)
def test_s(case):
    pass
"""


@pytest.mark.parametrize("ini, args, message", [
    ("avs_dask_workers = two", [], "ini avs_dask_workers: dask_workers must be an integer, got 'two'"),
    ("avs_dask_timeout = -1", [], "ini avs_dask_timeout: dask_timeout must be a positive number of seconds*"),
    ("avs_gifs = many", [], "ini avs_gifs: gifs must be an integer, got 'many'"),
    ("avs_shrink_budget = -2", [], "ini avs_shrink_budget: shrink_budget must be >= 0, got -2"),
    ("avs_case_timeout = soon", [], "ini avs_case_timeout: case_timeout must be a positive number*'soon'"),
    ("avs_executor = ray", [], "ini avs_executor: unknown executor 'ray'; available: inprocess, dask"),
    ("", ["--avs-samples=abc"], "--avs-samples: samples must be an integer, got 'abc'"),
    ("", ["--avs-case-timeout=1e20"], "--avs-case-timeout: case_timeout must be at most 86400 s (a day), got '1e20'*"),
    ("", ["--avs-samples=0"], "--avs-samples: samples must be >= 1, got 0"),
    ("", ["--avs-sampler=halton,nope"], "--avs-sampler: unknown sampler 'nope'; available:*"),
    ("", ["--avs-driver=tesla"], "--avs-driver: unknown driver 'tesla'*"),
    ("", ["--avs-params=[1]"], "--avs-params must be a JSON object*"),
    ("avs_dask_retries = 1.5", ["--avs-dask-retries=x"], "--avs-dask-retries: dask_retries must be an integer, got 'x'"),
])
def test_a_bad_setting_is_a_usage_error_naming_option_and_source(pytester, ini, args, message):
    pytester.makepyfile(SCENARIO)
    if ini:
        pytester.makeini(f"[pytest]\n{ini}\n")
    result = pytester.runpytest("--avs-db=none", "--avs-report=none", *args)
    assert result.ret == pytest.ExitCode.USAGE_ERROR
    result.stderr.fnmatch_lines([f"ERROR: {message}"])
    assert "INTERNALERROR" not in result.stdout.str() + result.stderr.str()


def test_ini_values_are_defaults_the_marker_and_command_line_beat(pytester):
    pytester.makepyfile("""
from pytest_avscenario import scenario, Uniform

@scenario(x=Uniform(0, 1), shrink_budget=3)
def test_marker(case):
    pass

@scenario(x=Uniform(0, 1))
def test_plain(case):
    pass
""")
    pytester.makeini("[pytest]\navs_samples = 4\navs_shrink_budget = 7\n")
    result = pytester.runpytest("--avs-db=none", "--avs-report=none", "--collect-only", "-q")
    assert result.stdout.str().count("test_plain[halton-") == 4  # ini default
    result = pytester.runpytest("--avs-db=none", "--avs-report=none", "--collect-only", "-q",
                                "--avs-samples=2")
    assert result.stdout.str().count("test_marker[halton-") == 2  # the command line overrides


def test_a_bad_marker_value_names_the_test_and_the_marker(pytester):
    pytester.makepyfile("""
from pytest_avscenario import scenario, Uniform

@scenario(x=Uniform(0, 1), shrink_max=-1)
def test_bad(case):
    pass
""")
    result = pytester.runpytest("--avs-db=none", "--avs-report=none")
    result.stdout.fnmatch_lines(["*::test_bad: shrink_max must be >= 0, got -1 (from @scenario(shrink_max=...))*"])


def test_the_built_in_driver_names_are_the_simulators(pytester):
    from pytest_avscenario.pytest_plugin.options import BUILTIN_DRIVERS
    from pytest_avscenario.sim.drivers import BUILTIN

    assert BUILTIN_DRIVERS == BUILTIN
    pytester.makepyfile("""
from pytest_avscenario import scenario, Uniform

@scenario(gap=Uniform(30, 60), samples=2)
def test_follow(case, world):
    road = world.straight_road(lanes=1, length=300)
    world.ego(road.lane(0), s=20.0, speed=15.0)
    world.car(road.lane(0), s=20.0 + case.gap, speed=10.0)
    world.run(seconds=2)
""")
    pytester.runpytest("--avs-driver=careful", "--avs-db=none", "-p", "no:xdist").assert_outcomes(passed=2)


def test_pytest_help_lists_every_option(pytester):
    # argparse formats help texts with %: a literal one (rate:METRIC<=1%@95%) once made
    # `pytest --help` crash with the plugin installed
    from pytest_avscenario.pytest_plugin.options import OPTIONS

    result = pytester.runpytest("--help")
    assert result.ret == 0, result.stderr.str()
    text = result.stdout.str()
    assert all(f"--avs-{o.name}" in text for o in OPTIONS)
    assert "1%@95%" in text


STACK_MODULE = """
class MyStack:
    def act(self, observation):
        return (0.0, 0.0)

class Parts:
    pass

class NeedsModel:
    def __init__(self, model):
        self.model = model

    def act(self, observation):
        return (0.0, 0.0)

speed_limit = 30

def broken():
    pass
"""

FOLLOW = """
from pytest_avscenario import scenario, Uniform

@scenario(gap=Uniform(30, 60), samples=2)
def test_follow(case, world):
    road = world.straight_road(lanes=1, length=300)
    world.ego(road.lane(0), s=20.0, speed=15.0)
    world.car(road.lane(0), s=20.0 + case.gap, speed=10.0)
    world.run(seconds=1)
"""


@pytest.mark.parametrize("ini, args, message", [
    ("", ["--avs-driver=mystack:MyStak"],
     "--avs-driver: driver 'mystack:MyStak': 'mystack' has no attribute 'MyStak' (did you mean 'MyStack'?)"),
    ("avs_driver = mystak:MyStack", [],
     "ini avs_driver: driver 'mystak:MyStack': no module named 'mystak' (did you mean 'mystack'?); "
     "the module must be importable when pytest starts*"),
    ("", ["--avs-driver=mystack:Parts"],
     "--avs-driver: driver 'mystack:Parts': class Parts has no act(observation) or predict(observation) "
     "method and its objects are not callable, so it cannot drive"),
    ("", ["--avs-driver=mystack:NeedsModel"],
     "--avs-driver: driver 'mystack:NeedsModel': class NeedsModel is made without arguments, but its "
     "constructor needs some*"),
    ("", ["--avs-driver=mystack:speed_limit"],
     "--avs-driver: driver 'mystack:speed_limit': 'speed_limit' is of type int, not a driver*"),
    ("", ["--avs-driver=mystack:MyStack.act.nope"],
     "--avs-driver: driver 'mystack:MyStack.act.nope': 'mystack:MyStack.act' has no attribute 'nope'"),
])
def test_an_import_path_driver_is_imported_and_checked_at_start_up(pytester, ini, args, message):
    # a typo in --avs-driver used to error every case with a long traceback each
    pytester.makepyfile(mystack=STACK_MODULE, test_follow=FOLLOW)
    pytester.makeini(f"[pytest]\npythonpath = .\n{ini}\n")
    result = pytester.runpytest("--avs-db=none", "--avs-report=none", "-p", "no:xdist", *args)
    assert result.ret == pytest.ExitCode.USAGE_ERROR
    result.stderr.fnmatch_lines([f"ERROR: {message}"])
    assert len(result.stderr.str().strip().splitlines()) == 1  # one line, no traceback
    assert "test_follow" not in result.stdout.str()  # no case ran


def test_a_module_that_raises_on_import_is_one_line_naming_the_error(pytester):
    pytester.makepyfile(mystack="import numpy\nraise RuntimeError('no GPU found')\n", test_follow=FOLLOW)
    pytester.makeini("[pytest]\npythonpath = .\n")
    result = pytester.runpytest("--avs-db=none", "--avs-report=none", "--avs-driver=mystack:Stack")
    assert result.ret == pytest.ExitCode.USAGE_ERROR
    result.stderr.fnmatch_lines(["ERROR: --avs-driver: driver 'mystack:Stack': importing module 'mystack' "
                                 "failed: RuntimeError: no GPU found"])


@pytest.mark.parametrize("xdist", [[], ["-n", "2"]])
def test_an_import_path_driver_checked_at_start_up_still_drives_under_xdist(pytester, xdist):
    pytester.makepyfile(mystack=STACK_MODULE, test_follow=FOLLOW)
    pytester.makeini("[pytest]\npythonpath = .\n")
    result = pytester.runpytest_subprocess("--avs-db=none", "--avs-report=none", "--avs-driver=mystack:MyStack",
                                           *(xdist or ["-p", "no:xdist"]))
    result.assert_outcomes(passed=2)
    bad = pytester.runpytest_subprocess("--avs-db=none", "--avs-report=none", "--avs-driver=mystack:MyStak",
                                        *(xdist or ["-p", "no:xdist"]))
    assert bad.ret == pytest.ExitCode.USAGE_ERROR
    bad.stderr.fnmatch_lines(["ERROR: --avs-driver: driver 'mystack:MyStak': *did you mean 'MyStack'?)"])
    assert "Traceback" not in bad.stdout.str() + bad.stderr.str()

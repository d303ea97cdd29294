"""A failing test stays a failure on CPython < 3.13 when the garbage collector finalizes a
raising ``__del__`` while pytest parses the test's source to show the failure (the plugin's
:mod:`~pytest_avscenario.pytest_plugin.astguard`); without the plugin the same run is an
INTERNALERROR that loses the run's rows and report."""

import sys

import pytest

# An object that, each time the collector finalizes it, leaves a new one behind and raises:
# there is cyclic garbage at every collection, including one during pytest's parse of this
# long file when it formats the assertion's failure.
PHOENIX = """
import gc
LEFT = [400]

class Phoenix:
    def __init__(self):
        self.me = self

    def __del__(self):
        if LEFT[0] > 0:
            LEFT[0] -= 1
            Phoenix()
        raise ValueError("finalizer")


def test_fails():
    Phoenix()
    assert 1 == 2
""" + "\n".join(f"x{i} = [{i}, {i} + 1, ({i}, {i})]" for i in range(3000)) + "\n"


def test_a_failure_formatted_during_a_collection_stays_a_failure(pytester):
    pytester.makepyfile(test_gcparse=PHOENIX)
    result = pytester.runpytest_subprocess("-p", "no:cacheprovider", "-q")
    assert "SystemError" not in result.stdout.str() + result.stderr.str()
    assert result.ret == pytest.ExitCode.TESTS_FAILED
    result.stdout.fnmatch_lines(["*1 failed*"])


@pytest.mark.skipif(sys.version_info >= (3, 13), reason="CPython 3.13 keeps the depth per parse")
def test_without_the_guard_the_same_run_is_an_internal_error(pytester):
    """The negative control: the file above does reach the interpreter's fault."""
    pytester.makepyfile(test_gcparse=PHOENIX)
    result = pytester.runpytest_subprocess("-p", "no:cacheprovider", "-p", "no:avscenario", "-q")
    assert "AST constructor recursion depth mismatch" in result.stdout.str() + result.stderr.str()
    assert result.ret == pytest.ExitCode.INTERNAL_ERROR

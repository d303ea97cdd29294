"""The README's promises that CI and new users depend on."""

from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def _commands() -> list[str]:
    lines = (ROOT / "README.md").read_text().splitlines()
    return [l.strip() for l in lines[:16] if l.startswith("    ")]


def test_readme_opens_with_the_two_commands():
    cmds = _commands()
    assert len(cmds) == 2
    assert "example_tests" in cmds[0] and cmds[0].startswith("pip install")
    assert cmds[1].startswith('pip install -e ".[test]"') and "pytest tests" in cmds[1]


def test_ci_runs_exactly_the_readme_test_command():
    test_cmd = _commands()[1].split("&&", 1)[1].strip()
    ci = [l.strip() for l in (ROOT / ".ci" / "run").read_text().splitlines()
          if l.strip() and not l.strip().startswith("#")]
    pytest_lines = [l for l in ci if l.startswith("pytest")]
    # the README's command first, exactly; then only the marked slow set
    assert pytest_lines[0] == test_cmd
    assert all(l == f"{test_cmd} -m slow" for l in pytest_lines[1:])


def _snippet(after: str) -> str:
    """The first ```python block after the line containing ``after``, dedented."""
    import textwrap

    text = (ROOT / "README.md").read_text()
    start = text.index("```python", text.index(after)) + len("```python")
    return textwrap.dedent(text[start:text.index("```", start)])


def test_the_pedestrian_at_a_crosswalk_snippet_runs(pytester):
    # the README's example of a pedestrian crossing must stay runnable as written
    header = ("from pytest_avscenario import Uniform, scenario\n"
              "from pytest_avscenario.monitors import collision, distance\n"
              "from pytest_avscenario.sim import behaviors as b\n")
    pytester.makepyfile(test_snippet=header + _snippet("A pedestrian at a crosswalk"))
    result = pytester.runpytest("--avs-samples=2", "--avs-db=none", "--avs-report=none",
                                "--avs-shrink-budget=0", "-p", "no:xdist")
    outcomes = result.parseoutcomes()
    assert outcomes.get("errors", 0) == 0, result.stdout.str()
    assert outcomes.get("passed", 0) + outcomes.get("failed", 0) == 2


def test_the_options_table_lists_every_option():
    from pytest_avscenario.pytest_plugin.options import OPTIONS

    table = (ROOT / "README.md").read_text().split("## Options", 1)[1].split("\n## ", 1)[0]
    missing = [o.name for o in OPTIONS if f"`--avs-{o.name}" not in table]
    assert missing == []


def test_the_complete_examples_nominal_case_passes_with_the_autopilot():
    """A new user's first run: the README's complete example, at its nominal parameters and
    driven by the built-in autopilot, violates nothing (its failures are the sampled corners)."""
    from pytest_avscenario import Case
    from pytest_avscenario.monitors import MonitorSet
    from pytest_avscenario.sim import World
    from pytest_avscenario.space import FeatureSpace

    ns: dict = {}
    exec(compile(_snippet("## A complete example"), "README.md", "exec"), ns)
    fn = ns["test_vehicle_following"]
    (spec,) = [m.args[0] for m in fn.pytestmark if m.name == "scenario"]
    params = FeatureSpace(spec.parameters).nominal()
    for seed in (0, 1):
        case = Case(params, index=0, seed=seed, sampler="nominal", test=fn.__name__)
        world = World(seed=case.seed, rng=case.rng, driver="autopilot", name=fn.__name__)
        fn(case=case, world=world)
        verdict = MonitorSet(list(spec.monitors)).evaluate(world.trajectory)
        assert verdict.ok, (seed, params, verdict.rho)
        assert {"collision", "distance", "ttc"} <= set(verdict.rho)

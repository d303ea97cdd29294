"""Guard: the nominal case of every example scenario passes against the built-in autopilot.

Not a scenario test (``-m scenario`` skips it): it runs the nominal parameters of every
``@scenario`` test in this folder for three behaviour seeds outside the sampler and checks
every declared monitor, so a change to the autopilot, the simulator or a default metric that
breaks an ordinary situation shows up as one plain failure naming the scenario and the
metric. The only exceptions are the ones example_tests/README.md lists, with the reason,
between its ``nominal-exemptions`` markers (read here, so the README and the test cannot
disagree); a listed monitor that passes after all is a failure too, so the list stays true.
"""

import importlib
import math
import pathlib
import re

import pytest

from scout import run_one, scenario_tests

HERE = pathlib.Path(__file__).parent
MODULES = sorted(p.stem for p in HERE.glob("test_*.py")
                 if p.stem != "test_nominal_cases" and "@scenario(" in p.read_text())


def exemptions(readme: pathlib.Path = HERE / "README.md") -> dict[str, dict[str, str]]:
    """``{module: {monitor or "*": reason}}`` from the README's exemption table
    (``| module | monitors | why |``, monitors comma-separated, ``*`` for the whole module)."""
    text = readme.read_text()
    m = re.search(r"<!-- nominal-exemptions:start -->(.*?)<!-- nominal-exemptions:end -->", text, re.S)
    assert m, "example_tests/README.md has no nominal-exemptions table"
    out: dict[str, dict[str, str]] = {}
    for line in m.group(1).splitlines():
        cells = [c.strip().strip("`") for c in line.strip().strip("|").split("|")]
        if len(cells) != 3 or not cells[0].startswith("test_"):
            continue
        module, monitors, why = cells
        assert module in MODULES, f"README exempts {module!r}, which is no example module"
        out.setdefault(module, {}).update({n.strip().strip("`"): why for n in monitors.split(",")})
    return out


EXEMPT = exemptions()


def test_the_exemptions_give_a_reason():
    assert all(why for per in EXEMPT.values() for why in per.values())


@pytest.mark.parametrize("seed", [0, 1, 2])
@pytest.mark.parametrize("module", MODULES)
def test_nominal_case_passes(module, seed):
    from pytest_avscenario.space import FeatureSpace

    exempt = EXEMPT.get(module, {})
    if "*" in exempt:
        pytest.skip(f"{module}: {exempt['*']} (example_tests/README.md)")
    tests = scenario_tests(importlib.import_module(module))
    assert tests, f"{module} has no @scenario test"
    for name, fn, spec in tests:
        params = FeatureSpace(spec.parameters).nominal()
        verdict, _, error, _ = run_one(fn, spec, params, seed, "autopilot")
        assert error is None, f"{module}::{name}: {error}"
        assert all(not math.isnan(r) for r in verdict.rho.values())
        bad = {m: rho for m, rho in verdict.rho.items() if rho < 0 and m not in exempt}
        assert not bad, (f"{module}::{name} nominal case (seed {seed}) violates "
                         + ", ".join(f"{m} (rho={r:+.3f})" for m, r in bad.items())
                         + f"; parameters {params}")
        if seed == 0:  # an exemption that no longer applies is stale
            stale = [m for m in exempt if m in verdict.rho and verdict.rho[m] >= 0]
            assert not stale, (f"{module}::{name}: example_tests/README.md exempts {stale} from "
                               "the nominal check, but the nominal case passes them: drop the row")

"""The plugin's hookspecs (pytest_plugin/newhooks.py): a conftest.py implementing each one
changes what the run does — the cases drawn, where rows go, what a card shows, which
campaigns are rejected — and each hook runs where its docs say under pytest-xdist."""

import json

import pytest

# The other car stands 20·x m ahead and 3 m to the side: `distance` (5 m between centres) is
# violated for x < 0.2; the cars never touch, so `collision` always holds.
SCENARIO = """
from pytest_avscenario import scenario, Uniform
from pytest_avscenario.monitors import collision, distance
from pytest_avscenario.trajectory import Trajectory

@scenario(x=Uniform(0, 1), samples=8, sampler="halton", monitors=[distance(5.0, kind="centre"), collision()]{accept})
def test_gap(case):
    gap = 20 * case.x
    return Trajectory.from_arrays([0.0, 0.1], {{
        "ego": {{"x": [0.0, 0.0], "y": [0.0, 0.0]}},
        "lead": {{"x": [gap, gap], "y": [3.0, 3.0]}},
    }})
"""

ARGS = ("--avs-db=none", "--avs-seed=1", "--avs-shrink-budget=0", "-p", "no:cacheprovider")


def _scenario(pytester, accept=""):
    pytester.makepyfile(test_gap=SCENARIO.format(accept=f", accept={accept}" if accept else ""))


def test_make_sampler_replaces_how_a_named_sampler_is_made(pytester):
    _scenario(pytester)
    plain = pytester.runpytest(*ARGS)
    assert plain.parseoutcomes()["failed"] < 8  # Halton spreads the cases: most keep the gap
    pytester.makeconftest("""
        import json
        import numpy as np
        from pytest_avscenario.samplers import Sampler

        class Corner(Sampler):
            name = "halton"
            def ask_unit(self):
                return np.zeros(self.d)  # every case at the space's lower corner

        def pytest_avscenario_make_sampler(config, name, space, seed, options):
            with open("made.jsonl", "a") as fh:
                fh.write(json.dumps({"name": name, "params": list(space.parameters), "seed": seed}) + "\\n")
            return Corner(space, seed=seed) if name == "halton" else None
    """)
    hooked = pytester.runpytest(*ARGS)
    assert hooked.parseoutcomes()["failed"] == 8  # x = 0 for every case: all too close
    made = [json.loads(line) for line in (pytester.path / "made.jsonl").read_text().splitlines()]
    assert {m["name"] for m in made} == {"halton"} and made[0]["params"] == ["x"]
    assert isinstance(made[0]["seed"], int)


SINK = """
    import json, os

    def pytest_avscenario_case_finished(config, row):
        with open("rows.jsonl", "a") as fh:
            fh.write(json.dumps({"item": row.item, "verdict": row.verdict, "origin": row.origin,
                                 "where": os.environ.get("PYTEST_XDIST_WORKER", "controller")}) + "\\n")
"""


def _sunk(pytester):
    return [json.loads(line) for line in (pytester.path / "rows.jsonl").read_text().splitlines()]


def test_case_finished_gets_every_case_row(pytester):
    _scenario(pytester)
    pytester.makeconftest(SINK)
    result = pytester.runpytest(*ARGS)
    outcomes = result.parseoutcomes()
    rows = _sunk(pytester)
    assert sorted(r["item"] for r in rows) == [f"test_gap.py::test_gap[halton-{k:03d}]" for k in range(8)]
    assert sum(r["verdict"] == "fail" for r in rows) == outcomes["failed"]
    assert sum(r["verdict"] == "pass" for r in rows) == outcomes["passed"]


def test_case_finished_runs_on_the_xdist_controller(pytester, monkeypatch):
    pytest.importorskip("xdist")
    # the inner run's controller must not inherit this suite's own xdist worker name
    monkeypatch.delenv("PYTEST_XDIST_WORKER", raising=False)
    _scenario(pytester)
    pytester.makeconftest(SINK)
    result = pytester.runpytest_subprocess(*ARGS, "-n", "2")
    assert result.ret == pytest.ExitCode.TESTS_FAILED
    rows = _sunk(pytester)
    assert len(rows) == 8 and {r["where"] for r in rows} == {"controller"}


def test_case_finished_that_raises_costs_a_warning_not_the_rows(pytester):
    _scenario(pytester)
    pytester.makeconftest("""
        def pytest_avscenario_case_finished(config, row):
            raise RuntimeError("sink down")
    """)
    result = pytester.runpytest(*ARGS)
    assert "sink down" in result.stdout.str()
    assert len((pytester.path / "avs-report" / "errors.jsonl").read_text().splitlines()) == 8


def test_card_sections_appear_on_every_counterexample_card(pytester):
    _scenario(pytester)
    pytester.makeconftest("""
        import html

        def pytest_avscenario_card_sections(config, row):
            return [("Triage <ticket>", f"<p class='ticket'>AV-{html.escape(row.item)}</p>")]
    """)
    result = pytester.runpytest(*ARGS)
    failed = result.parseoutcomes()["failed"]
    cards = sorted((pytester.path / "avs-report" / "cases").glob("*.html"))
    assert len(cards) == failed >= 1
    for card in cards:
        page = card.read_text()
        assert "<h2>Triage &lt;ticket&gt;</h2>" in page  # the title is escaped
        assert "<p class='ticket'>AV-test_gap.py::test_gap[halton-" in page  # the HTML as given
        assert page.index("Triage") > page.index("Drawn during the run")  # after the card's own


def test_campaign_verdict_adds_a_teams_own_criterion(pytester):
    # the declared criterion accepts distance violations (only collisions reject) ...
    _scenario(pytester, accept='["collision"]')
    accepted = pytester.runpytest(*ARGS)
    assert accepted.ret == pytest.ExitCode.OK
    # ... the team's own rejects a campaign with more than one of them
    pytester.makeconftest("""
        def pytest_avscenario_campaign_verdict(config, test, sampler, rows):
            n = sum(1 for r in rows if (r.rho.get("distance") or 0) < 0)
            return [f"{n} cases closer than 5 m (team limit: 1)"] if n > 1 else []
    """)
    rejected = pytester.runpytest(*ARGS)
    assert rejected.ret == pytest.ExitCode.TESTS_FAILED
    rejected.stdout.fnmatch_lines(["REJECTED test_gap [[]halton]: * cases closer than 5 m (team limit: 1)*"])
    (campaign,) = json.loads((pytester.path / "avs-report" / "summary.json").read_text())["tests"]
    assert campaign["verdict"] == "rejected"
    assert any("team limit" in r for r in campaign["reasons"])

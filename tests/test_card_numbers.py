"""One set of numbers per counterexample: the card's metric table, its replay, the terminal's
failure text, errors.jsonl and JUnit describe the same cases with the same values, and where
two cases are involved (the case as found and its minimized case) every number says which.

The scene: a lead brakes to a stop ahead of the ego; a TTC under 2 s. The case as found
(a short gap, early braking) violates it earlier and deeper than its minimized case (the
nominal gap and braking moment), so each number can only match its own case.
"""

from __future__ import annotations

import html
import json
import re
from pathlib import Path

import pytest

from pytest_avscenario.codec import fmt_rho

BRAKING_LEAD = """
from pytest_avscenario import scenario, Uniform
from pytest_avscenario.monitors import collision, ttc
from pytest_avscenario.sim import behaviors as b


@scenario(gap=Uniform(6.0, 40.0, nominal=35.0, unit="m"),
          brake_at=Uniform(0.0, 3.0, nominal=3.0, unit="s"),
          samples=1, monitors=[collision(), ttc(2.0)])
def test_follow(case, world):
    road = world.straight_road(lanes=1, length=400)
    world.ego(road.lane(0), s=20.0, speed=14.0)
    world.car(road.lane(0), s=20.0 + case.gap, speed=12.0, name="lead",
              behavior=b.speed_profile([(case.brake_at, 12.0), (case.brake_at + 2.0, 0.0)],
                                       max_decel=8.0))
    world.run(seconds=6)
"""

ARGS = ("--avs-seed=0", "--avs-db=none", "--avs-shrink-budget=4", "--avs-reference-driver=none",
        "--avs-export=none", "-p", "no:xdist", "-p", "no:cacheprovider", "--junitxml=out.xml")


def _text(page: str) -> str:
    page = re.sub(r"<script.*?</script>|<style.*?</style>", "", page, flags=re.S)
    return html.unescape(re.sub(r"\s+", " ", re.sub(r"<[^>]+>", " ", page)))


@pytest.fixture
def run(pytester):
    pytester.makepyfile(test_follow=BRAKING_LEAD)
    result = pytester.runpytest(*ARGS)
    result.assert_outcomes(failed=1)
    report = pytester.path / "avs-report"
    row = next(r for r in map(json.loads, (report / "errors.jsonl").read_text().splitlines())
               if r["origin"] == "sampled")
    card = next((report / "cases").glob("*.html")).read_text()
    return result.stdout.str(), row, card, (pytester.path / "out.xml").read_text()


def test_found_and_minimized_numbers_agree_everywhere_and_say_which_case(run):
    out, row, card, junit = run
    found_t = row["violations"]["ttc"]["t"]
    small_t = row["minimized_violations"]["ttc"]["t"]
    found_rho, small_rho = row["rho"]["ttc"], row["minimized_rho"]["ttc"]
    # the scene does what the test needs: two cases, different when and how much
    assert row["minimized"] == {"gap": 35.0, "brake_at": 3.0} != row["params"]
    assert found_t < small_t and found_rho != small_rho < 0

    # the card's table: a group per case, each with its own ρ and first violation
    text = _text(card)
    assert "case as found" in text and "minimized case" in text
    metric_row = re.search(r"<tr><td>ttc</td>(.*?)</tr>", card).group(1)
    cells = [_text(c).strip() for c in re.findall(r"<td[^>]*>(.*?)</td>", metric_row)]
    # threshold | as found: ρ, first, agent | minimized: ρ, first, agent
    assert cells[0] == "2"
    assert cells[1] == fmt_rho(found_rho) and cells[2].split()[0] == f"{found_t:.2f}"
    assert cells[4] == fmt_rho(small_rho) and cells[5].split()[0] == f"{small_t:.2f}"
    assert f"first at t = {found_t:.2f} s with lead (case as found; minimized case first at t = {small_t:.2f} s)" in text

    # the replay plays the minimized case and says so beside its numbers
    data = json.loads(re.search(r"id='replay-data'>(.*?)</script>", card, re.S).group(1))
    assert data["case"] == "minimized" and data["title"] == "test_follow[halton-000], minimized case"
    (shown,) = data["violations"]
    assert shown["t"] == pytest.approx(small_t) and shown["rho"] == round(small_rho, 3)
    assert "first violation of the minimized case" in card

    # the terminal: the same two sets of numbers, each labelled
    line = next(l for l in out.splitlines() if l.startswith("  ttc: rho "))
    assert line.startswith(f"  ttc: rho {fmt_rho(found_rho)}, threshold 2 — min TTC")
    assert line.endswith(f"; first violated at t={found_t:.2f} s (as found)")
    assert f"minimized case: ttc rho {fmt_rho(small_rho)}, first violated at t={small_t:.2f} s" in out
    assert re.search(r"\n  parameters: gap=[0-9.]+, brake_at=[0-9.]+ \(as found\)\n", out)

    # JUnit keeps both as well
    assert f'name="avs.minimized_rho.ttc" value="{small_rho!r}"' in junit
    assert f'name="avs.rho.ttc" value="{found_rho!r}"' in junit

    # the monitor's text names its worst value's moment ("min TTC ... at t=..."): later than
    # the first violation here, and the card gives both, as the terminal does
    where = row["violations"]["ttc"]
    worst = re.search(r"min TTC .*? at t=([0-9.]+) s", out).group(1)
    assert float(worst) == pytest.approx(where["worst_t"]) and where["worst_t"] > where["t"]
    assert f"worst at {where['worst_t']:.2f}" in _text(card)


def _row(**extra):
    from pytest_avscenario.outcome import CaseRow

    return CaseRow(test="t.py::test_follow", item="t.py::test_follow[halton-003]", sampler="halton",
                   index=3, seed=7, origin="sampled", params={"gap": 12.0}, verdict="fail",
                   rho={"collision": 1.5, "ttc": -0.75},
                   violations={"ttc": {"t": 0.0, "agent": "lead", "threshold": 2.0, "worst_t": 1.1}},
                   **extra)


def test_a_card_without_a_minimized_case_has_one_group_and_the_worst_moment():
    from pytest_avscenario.report.cards import render_card

    card = render_card(Path("."), _row(), metrics=("collision", "ttc"))
    assert "class='group'>case as found</th>" in card and "minimized case" not in card
    # the terminal's detail names the worst moment (1.10 s), the card's column the first
    # violation (0.00 s): the card gives both, each named
    assert "<td class='num'>0.00<br><span class='meta'>worst at 1.10</span></td>" in card
    assert "first at t = 0.00 s with lead</p>" in card  # no "(case as found)" with one case


def test_a_card_with_a_minimized_case_gives_each_case_its_own_numbers():
    from pytest_avscenario.report.cards import render_card

    row = _row(minimized={"gap": 30.0}, shrink_sims=4, minimized_rho={"collision": 9.0, "ttc": -0.25},
               minimized_violations={"ttc": {"t": 4.2, "agent": "lead", "threshold": 2.0, "worst_t": 4.2}})
    card = render_card(Path("."), row, metrics=("collision", "ttc"))
    head = re.search(r"<thead>(.*?)</thead>", card, re.S).group(1)
    assert "<th colspan='3' class='group'>case as found</th>" in head
    assert "<th colspan='3' class='group'>minimized case</th>" in head
    ttc_row = re.search(r"<tr><td>ttc</td>(.*?)</tr>", card).group(1)
    cells = [_text(c).strip() for c in re.findall(r"<td[^>]*>(.*?)</td>", ttc_row)]
    assert cells == ["2", "-0.750", "0.00 worst at 1.10", "lead", "-0.250", "4.20", "lead"]
    collision_row = re.search(r"<tr><td>collision</td>(.*?)</tr>", card).group(1)
    assert [_text(c).strip() for c in re.findall(r"<td[^>]*>(.*?)</td>", collision_row)] == \
        ["—", "+1.500", "—", "—", "+9.000", "—", "—"]
    assert "(case as found; minimized case first at t = 4.20 s)" in card
    # errors.jsonl keeps the minimized case's ρ beside the found one's, and reads it back
    from pytest_avscenario.outcome import CaseRow

    data = json.loads(json.dumps(row.to_json()))
    assert data["minimized_rho"] == {"collision": 9.0, "ttc": -0.25} and data["rho"]["ttc"] == -0.75
    assert CaseRow.from_json(data).minimized_rho == {"collision": 9.0, "ttc": -0.25}


def test_the_replay_of_a_minimized_case_says_so_beside_its_numbers(tmp_path):
    import shutil

    from pytest_avscenario.report.recording import recording_data
    from pytest_avscenario.sim import World
    from pytest_avscenario.sim.clip import decoded, dumps, frame_lines

    w = World(seed=1, driver=lambda obs: (0.0, 0.0), name="crash")
    road = w.straight_road(lanes=1, length=200)
    w.ego(road.lane(0), s=10.0, speed=15.0)
    w.car(road.lane(0), s=61.0, speed=0.0, name="stopped")
    w.run(4.0)
    violations = {"collision": {"t": 3.1, "agent": "stopped", "threshold": 0.0, "rho": -0.4321}}
    data = recording_data(w, violations=violations, case="minimized")
    plain = decoded(json.loads(dumps(data)))
    line = frame_lines(plain, plain["first"])[-1]
    # ρ as the card and the terminal print it (fmt_rho: three decimals), and which case it is
    assert line.endswith("run ρ -0.432, first at 3.10 s (minimized case)"), line
    unlabelled = decoded(json.loads(dumps(recording_data(w, violations=violations))))
    assert frame_lines(unlabelled, unlabelled["first"])[-1].endswith("first at 3.10 s")
    if shutil.which("chromium") is None:
        pytest.skip("chromium is not installed: the player's own lines are not checked")
    from test_report_cards import _dom, _replay_page

    dom = _dom(_replay_page(tmp_path, data, "minimized"))
    shown = html.unescape(re.search(r'<pre class="values">(.*?)</pre>', dom, re.S).group(1))
    assert shown.splitlines() == frame_lines(plain, plain["first"])[1:]
    assert "first violation of the minimized case" in dom

"""Issue #17 item 1: a page per counterexample an engineer can act on.

Each failing case gets a card under ``cases/``: the violated metrics with ρ, threshold, the
time of the first violation and the agent involved; the parameters found / minimized /
nominal with the units the declaration gives; the values drawn from ``case.rng``; the
``@example`` line with its import and the exact re-run command; the pictures. The index
stays short: a table per test linking to the cards. Checked through pytest itself, and in
headless Chromium (skipped with a reason when it is absent; ``.ci/run`` installs it).
"""

from __future__ import annotations

import html
import json
import re
import shlex
import shutil
import subprocess
import sys
import tempfile

import numpy as np
import pytest

CUT_IN = """
from pytest_avscenario import scenario, Uniform, Choice
from pytest_avscenario.monitors import distance

@scenario(gap=Uniform(3, 30, nominal=25, unit="m"), weather=Choice(["dry", "rain"]),
          samples=6, monitors=[distance(8.0, kind="centre")])
def test_gap(case, world):
    jitter = float(case.rng.uniform(-0.5, 0.5))  # drawn during the run: on the card
    road = world.straight_road(lanes=1, length=300)
    world.ego(road.lane(0), s=20.0, speed=10.0)
    world.car(road.lane(0), s=20.0 + case.gap + jitter, speed=10.0, name="lead")
    world.run(seconds=1)
"""


def _cards(report):
    return sorted((report / "cases").glob("*.html"))


@pytest.fixture(scope="module")
def campaign(tmp_path_factory):
    """One campaign with failures (gap < 8 m), run once for the checks below."""
    root = tmp_path_factory.mktemp("cards")
    (root / "test_cut.py").write_text(CUT_IN)
    proc = subprocess.run(
        [sys.executable, "-m", "pytest", "test_cut.py", "--avs-seed=3", "--avs-db=none",
         "--avs-shrink-budget=8", "-p", "no:cacheprovider", "-p", "no:xdist", "-p", "no:randomly"],
        cwd=root, capture_output=True, text=True, timeout=300)
    rows = [json.loads(line) for line in (root / "avs-report" / "errors.jsonl").read_text().splitlines()]
    return root, proc, rows


def test_every_counterexample_has_a_card_linked_from_the_index(campaign):
    root, proc, rows = campaign
    report = root / "avs-report"
    failing = [r for r in rows if r["verdict"] == "fail"]
    assert failing, proc.stdout
    cards = _cards(report)
    assert len(cards) == len(failing)
    index = (report / "index.html").read_text()
    for card in cards:
        assert f"cases/{card.name}" in index
    # the index lists them in a collapsed table, not as a wall of pictures
    assert re.search(rf"<summary>{len(failing)} counterexamples?", index)
    assert "<dl class='legend'" in index and "ε-coverage" in index


def test_a_card_shows_what_failed_where_and_how_to_see_it_again(campaign):
    root, proc, rows = campaign
    row = next(r for r in rows if r["verdict"] == "fail" and r.get("minimized"))
    name = row["item"].partition("[")[2].rstrip("]")
    card = next(c for c in _cards(root / "avs-report") if c.name.endswith(f".{name}.html"))
    page = card.read_text()
    # the metric, its ρ and threshold, when it was first violated and with whom
    where = row["violations"]["distance"]
    assert where["agent"] == "lead" and where["threshold"] == 8.0
    # (the first violation's time, then its worst moment's when that came later)
    assert re.search(rf">{where['t']:.2f}(</td>|<br><span class='meta'>worst at)", page) and ">lead</td>" in page
    assert f"{row['rho']['distance']:+.3f}" in page
    # parameters found, minimized and nominal, with the declared unit
    assert "<td>gap</td><td>m</td>" in page
    assert f"{row['params']['gap']:.6g}" in page and f"{row['minimized']['gap']:.6g}" in page
    assert "<td class='num'>25</td>" in page  # the nominal gap
    # what the run drew from case.rng, with its value
    drawn = row["drawn"]
    assert drawn["count"] == 1 and drawn["draws"][0]["call"] == "uniform(-0.5, 0.5)"
    assert "uniform(-0.5, 0.5)" in page and f"{drawn['draws'][0]['value']:.6g}" in page
    # the line to pin it (with its import) and the exact command to re-run it
    assert "from pytest_avscenario import example" in page
    assert "@example(gap=" in page
    assert f"pytest &#x27;{row['item']}&#x27; --avs-seed=3" in page
    # a minimized counterexample's pictures: its time series and its first violation
    for kind in ("timeseries", "moment"):
        link = re.search(rf"src='([^']*\.{kind}\.png)'", page)
        assert link and (card.parent / link.group(1)).is_file(), kind
    # the terminal says what was drawn too
    assert "drawn from case.rng (1): uniform(-0.5, 0.5) -> " in proc.stdout


def test_the_rerun_command_on_a_card_re_runs_that_case(campaign):
    root, _, rows = campaign
    row = next(r for r in rows if r["verdict"] == "fail")
    card = next(c for c in _cards(root / "avs-report") if c.name.endswith(f".{row['item'].partition('[')[2][:-1]}.html"))
    command = re.search(r"<pre class='rerun'>([^<]*)</pre>", card.read_text()).group(1)
    args = shlex.split(html.unescape(command))
    assert args[0] == "pytest"
    proc = subprocess.run([sys.executable, "-m", "pytest", *args[1:], "--avs-db=none",
                           "--avs-shrink-budget=0", "-p", "no:cacheprovider", "-p", "no:xdist"],
                          cwd=root, capture_output=True, text=True, timeout=300)
    assert "1 failed" in proc.stdout, proc.stdout
    again = [json.loads(line) for line in (root / "avs-report" / "rerun" / "errors.jsonl").read_text().splitlines()]
    assert [(r["item"], r["params"], r["rho"]) for r in again] == [(row["item"], row["params"], row["rho"])]


def _chromium() -> str:
    for name in ("chromium", "chromium-browser", "google-chrome"):
        if shutil.which(name):
            return shutil.which(name)
    pytest.skip("Chromium is not installed (Debian: the chromium package), so the browser "
                "checks of the HTML report cannot run; .ci/run installs it")


def _dom(url: str) -> str:
    with tempfile.TemporaryDirectory() as profile:
        cmd = [_chromium(), "--headless", "--no-sandbox", "--disable-gpu", "--hide-scrollbars",
               "--disable-quic", "--no-first-run", "--disable-background-networking",
               "--disable-component-update", "--disable-sync", f"--user-data-dir={profile}",
               "--virtual-time-budget=5000", "--dump-dom", url]
        return subprocess.run(cmd, capture_output=True, text=True, timeout=90).stdout


def test_a_card_renders_in_chromium_without_script_errors(campaign):
    root, _, rows = campaign
    card = _cards(root / "avs-report")[0]
    dom = _dom(card.resolve().as_uri())
    assert 'data-loaded="yes"' in dom and 'data-script-errors="0"' in dom, dom[:400]
    params = re.search(r"<table class=\"params\">.*?</table>", dom, re.S).group(0)
    assert "<td>gap</td>" in params and "<td>weather</td>" in params
    index = _dom((root / "avs-report" / "index.html").resolve().as_uri())
    assert 'id="summary"' in index and "pictures loaded" in index


# --------------------------------------------------------------------------- the replay

def _replay(page: str):
    found = re.search(r"<script type='application/json' id='replay-data'>(.*?)</script>", page, re.S)
    return json.loads(found.group(1)) if found else None


def test_a_card_replays_its_case_from_the_first_violation(campaign):
    root, _, rows = campaign
    report = root / "avs-report"
    row = next(r for r in rows if r["verdict"] == "fail")
    card = next(c for c in _cards(report) if c.name.endswith(f".{row['item'].partition('[')[2][:-1]}.html"))
    page = card.read_text()
    data = _replay(page)
    # the slider, the canvas and the data inline; the player is the report's own shared file
    # beside the card: it works offline, with nothing from the network
    assert data is not None and "<input type='range'" in page and "<canvas" in page
    assert re.findall(r"<script[^>]+src='([^']+)'", page) == [next((report / "cases").glob("replay-*.js")).name]
    assert not re.search(r"https?://", page)
    # the recording came as cases/*.replay.json; the card holds the report's only copy
    assert list((report / "cases").glob("*.replay.json")) == []
    assert [a["name"] for a in data["agents"]] == ["ego", "lead"] and data["critical"] == "lead"
    assert data["first_kind"] == "violation" and data["violations"][0]["metric"] == "distance"


def test_the_replay_runs_in_chromium_and_redraws_at_the_chosen_time(campaign):
    root, _, rows = campaign
    card = _cards(root / "avs-report")[0]
    data = _replay(card.read_text())
    dom = _dom(card.resolve().as_uri())
    assert 'data-script-errors="0"' in dom and 'data-loaded="yes"' in dom, dom[:400]
    section = re.search(r'<section class="replay"[^>]*>', dom).group(0)
    # drawn once, at the first violation
    assert 'data-draws="1"' in section and f'data-frame="{data["first"]}"' in section
    assert f'data-t="{data["first_t"]:.2f}"' in section
    assert re.search(r"<pre class=\"values\">lead: distance [0-9.]+ m", dom)
    # moving the slider (here through the address, which sets it and fires its input event)
    later = _dom(card.resolve().as_uri() + "#t=0.8")
    section = re.search(r'<section class="replay"[^>]*>', later).group(0)
    assert 'data-t="0.80"' in section and 'data-script-errors="0"' in later
    assert "<output>t = 0.80 s</output>" in later


def _replay_page(tmp_path, data, name: str) -> str:
    from pytest_avscenario.report.player import player_html

    page = tmp_path / f"{name}.html"
    page.write_text("<!DOCTYPE html><html><head><meta charset='utf-8'>"
                    "<script>window.onerror = function (m) { document.documentElement.setAttribute('data-error', m); }"
                    f"</script></head><body>{player_html(data)}</body></html>")
    return page.resolve().as_uri()


def test_the_replay_writes_the_egos_decision_in_force_as_the_still_does(tmp_path):
    from test_replay import decided_world

    from pytest_avscenario.report.recording import recording_data
    from pytest_avscenario.sim.clip import decoded, dumps, frame_lines

    data = recording_data(decided_world(), fallback_t=4.6)
    plain = decoded(json.loads(dumps(data)))
    for t in (0.0, 2.4, 4.6):
        dom = _dom(_replay_page(tmp_path, data, "decided") + f"#t={t}")
        assert 'data-error="' not in dom, dom[:400]
        k = plain["t"].index(t)
        shown = html.unescape(re.search(r'<pre class="values">(.*?)</pre>', dom, re.S).group(1))
        assert shown.splitlines() == frame_lines(plain, k)[1:]  # the same lines, the decision among them
        assert any(line.startswith("ego decision: ") for line in shown.splitlines())


def test_the_replay_labels_each_car_beside_it_and_off_the_others_in_a_dense_scene(tmp_path):
    from test_sim_render import NEAR_PX, _gap, _overlaps, dense_scene

    from pytest_avscenario.monitors import distance
    from pytest_avscenario.report.recording import recording_data
    from pytest_avscenario.sim.clip import decoded, dumps

    w = dense_scene()
    data = recording_data(w, violations={"distance": {"t": 0.4, "agent": "car4", "threshold": 5.0, "rho": -4.0}},
                       monitors=[distance(5.0, kind="centre")])
    dom = _dom(_replay_page(tmp_path, data, "dense"))
    assert 'data-error="' not in dom, dom[:400]
    placed = json.loads(html.unescape(re.search(r'data-labels="([^"]*)"', dom).group(1)))
    # the footprints on the canvas, from the data alone: the view follows the ego, the road's
    # middle fixed, north up
    plain = decoded(json.loads(dumps(data)))
    k, view = plain["first"], data["view"]
    (W, H), S = view["size"], view["scale"]
    ego = plain["agents"][0]
    cx, cy = ego["x"][k] + view["ahead"], view["cy"]
    cars = {}
    for a in plain["agents"]:
        h = np.radians(a["h"][k])
        xs, ys = [], []
        for f, g in ((1, 1), (1, -1), (-1, -1), (-1, 1)):
            x = a["x"][k] + np.cos(h) * f * a["L"] / 2 - np.sin(h) * g * a["W"] / 2
            y = a["y"][k] + np.sin(h) * f * a["L"] / 2 + np.cos(h) * g * a["W"] / 2
            xs.append((x - cx) * S + W / 2)
            ys.append(H / 2 - (y - cy) * S)
        cars[a["name"]] = (min(xs), min(ys), max(xs) - min(xs), max(ys) - min(ys))
    assert sorted(placed) == sorted(cars)
    for name, label in placed.items():
        box = label["box"]
        assert 0 <= box[0] and box[0] + box[2] <= W and 0 <= box[1] and box[1] + box[3] <= H
        assert _gap(box, cars[name]) <= NEAR_PX, (name, box, cars[name])
        assert not [n for n in cars if n != name and _overlaps(box, cars[n])], (name, box)
        assert not [n for n, o in placed.items() if n != name and _overlaps(box, o["box"])], (name, box)


def test_a_campaign_with_more_counterexamples_than_the_cap_cards_the_first_and_says_so(tmp_path, monkeypatch):
    """A huge campaign's counterexamples do not each get a page (issue #35: 30,000 pages at
    the end of a 100,000-case run): each failure mode's representative, the minimized ones,
    then those that ran first get one; the index says how many of how many, and that the
    error table has them all."""
    from pytest_avscenario.outcome import CaseRow
    from pytest_avscenario.report import build
    from pytest_avscenario.report.summary import TestInfo
    from pytest_avscenario.space import FeatureSpace, Uniform

    monkeypatch.setattr(build, "MAX_CARDS", 4)
    test = "test_big.py::test_big"
    rows = [CaseRow(test=test, item=f"{test}[halton-{i:03d}]", sampler="halton", index=i, seed=i,
                    origin="sampled", params={"x": i / 20}, rho={"distance": 0.5 - i / 20},
                    verdict="fail" if i > 10 else "pass",
                    minimized={"x": 0.6} if i == 19 else None) for i in range(20)]
    info = {test: TestInfo(("distance",), FeatureSpace({"x": Uniform(0, 1)}))}
    summary = build.finish_report(tmp_path, info, rows=rows, pictures=False)
    cards = sorted(p.name for p in (tmp_path / "cases").glob("*.html"))
    assert len(cards) == 4
    representatives = {m.representative for s in summary for m in s.modes}
    assert representatives
    from pytest_avscenario.report.cards import card_name

    carded = {r.item for r in rows if card_name(r) in cards}
    assert representatives <= carded and f"{test}[halton-019]" in carded  # the minimized one
    index = (tmp_path / "index.html").read_text()
    assert "9 counterexamples (1 minimized): pages for 4 of them" in index and "errors.jsonl" in index
    # the index links only pages that exist
    linked = set(re.findall(r"cases/([^'\"#]+\.html)", index))
    assert linked and linked <= set(cards)

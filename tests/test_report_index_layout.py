"""The index's first screen says what the run concluded: the run's verdict and the rejected
campaigns open the page, the verdict column is visible at 1,280 px without scrolling, and a
baseline comparison shows only what changed (the rest folded). Measured in headless Chromium."""

from __future__ import annotations

import re
from dataclasses import replace

import pytest

from pytest_avscenario.report.html import render_index
from test_report_cards import _dom
from test_report_summary import FOLLOW, PARK, rows, tests_info  # noqa: F401 (fixtures)

# the page measures itself after layout and writes the numbers into <html>, for --dump-dom
PROBE = """<script>
window.addEventListener("load", function () {
  var root = document.documentElement;
  var th = Array.from(document.querySelectorAll("#summary th")).find(function (h) { return h.textContent === "verdict"; });
  var r = th.getBoundingClientRect();
  root.setAttribute("data-verdict-right", String(Math.round(r.right)));
  root.setAttribute("data-verdict-left", String(Math.round(r.left)));
  root.setAttribute("data-run-verdict-top", String(Math.round(document.getElementById("run-verdict").getBoundingClientRect().top)));
  root.setAttribute("data-summary-top", String(Math.round(document.getElementById("summary").getBoundingClientRect().top)));
  root.setAttribute("data-viewport", String(window.innerWidth));
});
</script>"""


def _summary(rows, tests_info):
    from pytest_avscenario.report.summary import summarize

    long = "test_" + "unprotected_left_turn_with_a_lateral_car_running_the_stop_" * 2 + "east"
    out = []
    for s in summarize(rows, tests_info):
        rejected = s.counterexamples > 0
        out.append(replace(s, test=s.test.replace("test_vehicle_following", long),
                           reasons=["counterexample violating collision: [halton-003]"] if rejected else []))
    return out


def _page(tmp_path, summary, preamble=()):
    html = render_index(tmp_path, summary, {}, {}, meta={"seed": 0}, preamble=list(preamble))
    page = tmp_path / "index.html"
    page.write_text(html.replace("</body>", PROBE + "</body>"))
    return page, html


def _chromium_dom(page):
    from test_report_cards import _chromium

    import subprocess
    import tempfile

    with tempfile.TemporaryDirectory() as profile:
        cmd = [_chromium(), "--headless", "--no-sandbox", "--disable-gpu", "--hide-scrollbars",
               "--no-first-run", f"--user-data-dir={profile}", "--window-size=1280,800",
               "--virtual-time-budget=3000", "--dump-dom", page.resolve().as_uri()]
        return subprocess.run(cmd, capture_output=True, text=True, timeout=90).stdout


def test_the_index_opens_with_the_verdict_and_the_rejected_campaigns(rows, tests_info, tmp_path):
    summary = _summary(rows, tests_info)
    page, html = _page(tmp_path, summary)
    body = html.split("<body>", 1)[1]
    # the verdict is the first thing after the title and the run's facts
    assert body.index("id='run-verdict'") < body.index("id='summary'")
    rejected = [s for s in summary if s.reasons]
    assert rejected and f"data-verdict='rejected'" in html
    assert f"{len(rejected)} of {len(summary)} campaigns rejected" in html
    ul = re.search(r"<ul id='rejected'>(.*?)</ul>", html).group(1)
    assert ul.count("<li>") == len(rejected) and "collision" in ul
    # all accepted: the same place says so
    _, ok = _page(tmp_path, [replace(s, reasons=[]) for s in summary])
    assert "data-verdict='accepted'" in ok and "id='rejected'" not in ok


def test_the_verdict_column_is_on_the_first_screen_at_1280_px(rows, tests_info, tmp_path):
    page, _ = _page(tmp_path, _summary(rows, tests_info))
    dom = _chromium_dom(page)
    got = {k: int(v) for k, v in re.findall(r'data-(verdict-right|verdict-left|run-verdict-top|summary-top|viewport)="(-?\d+)"', dom)}
    assert got.get("viewport") == 1280, dom[:300]
    assert 0 < got["verdict-left"] < got["verdict-right"] <= 1280, got
    assert got["run-verdict-top"] < 200 and got["summary-top"] < 800, got


def test_a_baseline_comparison_shows_what_changed_and_folds_the_rest():
    from pytest_avscenario.report.compare import Comparison, RateChange, comparison_html

    rates = [RateChange(FOLLOW, "halton", "collision", (5, 60), (1, 60)),
             RateChange(FOLLOW, "halton", "ttc", (3, 60), (3, 60)),
             RateChange(PARK, "halton", "ttc", (0, 60), (0, 60)),
             RateChange(PARK, "halton", "distance", (2, 60), (2, 60))]
    html = comparison_html(Comparison("main/summary.json", rates, [], [], []))
    changed = re.search(r"<table class='comparison changed'>.*?</table>", html, re.S).group(0)
    assert "collision" in changed and "ttc" not in changed
    folded = re.search(r"<details class='unchanged'><summary>(\d+) unchanged rates</summary>(.*?)</details>",
                       html, re.S)
    assert folded and folded.group(1) == "3" and "ttc" in folded.group(2)
    same = comparison_html(Comparison("main/summary.json", rates[1:], [], [], []))
    assert "No violation rate changed." in same and "class='comparison changed'" not in same

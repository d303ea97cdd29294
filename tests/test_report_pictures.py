"""Pictures and the static index page: PNGs that show passes and failures, an escaped page
whose table and images really render in a headless browser."""

import math
import re
import shutil
import subprocess
import tempfile
from pathlib import Path

import numpy as np
import pytest

from pytest_avscenario.report.html import render_index, write_index
from pytest_avscenario.report.plots import plot_feature_space, plot_rho_over_index, plot_test
from pytest_avscenario.report.summary import TestInfo, summarize
from pytest_avscenario.report.table import ErrorTable
from pytest_avscenario.space import Choice, FeatureSpace, Uniform

PASS_RGB = (0x00, 0x72, 0xB2)  # the ρ plot's passing cases
FAIL_RGB = (0xD5, 0x5E, 0x00)  # failures (in the space plot: those that violated distance first)
SPACE_PASS_RGB = (0x9E, 0xC5, 0xE8)  # the space plot's passing cases
TTC_FIRST_RGB = (0xE6, 0x9F, 0x00)  # the space plot's failures that violated ttc first
NASTY = "tests/test_x.py::test_follow[<img src=x onerror=alert(1)>&\"q\"]"


def make_rows(test=NASTY, n=40, seed=0):
    rng = np.random.default_rng(seed)
    rows = []
    for i in range(n):
        gap, speed = rng.uniform(10, 40), rng.uniform(5, 15)
        rho = {"distance": gap - 25.0, "ttc": math.inf if i % 3 else speed - 10.0}
        rows.append({
            "test": test, "item": f"{test}[{i}]", "sampler": "halton" if i % 2 else "mab", "index": i // 2,
            "seed": i, "origin": "sampled", "params": {"gap": gap, "speed": speed, "road": ["dry", "<wet>"][i % 2]},
            "rho": rho, "verdict": "fail" if min(rho.values()) < 0 else "pass", "sim_time_s": 0.01, "error": None,
        })
    return rows


def _pixels(path):
    from PIL import Image

    return np.asarray(Image.open(path).convert("RGB")).reshape(-1, 3).astype(int)


def _count_colour(pixels, rgb, tol=90):
    # Loose enough for antialiasing and the markers' slight transparency over white, far
    # tighter than the distance between the pass blue, the fail orange and the grey lines.
    return int((np.abs(pixels - np.array(rgb)).sum(axis=1) < tol).sum())


def test_feature_space_plot_shows_passing_and_failing_cases(tmp_path):
    path = plot_feature_space(tmp_path / "space.png", make_rows(), metrics=["distance", "ttc"])
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    px = _pixels(path)
    assert _count_colour(px, SPACE_PASS_RGB, tol=40) > 50 and _count_colour(px, FAIL_RGB, tol=40) > 50
    # failures are coloured by the metric they violated first: without times, the first in
    # declaration order; cases that violated ttc before distance take ttc's colour
    rows = make_rows()
    both = [r for r in rows if r["rho"]["ttc"] < 0 and r["rho"]["distance"] < 0]
    assert both
    for r in both:
        r["violations"] = {"ttc": {"t": 1.0}, "distance": {"t": 2.0}}
    px2 = _pixels(plot_feature_space(tmp_path / "space2.png", rows, metrics=["distance", "ttc"]))
    assert _count_colour(px2, TTC_FIRST_RGB, tol=40) > _count_colour(px, TTC_FIRST_RGB, tol=40) + 20
    # Only passing cases: no failure colour anywhere.
    passing = [r for r in make_rows() if r["verdict"] == "pass"]
    assert _count_colour(_pixels(plot_feature_space(tmp_path / "p.png", passing)), FAIL_RGB, tol=40) == 0


def test_rho_plot_handles_infinities_and_missing_values(tmp_path):
    rows = make_rows()
    rows[0]["rho"] = {"distance": -math.inf}  # ttc missing, distance off the scale
    path = plot_rho_over_index(tmp_path / "rho.png", rows, ["distance", "ttc"])
    from PIL import Image

    w, h = Image.open(path).size
    assert w > 500 and h > 400  # two panels
    assert _count_colour(_pixels(path), FAIL_RGB) > 20


def test_nothing_to_draw_writes_nothing(tmp_path):
    assert plot_feature_space(tmp_path / "a.png", []) is None
    constant = [dict(r, params={"lane": 1}) for r in make_rows(n=3)]
    assert plot_feature_space(tmp_path / "b.png", constant) is None
    assert plot_rho_over_index(tmp_path / "c.png", [dict(r, rho={}) for r in make_rows(n=3)]) is None
    assert list(tmp_path.iterdir()) == []


def test_plot_test_names_files_after_the_test(tmp_path):
    out = plot_test(tmp_path, NASTY, make_rows(n=6))
    assert set(out) == {"space", "rho"}
    for p in out.values():
        assert p.parent == tmp_path / "plots" and "<" not in p.name and p.stat().st_size > 5000


def _build_report(directory: Path):
    rows = make_rows() + make_rows(test="tests/test_y.py::test_cross", n=10, seed=1)
    info = {NASTY: TestInfo(("distance", "ttc"), FeatureSpace({"gap": Uniform(10, 40), "speed": Uniform(5, 15),
                                                               "road": Choice(["dry", "<wet>"])}))}
    with ErrorTable(directory) as table:
        for r in rows:
            table.append(r)
        tables = table.tables()
    tables[""] = [directory / "errors.jsonl"]
    images = {t: plot_test(directory, t, [r for r in rows if r["test"] == t]) for t in (NASTY, "tests/test_y.py::test_cross")}
    summary = summarize(rows, info)
    return write_index(directory, summary, images, tables, meta={"seed": "<7>"}), summary, images


def test_index_escapes_everything_and_links_relatively(tmp_path):
    index, summary, images = _build_report(tmp_path / "rep")
    text = index.read_text()
    assert "<img src=x" not in text and "&lt;img src=x onerror=alert(1)&gt;&amp;&quot;q&quot;" in text
    assert "seed: &lt;7&gt;" in text
    hrefs = re.findall(r"(?:href|src)='([^']*)'", text)
    assert hrefs and all(not h.startswith(("/", "http")) for h in hrefs)
    for h in hrefs:  # every link resolves to a file we wrote, or to a section of the page
        from urllib.parse import unquote

        if h.startswith("#"):
            assert f"id='{h[1:]}'" in text, h
            continue
        assert (index.parent / unquote(h)).is_file(), h
    n_images = sum(len(v) for v in images.values())
    assert text.count("<img ") == n_images == 4
    assert text.count("<tr>") == 1 + len(summary)


def _chromium() -> str:
    """Path of a headless-capable Chromium; the test skips when there is none (tests never
    install anything: `.ci/run` installs Debian's package)."""
    for name in ("chromium", "chromium-browser", "google-chrome"):
        if shutil.which(name):
            return shutil.which(name)
    pytest.skip("Chromium is not installed: `apt install chromium` (Debian) to run the "
                "browser checks of the HTML report; .ci/run installs it")


def _headless(chromium: str, *args: str) -> subprocess.CompletedProcess:
    # no network here: without these flags Chromium keeps trying (and failing) to phone home
    with tempfile.TemporaryDirectory() as profile:
        cmd = [chromium, "--headless", "--no-sandbox", "--disable-gpu", "--hide-scrollbars",
               "--disable-quic", "--no-first-run", "--disable-background-networking",
               "--disable-component-update", "--disable-sync", f"--user-data-dir={profile}",
               "--virtual-time-budget=5000", *args]
        return subprocess.run(cmd, capture_output=True, text=True, timeout=90)


@pytest.fixture(scope="module")
def chromium():
    return _chromium()


def test_index_renders_its_table_and_images_in_headless_chromium(tmp_path, chromium):
    index, summary, images = _build_report(tmp_path / "rep")
    url = index.resolve().as_uri()
    dom = _headless(chromium, "--dump-dom", url).stdout
    assert "<table id=\"summary\">" in dom
    assert dom.count("<tr>") == 1 + len(summary)
    n = sum(len(v) for v in images.values())
    # The page's own check ran in the browser: every <img> decoded to a non-empty bitmap.
    assert f'data-loaded="{n}/{n}"' in dom and dom.count('data-loaded="yes"') == n
    shot = tmp_path / "shot.png"
    _headless(chromium, "--window-size=1300,2200", f"--screenshot={shot}", url)
    px = _pixels(shot)
    assert _count_colour(px, FAIL_RGB) > 100  # the scatter points were painted


def test_the_browser_check_notices_a_missing_picture(tmp_path, chromium):
    page = render_index(tmp_path, [], {"t": {"gone": tmp_path / "nope.png"}}, {})
    (tmp_path / "index.html").write_text(page)
    dom = _headless(chromium, "--dump-dom", (tmp_path / "index.html").as_uri()).stdout
    assert 'data-loaded="0/1"' in dom and 'class="broken"' in dom


def test_finish_report_builds_everything_from_the_tables_on_disk(tmp_path):
    from pytest_avscenario.report.build import finish_report

    rows = make_rows(n=12)
    with ErrorTable(tmp_path) as table:
        for r in rows:
            table.append(r)
        table.append(dict(rows[0], origin="shrink"))
    info = {NASTY: TestInfo(("distance", "ttc"), FeatureSpace({"gap": Uniform(10, 40), "speed": Uniform(5, 15),
                                                               "road": Choice(["dry", "<wet>"])}))}
    summary = finish_report(tmp_path, info, seed=3, versions={"highway-env": "1.12.1"})
    assert [(s.sampler, s.samples) for s in summary] == [("mab", 6), ("halton", 6)]
    import json

    data = json.loads((tmp_path / "summary.json").read_text())
    assert data["seed"] == 3 and len(data["tests"]) == 2
    page = (tmp_path / "index.html").read_text()
    assert page.count("<img ") == 2 and ".shrink.csv" in page and "errors.jsonl" in page
    assert len(list((tmp_path / "plots").glob("*.png"))) == 2


def test_the_space_plot_draws_values_near_the_largest_float(tmp_path):
    # Uniform(1e308, 1.7e308) is a valid declaration: its axis is drawn divided by 1e308
    from pytest_avscenario.outcome import CaseRow
    from pytest_avscenario.report.plots import _axis_name, plot_feature_space

    rows = [CaseRow(test="t", item=f"t[halton-00{i}]", sampler="halton", index=i, seed=1,
                    origin="sampled", params={"x": 1e308 + i * 1.5e307}, rho={}, verdict="pass")
            for i in range(5)]
    assert plot_feature_space(tmp_path / "space.png", rows) is not None
    assert _axis_name(rows, "x") == "x (×1e+308)"


def test_the_case_time_series_shows_the_egos_decisions_along_its_time_axis(tmp_path):
    from PIL import Image

    from pytest_avscenario.monitors import distance
    from pytest_avscenario.report.casefigs import DECISION_COLOURS, decision_spans, plot_case_timeseries
    from pytest_avscenario.trajectory import Trajectory

    t = np.arange(0, 10.01, 0.1)
    agents = {"ego": {"x": 20 * t, "y": 0 * t}, "lead": {"x": 30 + 18 * t, "y": 0 * t}}
    plain = Trajectory.from_arrays(t, agents)
    decided = Trajectory.from_arrays(t, agents, meta={"decisions": {"source": "action", "changes": [
        [0.0, "FASTER"], [2.0, "IDLE"], [6.0, "FASTER"]]}})
    assert decision_spans(plain) == []
    assert decision_spans(decided) == [(0.0, 2.0, "FASTER"), (2.0, 6.0, "IDLE"), (6.0, 10.0, "FASTER")]
    before = Image.open(plot_case_timeseries(tmp_path / "plain.png", plain, monitors=[distance(5.0, kind="centre")]))
    after = plot_case_timeseries(tmp_path / "decided.png", decided, monitors=[distance(5.0, kind="centre")], first_t=3.0)
    rgb = np.asarray(Image.open(after).convert("RGB")).astype(int)
    assert rgb.shape[0] > before.height  # a strip above the three panels

    def hexrgb(h):
        return np.array([int(h[i:i + 2], 16) for i in (1, 3, 5)])

    faster = (np.abs(rgb - hexrgb(DECISION_COLOURS[0])).sum(axis=2) < 30)
    idle = (np.abs(rgb - hexrgb(DECISION_COLOURS[1])).sum(axis=2) < 30)
    # the strip: the row holding most of the first decision's colour, in the top fifth
    row = int(np.argmax(faster.sum(axis=1)))
    assert row < rgb.shape[0] / 5
    # along it, each decision's colour covers the share of the run it was in force (FASTER 6 s
    # of 10, IDLE 4 s), in time order: FASTER, then IDLE from 2 s, then FASTER from 6 s
    cols_f, cols_i = np.flatnonzero(faster[row]), np.flatnonzero(idle[row])
    assert len(cols_f) / (len(cols_f) + len(cols_i)) == pytest.approx(0.6, abs=0.06)
    assert cols_f.min() < cols_i.min() < cols_i.max() < cols_f.max()

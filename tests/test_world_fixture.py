"""The world and avs_driver fixtures as a user meets them: real highway-env runs."""

from __future__ import annotations

FOLLOW = """
from pytest_avscenario import scenario, Uniform
from pytest_avscenario.monitors import distance, progress
from pytest_avscenario.sim import behaviors as b

@scenario(gap=Uniform(25, 40), samples=2, monitors=[progress(11.0), distance(5.0, kind="centre")])
def test_follow(case, world):
    road = world.straight_road(lanes=1, length=400)
    world.ego(road.lane(0), s=20.0, speed=12.0)
    world.car(road.lane(0), s=20.0 + case.gap, speed=12.0)
    world.run(seconds=5)
    assert world.trajectory.n_steps == 51
"""


def test_world_runs_highway_env_and_monitors_judge_it(pytester):
    pytester.makepyfile(test_follow=FOLLOW)
    result = pytester.runpytest("--avs-seed=1", "--avs-db=none", "--avs-driver=idm")
    result.assert_outcomes(passed=2)


def test_user_driver_from_conftest_drives_the_ego(pytester):
    pytester.makeconftest("""
import pytest

class StandStill:
    def act(self, observation):
        # brake to a stop whatever happens
        return (-6.0, 0.0)

@pytest.fixture
def avs_driver():
    return StandStill()
""")
    # braking at 6 m/s^2 from 12 m/s stops the ego after 12 m: it cannot make 30 m of progress
    pytester.makepyfile(test_follow=FOLLOW.replace("progress(11.0)", "progress(30.0)"))
    result = pytester.runpytest("--avs-seed=1", "--avs-db=none", "--avs-shrink-budget=0")
    result.assert_outcomes(failed=2)
    result.stdout.fnmatch_lines(["*scenario violated: progress*"])


def test_a_driver_that_raises_fails_the_case_not_the_session(pytester):
    pytester.makeconftest("""
import pytest

@pytest.fixture
def avs_driver():
    def policy(observation):
        raise RuntimeError("perception crashed")
    return policy
""")
    pytester.makepyfile(test_follow=FOLLOW)
    result = pytester.runpytest("--avs-seed=1", "--avs-db=none")
    result.assert_outcomes(errors=2)
    result.stdout.fnmatch_lines(["*perception crashed*"])
    rows = (pytester.path / "avs-report" / "errors.jsonl").read_text().splitlines()
    assert len(rows) == 2 and all('"verdict": "error"' in r for r in rows)


def test_no_trajectory_with_monitors_is_an_error_that_says_why(pytester):
    pytester.makepyfile(test_none="""
from pytest_avscenario import scenario, Uniform
from pytest_avscenario.monitors import distance
@scenario(gap=Uniform(25, 40), samples=1, monitors=[distance(5.0, kind="centre")])
def test_nothing(case, world):
    world.straight_road(lanes=1, length=100)
""")
    result = pytester.runpytest("--avs-db=none")
    result.assert_outcomes(errors=1)
    result.stdout.fnmatch_lines(["*declares monitors but produced no trajectory*world.run*"])


def test_bad_monitor_declaration_is_a_collection_error(pytester):
    pytester.makepyfile(test_bad="""
from pytest_avscenario import scenario, Uniform
from pytest_avscenario.monitors import distance
@scenario(gap=Uniform(25, 40), monitors=[distance(5.0, kind="centre"), distance(2.0, kind="centre")])
def test_twice(case, world):
    pass
""")
    result = pytester.runpytest()
    result.stdout.fnmatch_lines(["*::test_twice: monitors: two monitors are named 'distance'*"])


def test_minimized_counterexample_gets_a_first_violation_png_and_a_gif(pytester):
    pytester.makepyfile(test_close="""
from pytest_avscenario import scenario, Uniform
from pytest_avscenario.monitors import distance
from pytest_avscenario.sim import behaviors as b

@scenario(gap=Uniform(6, 40, nominal=35), samples=3, monitors=[distance(25.0, kind="centre")], shrink_budget=4)
def test_close(case, world):
    road = world.straight_road(lanes=1, length=300)
    world.ego(road.lane(0), s=20.0, speed=10.0)
    world.car(road.lane(0), s=20.0 + case.gap, speed=10.0)
    world.run(seconds=2)
""")
    result = pytester.runpytest("--avs-seed=1", "--avs-db=none", "--avs-driver=idm", "--avs-gifs=1")
    failed = result.parseoutcomes()["failed"]
    assert failed >= 2
    cases = pytester.path / "avs-report" / "cases"
    assert len(list(cases.glob("*.moment.png"))) == len(list(cases.glob("*.timeseries.png"))) == failed
    assert len(list(cases.glob("*.gif"))) == 1  # the cap
    index = (pytester.path / "avs-report" / "index.html").read_text()
    # the index links each counterexample's card; the card shows its PNG and GIF
    cards = sorted(cases.glob("*.html"))
    assert len(cards) == failed and all(f"cases/{c.name}" in index for c in cards)
    assert any(".gif" in c.read_text() for c in cards)
    from PIL import Image

    png = Image.open(next(cases.glob("*.moment.png")))
    colours = png.convert("RGB").getcolors(maxcolors=1 << 16) or []
    assert png.size[0] > 100 and len(colours) > 3  # not a blank frame


def test_pytest_html_rows_carry_the_pictures_of_a_failing_case(pytester):
    pytest_html = __import__("pytest").importorskip("pytest_html")
    pytester.makepyfile(test_close="""
from pytest_avscenario import scenario, Uniform
from pytest_avscenario.monitors import distance

@scenario(gap=Uniform(6, 40, nominal=35), samples=2, monitors=[distance(25.0, kind="centre")], shrink_budget=2)
def test_close(case, world):
    road = world.straight_road(lanes=1, length=300)
    world.ego(road.lane(0), s=20.0, speed=10.0)
    world.car(road.lane(0), s=20.0 + case.gap, speed=10.0)
    world.run(seconds=2)
""")
    result = pytester.runpytest("--avs-seed=1", "--avs-db=none", "--avs-driver=idm",
                                "--html=page.html", "--self-contained-html", "-W", "error::ResourceWarning")
    assert result.parseoutcomes()["failed"] == 2  # gaps 23 m and 14.5 m are both under 25 m
    assert "ResourceWarning" not in result.stdout.str()  # every picture file read is closed
    page = (pytester.path / "page.html").read_text()
    assert "first violation" in page and "data:image/png;base64," in page and "image/gif" in page

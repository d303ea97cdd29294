"""Issue #17 item 3: every counterexample can be replayed, and its still shows the first violation.

The replay data of a run holds every agent at a decimated rate with the first violation's
step among its frames, the critical agent and the metric values per frame; the annotated
still is drawn at that frame with every agent labelled. (The card page's slider is checked
through pytest and Chromium in test_report_cards.py.)
"""

from __future__ import annotations

import json
import math
import re

import numpy as np
import pytest
from PIL import Image

from pytest_avscenario.monitors import collision, distance, ttc
from pytest_avscenario.monitors.base import first_violation
from pytest_avscenario.outcome import violations_of
from pytest_avscenario.sim import World
from pytest_avscenario.report.recording import recording_data
from pytest_avscenario.sim.clip import decoded, dumps, frame_lines
from pytest_avscenario.trajectory import Trajectory

MONITORS = [distance(8.0, kind="centre"), collision(), ttc(2.0, kind="centre")]


def _violations(traj):
    results = {m.name: m.evaluate(traj) for m in MONITORS}
    first = {m.name: first_violation(m, traj, results[m.name]) for m in MONITORS if results[m.name].rho < 0}
    out = violations_of(results, first) or {}
    for name, where in out.items():
        where["rho"] = results[name].rho
    return out


@pytest.fixture(scope="module")
def crash():
    """The ego, driven by a policy that never brakes, runs into a stopped car; a third car
    passes in the next lane."""
    w = World(seed=1, driver=lambda obs: (0.0, 0.0), name="crash")
    road = w.straight_road(lanes=2, length=200)
    w.ego(road.lane(0), s=10.0, speed=15.0)
    w.car(road.lane(0), s=61.0, speed=0.0, name="stopped")
    w.car(road.lane(1), s=0.0, speed=10.0, name="passing")
    w.run(4.0)
    return w


def test_the_replay_of_a_collision_holds_every_agent_and_starts_at_the_first_violation(crash):
    traj = crash.trajectory
    violations = _violations(traj)
    assert set(violations) == {"distance", "collision", "ttc"}
    data = recording_data(crash, violations=violations, monitors=MONITORS, title="test_crash[x-0]")
    plain = decoded(json.loads(dumps(data)))  # what the card gets
    assert [a["name"] for a in plain["agents"]] == ["ego", "stopped", "passing"]
    assert [a["kind"] for a in plain["agents"]] == ["ego", "car", "car"]
    # 5 frames per second over 4 s, the first violation's step (TTC, at 1.1 s) and the contact's
    first_t = min(w["t"] for w in violations.values())
    assert first_t == pytest.approx(1.1) and violations["ttc"]["t"] == first_t
    assert len(plain["t"]) == 23 and plain["t"][0] == 0.0 and plain["t"][-1] == 4.0
    assert plain["t"][plain["first"]] == pytest.approx(first_t) and plain["first_kind"] == "violation"
    assert plain["critical"] == "stopped"
    # positions to the centimetre, at every frame
    for i, a in enumerate(plain["agents"]):
        for k, t in enumerate(plain["t"]):
            step = int(np.argmin(np.abs(traj.t - t)))
            assert a["x"][k] == pytest.approx(traj.x[i, step], abs=0.006)
            assert a["y"][k] == pytest.approx(traj.y[i, step], abs=0.006)
            assert a["v"][k] == pytest.approx(traj.speed[i, step], abs=0.06)
    # the crash: from which frame the ego and the stopped car are drawn crashed
    crash_t = traj.t[np.argmax(traj.crashed[0])]
    assert plain["t"][plain["agents"][0]["crash"]] == pytest.approx(crash_t)
    assert plain["agents"][2]["crash"] is None
    # per frame: the gap to the critical agent and ρ(t) of the distance metric
    k = plain["first"]
    step = int(np.argmin(np.abs(traj.t - plain["t"][k])))
    centre = math.hypot(traj.x[1, step] - traj.x[0, step], traj.y[1, step] - traj.y[0, step])
    assert plain["values"]["d"][k] == pytest.approx(centre, abs=0.006)
    assert plain["rho_t"]["ttc"][k] <= 0 < plain["rho_t"]["ttc"][k - 1]  # to the centisecond
    closer = [t >= violations["distance"]["t"] - 1e-9 for t in plain["t"]]
    assert [r < 0 for r in plain["rho_t"]["distance"]] == closer
    assert "collision" not in plain["rho_t"]  # a whole-run verdict has no value per frame
    assert len(plain["road"]["lanes"]) == 2
    lines = frame_lines(plain, k)
    assert lines[0] == f"t = {first_t:.2f} s — first violation"
    assert lines[1].startswith("stopped: distance ")
    assert any(line.startswith("collision: run ρ ") for line in lines)


def test_the_replay_is_small_and_the_same_for_the_same_run(crash):
    data = recording_data(crash, violations=_violations(crash.trajectory), monitors=MONITORS)
    text = dumps(data)
    assert len(text) < 4000  # ~600 counterexamples per example-suite report
    assert dumps(recording_data(crash, violations=_violations(crash.trajectory), monitors=MONITORS)) == text


def test_agents_present_for_part_of_the_run_are_absent_elsewhere():
    t = np.arange(0, 4.01, 0.1)
    present = (t >= 1.0) & (t <= 2.5)
    traj = Trajectory.from_arrays(t, {
        "ego": {"x": 10 * t, "y": np.zeros_like(t)},
        "walker": {"x": np.where(present, 25.0, np.nan), "y": np.where(present, 3 - 2 * (t - 1), np.nan),
                   "kind": "pedestrian", "present": present},
    })
    data = recording_data(traj, violations={"distance": {"t": 2.0, "agent": "walker", "threshold": 8.0, "rho": -3.0}},
                       monitors=[distance(8.0, kind="centre")])
    assert "road" not in data and data["agents"][1]["k0"] > 0
    plain = decoded(json.loads(dumps(data)))
    walker = plain["agents"][1]
    assert all(len(a[key]) == len(plain["t"]) for a in plain["agents"] for key in "xyhv")
    shown = [tk for tk, x in zip(plain["t"], walker["x"]) if x is not None]
    assert shown[0] == 1.0 and shown[-1] == 2.4
    assert walker["x"][plain["first"]] == 25.0 and plain["t"][plain["first"]] == 2.0
    # the ego is the view's anchor: the data says to follow it
    assert data["view"]["cx"] is None and data["view"]["cy"] is None


def test_the_still_is_drawn_at_the_first_violation_with_every_agent_labelled(crash, tmp_path):
    from pytest_avscenario.sim.render import render_moment

    violations = _violations(crash.trajectory)
    data = recording_data(crash, violations=violations, monitors=MONITORS, title="test_crash[x-0]")
    drawn = render_moment(crash, str(tmp_path / "m.png"), data)
    first_t = min(w["t"] for w in violations.values())
    assert drawn["t"] == pytest.approx(first_t) and crash.trajectory.t[drawn["step"]] == pytest.approx(first_t)
    assert sorted(drawn["labels"]) == ["ego", "passing", "stopped"] and drawn["critical"] == "stopped"
    assert drawn["lines"][0] == f"t = {first_t:.2f} s — first violation"
    image = Image.open(drawn["path"])
    assert image.mode == "P" and image.width == 800  # a palette PNG, the scene's width
    assert (tmp_path / "m.png").stat().st_size < 25_000
    # the critical agent's ring is in the picture
    rgb = np.asarray(image.convert("RGB")).reshape(-1, 3)
    assert ((rgb[:, 0] > 240) & (abs(rgb[:, 1].astype(int) - 150) < 12) & (rgb[:, 2] < 20)).sum() > 50


CLOSE_CALLS = """
from pytest_avscenario import scenario, Uniform
from pytest_avscenario.monitors import distance

@scenario(gap=Uniform(3, 12, unit="m"), samples=6, monitors=[distance(8.0, kind="centre")])
def test_gap(case, world):
    road = world.straight_road(lanes=1, length=200)
    world.ego(road.lane(0), s=10.0, speed=10.0)
    world.car(road.lane(0), s=10.0 + case.gap, speed=10.0, name="lead")
    world.run(seconds=1)
"""


def test_every_counterexample_gets_its_replay_not_only_the_pictured_ones(pytester):
    pytester.makepyfile(test_gap=CLOSE_CALLS)
    result = pytester.runpytest("--avs-seed=1", "--avs-db=none", "--avs-shrink-budget=0",
                                "--avs-case-pictures=1", "-p", "no:cacheprovider")
    failed = result.parseoutcomes()["failed"]
    assert failed >= 3
    cases = pytester.path / "avs-report" / "cases"
    cards = sorted(cases.glob("*.html"))
    assert len(cards) == failed
    assert len(list(cases.glob("*.moment.png"))) == 1  # the pictures stay within their cap
    (player,) = cases.glob("replay-*.js")  # one player script the cards share
    for card in cards:
        page = card.read_text()
        assert "<input type='range'" in page and "id='replay-data'" in page
        assert f"<script src='{player.name}'></script>" in page and "function avsReplay" not in page
    assert list(cases.glob("*.replay.json")) == []  # taken into the cards: one copy each
    # the next run in the folder deletes the player with the rest: it is listed as ours
    manifest = json.loads((pytester.path / "avs-report" / ".avs-manifest.json").read_text())
    assert f"cases/{player.name}" in manifest["files"]


def test_the_card_section_keeps_odd_agent_names_inside_its_data():
    from pytest_avscenario.report.player import player_html

    t = np.arange(0, 1.01, 0.1)
    name = "</script><img src=x onerror=alert(1)>"
    traj = Trajectory.from_arrays(t, {"ego": {"x": 10 * t, "y": 0 * t}, name: {"x": 12 + 0 * t, "y": 0 * t}})
    data = recording_data(traj, violations={"distance": {"t": 0.0, "agent": name, "threshold": 5.0, "rho": -3.0}})
    section = player_html(data)
    # the data's, the inline player's (a section made on its own) and the call's
    assert name not in section and section.count("</script>") == 3
    embedded = section.split("id='replay-data'>", 1)[1].split("</script>", 1)[0]
    assert json.loads(embedded) == json.loads(dumps(data)) and data["critical"] == name
    # the slider spans every frame and starts at the first violation
    assert "max='5'" in section and f"value='{data['first']}'" in section


# -- the ego's decisions (issue #26 item 6) -----------------------------------------------------------

#: the scripted agent's answers, one per decision (highway-fast-v0 decides once a second):
#: FASTER twice, IDLE twice, LANE_LEFT twice, IDLE twice
SCRIPT = [3, 3, 1, 1, 0, 0, 1, 1]


@pytest.fixture(scope="module")
def decided():
    return decided_world()


def decided_world() -> World:
    """A highway-env agent (a scripted callable policy: no stable-baselines3) drives 8 s."""
    from pytest_avscenario.sim.drivers import highway_env_agent

    answers = iter(SCRIPT)
    agent = highway_env_agent(lambda obs: next(answers), env="highway-fast-v0")
    w = World(seed=3, name="decided")
    road = w.straight_road(lanes=3, length=400, lane_width=4.0, speed_limit=30.0)
    w.ego(road.lane(1), s=20.0, speed=20.0, driver=agent)
    w.car(road.lane(1), s=60.0, speed=20.0, name="lead")
    w.run(7.9, dt=agent.dt)
    return w


def test_the_recording_keeps_a_discrete_agents_decisions_as_changes(decided):
    ego = decided.agent("ego")
    assert [t for t, _ in ego.decisions] == pytest.approx([0, 1, 2, 3, 4, 5, 6, 7])  # one a second
    made = decided.trajectory.meta["decisions"]
    assert made == {"source": "action", "changes": [[0.0, "FASTER"], [2.0, "IDLE"], [4.0, "LANE_LEFT"],
                                                    [6.0, "IDLE"]]}
    # the recording travels as JSON (xdist, Dask, .npz): the decisions with it
    assert json.loads(json.dumps(decided.trajectory.meta))["decisions"] == made
    assert decided.trajectory.ego.lane[-1] != decided.trajectory.ego.lane[0]  # it did change lane


def test_the_replay_names_the_decision_in_force_at_every_frame(decided):
    data = recording_data(decided, violations={}, monitors=MONITORS, fallback_t=3.0)
    # each label once, each change as [centiseconds, label number]: a few bytes per change
    assert data["decisions"] == {"source": "action", "labels": ["FASTER", "IDLE", "LANE_LEFT"],
                                 "at": [[0, 0], [200, 1], [400, 2], [600, 1]]}
    assert len(dumps(data["decisions"])) < 100
    plain = decoded(json.loads(dumps(data)))
    script = {0: "FASTER", 2: "IDLE", 4: "LANE_LEFT", 6: "IDLE"}
    for k, t in enumerate(plain["t"]):
        since = max(s for s in script if s <= t + 1e-9)
        lines = frame_lines(plain, k)
        assert f"ego decision: {script[since]} (since {since:.2f} s)" in lines, (t, lines)
    # the slider has a tick at each change of decision (and at the moment it starts from)
    from pytest_avscenario.report.player import player_html

    ticks = re.findall(r"<option value='(\d+)'>", player_html(data))
    assert [plain["t"][int(k)] for k in ticks] == [0.0, 2.0, 3.0, 4.0, 6.0]


def test_a_driver_with_a_reason_gets_its_reasons_recorded():
    # the autopilot says why it chose its command: cruising, then following a slower car
    w = World(seed=1, name="reasons")
    road = w.straight_road(lanes=1, length=300)
    w.ego(road.lane(0), s=10.0, speed=12.0)
    w.car(road.lane(0), s=45.0, speed=6.0, name="slow")
    w.run(5.0)
    made = w.trajectory.meta["decisions"]
    assert made["source"] == "reason"
    labels = [label for _, label in made["changes"]]
    assert "follow" in labels and all(a != b for a, b in zip(labels, labels[1:]))  # changes only
    plain = decoded(json.loads(dumps(recording_data(w))))
    assert any(line.startswith("ego reason: follow (since ") for line in frame_lines(plain, len(plain["t"]) - 1))


def test_a_policy_without_decisions_records_none(crash):
    assert "decisions" not in crash.trajectory.meta
    assert "decisions" not in recording_data(crash)


def test_a_continuous_agents_decisions_are_its_commands_to_a_tenth():
    from pytest_avscenario.sim.drivers import highway_env_agent

    # the second answer differs from the first by less than 0.05: the same decision
    answers = iter([np.array([0.5, -0.12]), np.array([0.52, -0.1]), np.array([0.0, 0.0])])
    agent = highway_env_agent(lambda obs: next(answers), env="highway-fast-v0",
                              config={"action": {"type": "ContinuousAction"}})
    w = World(seed=3, name="continuous")
    road = w.straight_road(lanes=3, length=400, lane_width=4.0, speed_limit=30.0)
    w.ego(road.lane(1), s=20.0, speed=20.0, driver=agent)
    w.run(2.9, dt=agent.dt)
    assert w.trajectory.meta["decisions"]["changes"] == [
        [0.0, "acceleration +0.5, steering -0.1"], [2.0, "acceleration +0.0, steering +0.0"]]


def test_a_user_policy_with_a_last_reason_gets_it_recorded():
    class Cautious:
        """Brakes gently after 1 s and says so."""

        def __init__(self):
            self.last_reason, self.n = "", 0

        def act(self, obs):
            self.n += 1
            self.last_reason = "keep speed" if self.n <= 10 else "slow down"
            return (0.0 if self.n <= 10 else -1.0), 0.0

    w = World(seed=1, driver=Cautious(), name="own_reason")
    road = w.straight_road(lanes=1, length=300)
    w.ego(road.lane(0), s=10.0, speed=12.0)
    w.run(2.0)
    assert w.trajectory.meta["decisions"] == {"source": "reason",
                                              "changes": [[0.0, "keep speed"], [1.0, "slow down"]]}

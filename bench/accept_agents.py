"""Acceptance check of the avoidability labels with trained highway-env agents (issue #26).

Needs the ``[sb3]`` extra (stable-baselines3, torch): run it from a virtual environment that has
it. Three commands::

    # a small continuous-action PPO on highway-fast-v0 (a few minutes on 2 cores)
    python bench/accept_agents.py train-ppo --out /tmp/ppo.zip --steps 12000 --seed 11
    # per report folder: counterexamples, collisions, off_road, avoidable/unavoidable/unknown
    # per metric; --partners re-runs each collision with the careful reference (in the ego's
    # seat, at the agent's step) and says whether the reference's own crash partner is the
    # agent the label was judged against
    python bench/accept_agents.py summary REPORT_DIR [...] --driver sb3:PATH@highway-fast-v0 --partners
    # the closed form for braking-lead collisions: the reference's own state at the lead's
    # brake onset put into braking_lead_min_gap, beside the label
    python bench/accept_agents.py closed-form REPORT_DIR --driver sb3:PATH@highway-fast-v0

The PPO is tested through the fixture way of the README: ``accept_ppo_fixture.py``'s
``avs_driver`` returns ``highway_env_agent(PPO.load(path), env="highway-fast-v0",
config={"action": {"type": "ContinuousAction"}})`` (how it was wired in: its docstring); for
``summary``/``closed-form`` name that driver ``ppo-continuous:PATH``.
"""

from __future__ import annotations

import argparse
import importlib
import json
import sys
import time
from collections import Counter
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
PPO_CONFIG = {"action": {"type": "ContinuousAction"}}


def train_ppo(out: Path, steps: int, budget_s: float, seed: int) -> dict:
    import gymnasium
    import highway_env  # noqa: F401
    import torch
    from stable_baselines3 import PPO

    sys.path.insert(0, str(ROOT / "example_tests"))
    from train_dqn import budget_callback

    torch.set_num_threads(1)

    env = gymnasium.make("highway-fast-v0", config=PPO_CONFIG)
    model = PPO("MlpPolicy", env, policy_kwargs=dict(net_arch=[64, 64]), n_steps=512, batch_size=64,
                n_epochs=5, learning_rate=3e-4, gamma=0.8, seed=seed, device="cpu", verbose=0)
    cb = budget_callback(budget_s)
    t0 = time.perf_counter()
    model.learn(total_timesteps=steps, callback=cb)
    took = time.perf_counter() - t0
    out.parent.mkdir(parents=True, exist_ok=True)
    model.save(out)
    # highway-env's own measure, 10 episodes
    crashes, speeds, offroad = 0, [], 0
    for i in range(10):
        obs, _ = env.reset(seed=1000 + i)
        done = trunc = False
        while not (done or trunc):
            a, _ = model.predict(obs, deterministic=True)
            obs, _, done, trunc, info = env.step(a)
            speeds.append(float(info["speed"]))
        crashes += bool(info["crashed"])
        offroad += not env.unwrapped.vehicle.on_road
    env.close()
    return {"steps": int(model.num_timesteps), "seconds": round(took), "stopped_early": cb.stopped_early,
            "crashes_of_10": crashes, "offroad_at_end_of_10": offroad,
            "mean_speed": round(sum(speeds) / max(1, len(speeds)), 1)}


def rows(report: Path) -> list[dict]:
    with open(report / "errors.jsonl") as f:
        return [json.loads(line) for line in f if line.strip()]


def _test_function(row: dict):
    mod_path, name = row["test"].split("::")
    folder = Path(mod_path).parent
    sys.path.insert(0, str(ROOT / (folder if str(folder) != "." else "example_tests")))
    mod = importlib.import_module(Path(mod_path).stem)
    fn = getattr(mod, name)
    spec = next(m.args[0] for m in fn.pytestmark if m.name == "scenario")
    return fn, spec


def reference_run(row: dict, driver):
    """The careful reference in the ego's seat of the case, at the scenario driver's step (as the
    plugin's avoidability check runs it); its trajectory."""
    from pytest_avscenario import Case
    from pytest_avscenario.sim import World

    fn, spec = _test_function(row)
    case = Case(row["params"], index=row["index"], seed=row["seed"], sampler=row["sampler"], test=fn.__name__)
    world = World(seed=case.seed, rng=case.rng, driver=driver, name=row["item"], ego_driver="careful")
    fn(case=case, world=world)
    return world.trajectory


def make_driver(spec: str | None):
    """``sb3:PATH@ENV`` as the plugin resolves it; ``ppo-continuous:PATH`` the fixture's PPO; None:
    careful (the reference as its own scenario driver)."""
    if not spec or spec == "careful":
        return None
    if spec.startswith("ppo-continuous:"):
        from stable_baselines3 import PPO

        from pytest_avscenario.sim.drivers import highway_env_agent

        return highway_env_agent(PPO.load(spec.split(":", 1)[1], device="cpu"), env="highway-fast-v0",
                                 config=PPO_CONFIG)
    from pytest_avscenario.sim.drivers import resolve

    return resolve(spec)


def summary(reports: list[Path], driver_spec: str | None, partners: bool) -> None:
    driver = make_driver(driver_spec) if partners else None
    print("| run | test | cex | collision | off_road | metric: avoidable / unavoidable / unknown |"
          + (" collision label judged vs the reference's own crash partner |" if partners else ""))
    print("|---|---|--:|--:|--:|---|" + ("---|" if partners else ""))
    for report in reports:
        by_test: dict[str, list[dict]] = {}
        for r in rows(report):
            if r.get("origin") == "sampled":
                by_test.setdefault(r["test"].split("::")[-1], []).append(r)
        for test, rs in sorted(by_test.items()):
            labels: dict[str, Counter] = {}
            for r in rs:
                for m, v in (r.get("avoidable") or {}).items():
                    labels.setdefault(m, Counter())[{True: "a", False: "u", None: "?"}[v]] += 1
            coll = sum(1 for r in rs if r["rho"].get("collision", 1) < 0)
            off = sum(1 for r in rs if r["rho"].get("off_road", 1) < 0)
            lab = "; ".join(f"{m} {c['a']}/{c['u']}/{c['?']}" for m, c in labels.items())
            extra = ""
            if partners:
                same = differ = ref_clean = 0
                notes = []
                from pytest_avscenario.monitors.conflict import crash_partner

                for r in rs:
                    c = (r.get("conflicts") or {}).get("collision")
                    if c is None:
                        continue
                    traj = reference_run(r, driver)
                    p = crash_partner(traj)
                    if p is None:
                        ref_clean += 1
                    elif p[0] == c["agent"]:
                        same += 1
                    else:
                        differ += 1
                        notes.append(f"{r['item'].split('[')[-1][:-1]}: judged vs {c['agent']}, "
                                     f"reference hit {p[0]} at {p[1]:.1f}s, label "
                                     f"{r['avoidable'].get('collision')}")
                extra = f" same {same}, other {differ}, reference no crash {ref_clean}" + \
                    (f" ({'; '.join(notes)})" if notes else "") + " |"
            print(f"| {report.name} | {test} | {len(rs)} | {coll} | {off} | {lab} |{extra}", flush=True)


def closed_form(report: Path, driver_spec: str | None) -> None:
    """Lead-deceleration collisions: the reference's gap and speed at the lead's brake onset into
    braking_lead_min_gap, against the label."""
    import numpy as np

    from pytest_avscenario.sim.drivers.reference import braking_lead_min_gap

    driver = make_driver(driver_spec)
    print("| case | v0 km/h | headway s | decel | brake_at | ref gap@onset m | ref v@onset | closed form m "
          "| ref sim min sep m | label | conflict why |")
    print("|---|--:|--:|--:|--:|--:|--:|--:|--:|---|---|")
    for r in rows(report):
        if "lead_deceleration" not in r["test"] or r.get("origin") != "sampled":
            continue
        if r["rho"].get("collision", 1) >= 0:
            continue
        p = r["params"]
        traj = reference_run(r, driver)
        lead = traj.names.index("lead")
        k = int(np.searchsorted(traj.t, p["brake_at"] - 1e-9))
        dx = float(np.hypot(traj.x[lead, k] - traj.x[0, k], traj.y[lead, k] - traj.y[0, k]))
        gap = dx - 0.5 * (traj.length[0] + traj.length[lead])
        v = float(traj.speed[0, k])
        vl = float(traj.speed[lead, k])
        acc = float((traj.speed[0, k + 1] - traj.speed[0, k]) / (traj.t[k + 1] - traj.t[k]))
        # the hazard is perceivable once the lead brakes harder than 1.5 m/s^2: a ramp to lead_decel
        mg = braking_lead_min_gap(gap, v, vl, p["lead_decel"], accel=min(acc, 0.0))
        from pytest_avscenario.monitors.metrics import footprint_separation
        from pytest_avscenario.monitors.conflict import conflict_view

        sep = float(np.min(footprint_separation(conflict_view(traj, "lead"))[0]))
        c = (r.get("conflicts") or {}).get("collision") or {}
        print(f"| {r['item'].split('[')[-1][:-1]} | {p['ego_speed']:.0f} | {p['headway']:.2f} | "
              f"{p['lead_decel']:.2f} | {p['brake_at']:.2f} | {gap:.1f} | {v:.1f} | {mg:+.2f} | {sep:+.2f} | "
              f"{(r.get('avoidable') or {}).get('collision')} | {c.get('why', '')} |", flush=True)


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    sub = ap.add_subparsers(dest="cmd", required=True)
    t = sub.add_parser("train-ppo")
    t.add_argument("--out", type=Path, required=True)
    t.add_argument("--steps", type=int, default=12000)
    t.add_argument("--budget", type=float, default=420.0)
    t.add_argument("--seed", type=int, default=11)
    s = sub.add_parser("summary")
    s.add_argument("reports", nargs="+", type=Path)
    s.add_argument("--driver")
    s.add_argument("--partners", action="store_true")
    c = sub.add_parser("closed-form")
    c.add_argument("report", type=Path)
    c.add_argument("--driver")
    a = ap.parse_args(argv)
    if a.cmd == "train-ppo":
        print(train_ppo(a.out.resolve(), a.steps, a.budget, a.seed))
    elif a.cmd == "summary":
        summary(a.reports, a.driver, a.partners)
    else:
        closed_form(a.report, a.driver)


def lead_grid(driver_spec: str | None) -> None:
    """The careful reference on test_r157_lead_deceleration where its closed form (from the
    scenario's own numbers) says it collides: does the simulated reference collide too?"""
    import itertools

    import numpy as np

    from pytest_avscenario.monitors.conflict import conflict_view
    from pytest_avscenario.monitors.metrics import footprint_separation
    from pytest_avscenario.sim.drivers.reference import braking_lead_min_gap

    driver = make_driver(driver_spec)
    print("| v m/s | headway s | decel | brake_at s | closed form m | simulated min sep m |")
    print("|--:|--:|--:|--:|--:|--:|")
    for v, h, d, ba in itertools.product((15.0, 20.0, 25.0), (0.8, 1.0), (5.5, 6.0), (1.0, 3.0)):
        cf = braking_lead_min_gap(h * v, v, v, d)
        if cf > 0:
            continue
        row = {"test": "example_tests/test_r157_lead_deceleration.py::test_r157_lead_deceleration",
               "item": "grid", "index": 0, "seed": 1, "sampler": "grid",
               "params": {"ego_speed": v * 3.6, "headway": h, "lead_decel": d, "brake_at": ba,
                          "curve": "straight"}}
        # the module's headway range starts at 1.0 s; 0.8 s is beyond it, on purpose
        sep = float(np.min(footprint_separation(conflict_view(reference_run(row, driver), "lead"))[0]))
        print(f"| {v:.0f} | {h} | {d} | {ba} | {cf:+.2f} | {sep:+.2f} |", flush=True)


if __name__ == "__main__":
    if len(sys.argv) > 1 and sys.argv[1] == "lead-grid":
        lead_grid(sys.argv[2] if len(sys.argv) > 2 else None)
    else:
        main()

"""Train a small DQN on highway-env's ``highway-fast-v0``, then test it two ways, side by side.

    pip install -e ".[sb3,xdist]"
    python example_tests/train_dqn.py                       # train (<= 10 min), measure, table
    python example_tests/train_dqn.py --no-train            # measure the saved model again
    python example_tests/train_dqn.py --no-train --modules example_tests/test_r157_*.py

1. **Train** an MLP DQN with stable-baselines3 on ``highway-fast-v0`` in its default config,
   with the hyper-parameters of highway-env's own DQN example (``scripts/sb3_highway_dqn.py``:
   learning rate 5e-4, replay buffer 15,000, learning from step 200, batch 32, gamma 0.8,
   one gradient step per step, a target update every 50 steps) scaled down to fit 10 minutes
   on 2 cores with room to spare: a 64x64 network instead of 256x256 (a ~120 KB zip instead
   of ~1.5 MB) and 6,000 steps instead of 20,000 — and exploring over 70 % of the run
   instead of stable-baselines3's default 10 %, which the short run needs (measured: 10,000
   steps with the default exploration crashed in 36 % of the episodes, these 6,000 in 8 %).
   With the same seed the weights are the same in every run. Training stops early when
   ``--budget`` seconds have passed (the model is then saved as it is, and the table says
   so). The model is saved to ``--out`` (default ``example_tests/models/dqn_highway_fast.zip``).
2. **highway-env's own measure**: the crash rate over ``--episodes`` episodes of
   ``highway-fast-v0`` (30 s each, seeds 1000, 1001, ...), the model acting deterministically —
   what an RL paper reports.
3. **The plugin's campaigns**: ``pytest MODULES -m scenario --avs-driver
   sb3:MODEL@highway-fast-v0`` with a fixed seed and no replay database, and the same
   campaigns with the built-in ``autopilot`` and highway-env's ``idm`` as the ego; per scenario
   and sampler, the number of counterexamples, of cases violating each metric and of
   collisions the careful reference driver avoids, read from each run's ``summary.json``
   and ``errors.jsonl``.

The tables are printed as Markdown; ``--readme`` also writes them into
``example_tests/README.md`` between the ``<!-- train_dqn -->`` markers.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
DEFAULT_OUT = HERE / "models" / "dqn_highway_fast.zip"
ENV_ID = "highway-fast-v0"
MARK_BEGIN = "<!-- train_dqn: begin -->"
MARK_END = "<!-- train_dqn: end -->"


def budget_callback(budget_s: float):
    """A stable-baselines3 callback that stops training once ``budget_s`` of wall time has
    passed; its ``stopped_early`` says whether it did (bench/accept_agents.py uses it too)."""
    from stable_baselines3.common.callbacks import BaseCallback

    class Budget(BaseCallback):
        def __init__(self) -> None:
            super().__init__()
            self.start = time.perf_counter()
            self.stopped_early = False

        def _on_step(self) -> bool:
            if time.perf_counter() - self.start > budget_s:
                self.stopped_early = True
                return False
            return True

    return Budget()


def train(out: Path, steps: int, budget_s: float, seed: int) -> dict:
    """Train the DQN, save it to ``out``; what happened as a dict."""
    import gymnasium
    import highway_env  # noqa: F401  (registers the environment ids)
    import torch
    from stable_baselines3 import DQN

    torch.set_num_threads(1)  # a 64x64 network: threads cost more than they give

    env = gymnasium.make(ENV_ID)
    model = DQN(
        "MlpPolicy", env,
        policy_kwargs=dict(net_arch=[64, 64]),
        learning_rate=5e-4,
        buffer_size=15000,
        learning_starts=200,
        batch_size=32,
        gamma=0.8,
        train_freq=1,
        gradient_steps=1,
        target_update_interval=50,
        exploration_fraction=0.7,
        seed=seed,
        device="cpu",
        verbose=0,
    )
    budget = budget_callback(budget_s)
    t0 = time.perf_counter()
    model.learn(total_timesteps=steps, callback=budget)
    took = time.perf_counter() - t0
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = out.with_name(out.name + ".tmp.zip")
    model.save(tmp)
    os.replace(tmp, out)
    env.close()
    return {"steps": int(model.num_timesteps), "seconds": took, "stopped_early": budget.stopped_early,
            "bytes": out.stat().st_size}


def crash_rate(model_path: Path, episodes: int) -> dict:
    """The model in highway-env itself: crashes over ``episodes`` episodes (seeds 1000, ...)."""
    import gymnasium
    import highway_env  # noqa: F401
    import torch
    from stable_baselines3 import DQN

    torch.set_num_threads(1)
    model = DQN.load(model_path, device="cpu")
    env = gymnasium.make(ENV_ID)
    crashes, lengths, speeds = 0, [], []
    for i in range(episodes):
        obs, _ = env.reset(seed=1000 + i)
        done = truncated = False
        n = 0
        while not (done or truncated):
            action, _ = model.predict(obs, deterministic=True)
            obs, _, done, truncated, info = env.step(action)
            speeds.append(float(info["speed"]))
            n += 1
        crashes += bool(info["crashed"])
        lengths.append(n)
    env.close()
    return {"episodes": episodes, "crashes": crashes, "rate": crashes / episodes,
            "mean_length_s": sum(lengths) / len(lengths) / env.unwrapped.config["policy_frequency"],
            "mean_speed_mps": sum(speeds) / len(speeds)}


def campaign(driver: str, modules: list[str], report: Path, samples: int, seed: int,
             workers: int) -> tuple[list[dict], float]:
    """Run the scenario modules with ``driver`` as the ego; the summary's rows and wall time."""
    cmd = [sys.executable, "-m", "pytest", *modules, "-m", "scenario", "-q", "-p", "no:cacheprovider",
           f"--avs-seed={seed}", f"--avs-samples={samples}", f"--avs-driver={driver}",
           "--avs-db=none", f"--avs-report={report}", "--avs-shrink-budget=0"]
    if workers > 1:
        cmd += ["-n", str(workers)]
    print("$", " ".join(cmd), flush=True)
    t0 = time.perf_counter()
    done = subprocess.run(cmd, cwd=HERE.parent, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                          text=True)
    took = time.perf_counter() - t0
    tail = "\n".join(done.stdout.splitlines()[-3:])
    print(tail, flush=True)
    if done.returncode not in (0, 1):  # 1: counterexamples found, as expected
        raise SystemExit(f"the campaign with {driver} ended with status {done.returncode}:\n"
                         + done.stdout[-4000:])
    with open(report / "summary.json") as f:
        rows = json.load(f)["tests"]
    avoidable: dict[tuple[str, str], int] = {}
    with open(report / "errors.jsonl") as f:
        for line in f:
            case = json.loads(line)
            if (case.get("avoidable") or {}).get("collision") is True:
                key = (case["test"], case["sampler"])
                avoidable[key] = avoidable.get(key, 0) + 1
    for r in rows:
        r["avoidable_collisions"] = avoidable.get((r["test"], r["sampler"]), 0)
    return rows, took


def _name(test: str) -> str:
    return test.split("::")[-1].removeprefix("test_")


def tables(trained: dict | None, crash: dict, runs: dict[str, list[dict]],
           times: dict[str, float], load: float, command: str) -> str:
    lines = []
    if trained is not None:
        early = " (stopped by the time budget)" if trained["stopped_early"] else ""
        lines.append(f"Trained: {trained['steps']} steps in {trained['seconds']:.0f} s{early}; "
                     f"model {trained['bytes'] / 1024:.0f} KB.")
        lines.append("")
    lines.append(f"**In highway-env** (`{ENV_ID}`, default config, {crash['episodes']} episodes "
                 f"of 30 s, deterministic actions): the model crashes in **{crash['crashes']} of "
                 f"{crash['episodes']} episodes ({crash['rate']:.0%})**, mean episode "
                 f"{crash['mean_length_s']:.1f} s, mean speed {crash['mean_speed_mps']:.1f} m/s.")
    lines.append("")
    lines.append("**In the plugin's campaigns** — counterexamples / samples, then the cases "
                 "violating each metric; a collision is *avoidable* when the careful reference "
                 "driver, in the ego's seat of the same case, has none:")
    lines.append("")
    drivers = list(runs)
    head = "| scenario | sampler |" + "".join(f" {d} |" for d in drivers)
    lines += [head, "|---|---|" + "---|" * len(drivers)]
    keys = []
    for rows in runs.values():
        for r in rows:
            k = (_name(r["test"]), r["sampler"])
            if k not in keys and r["sampler"] != "replay":
                keys.append(k)
    for k in keys:
        cells = []
        for d in drivers:
            r = next((r for r in runs[d] if (_name(r["test"]), r["sampler"]) == k), None)
            if r is None:
                cells.append("–")
                continue
            n = r["samples"]
            parts = []
            for m, c in r["violations"].items():
                if not c:
                    continue
                extra = f" ({r['avoidable_collisions']} avoidable)" if m == "collision" else ""
                parts.append(f"{m} {c}{extra}")
            if r.get("errors"):
                parts.append(f"{r['errors']} errors")
            cells.append(f"**{r['counterexamples']}**/{n}" + (": " + ", ".join(parts) if parts else ""))
        lines.append(f"| {k[0]} | {k[1]} |" + "".join(f" {c} |" for c in cells))
    lines.append("")
    lines.append("Campaign wall time (`-n 2`): "
                 + ", ".join(f"{d} {t:.0f} s" for d, t in times.items())
                 + f"; load average {load:.1f} when the script started.")
    lines.append("")
    lines.append(f"Made with `{command}`.")
    return "\n".join(lines)


def write_readme(text: str) -> None:
    path = HERE / "README.md"
    old = path.read_text()
    if MARK_BEGIN not in old or MARK_END not in old:
        raise SystemExit(f"{path} lacks the {MARK_BEGIN} / {MARK_END} markers")
    head, rest = old.split(MARK_BEGIN, 1)
    _, tail = rest.split(MARK_END, 1)
    new = f"{head}{MARK_BEGIN}\n{text}\n{MARK_END}{tail}"
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_text(new)
    os.replace(tmp, path)


def main(argv: list[str] | None = None) -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--out", type=Path, default=DEFAULT_OUT, help="where the model is saved")
    p.add_argument("--steps", type=int, default=6000, help="training steps (default 6000)")
    p.add_argument("--budget", type=float, default=570.0,
                   help="stop training after this many seconds (default 570)")
    p.add_argument("--seed", type=int, default=0, help="seed of training and of the campaigns")
    p.add_argument("--no-train", action="store_true", help="measure the model saved at --out")
    p.add_argument("--episodes", type=int, default=50, help="highway-env episodes (default 50)")
    p.add_argument("--modules", nargs="+", default=["example_tests/test_trained_agent.py"],
                   help="scenario modules of the campaigns (default: the trained-agent example)")
    p.add_argument("--samples", type=int, default=30, help="cases per test and sampler (default 30)")
    p.add_argument("--drivers", default="sb3,autopilot,idm",
                   help="egos of the campaigns: sb3 (the model), autopilot, idm, careful")
    p.add_argument("-n", "--workers", type=int, default=2, help="pytest-xdist workers (default 2)")
    p.add_argument("--report-root", type=Path, default=Path("/tmp/avs-train-dqn"),
                   help="where the campaigns' reports go (one folder per driver)")
    p.add_argument("--readme", action="store_true", help="write the tables into example_tests/README.md")
    args = p.parse_args(argv)

    out = args.out.resolve()
    load = os.getloadavg()[0]
    trained = None
    if not args.no_train:
        print(f"training a DQN on {ENV_ID}: {args.steps} steps, at most {args.budget:.0f} s", flush=True)
        trained = train(out, args.steps, args.budget, args.seed)
        print(f"  {trained}", flush=True)
    elif not out.is_file():
        raise SystemExit(f"no model at {out}: train one first (without --no-train)")
    print(f"crash rate in highway-env over {args.episodes} episodes", flush=True)
    crash = crash_rate(out, args.episodes)
    print(f"  {crash}", flush=True)
    runs: dict[str, list[dict]] = {}
    times: dict[str, float] = {}
    for name in [d.strip() for d in args.drivers.split(",") if d.strip()]:
        driver = f"sb3:{out}@{ENV_ID}" if name == "sb3" else name
        label = "DQN" if name == "sb3" else name
        rows, took = campaign(driver, args.modules, args.report_root / name, args.samples,
                              args.seed, args.workers)
        print(f"  {label}: {took:.0f} s", flush=True)
        runs[label] = rows
        times[label] = took
    cmd = "python example_tests/train_dqn.py" + (" --no-train" if args.no_train else "") + \
        (f" --modules {' '.join(args.modules)}" if args.modules != p.get_default("modules") else "") + \
        (f" --samples {args.samples}" if args.samples != 30 else "") + (" --readme" if args.readme else "")
    text = tables(trained, crash, runs, times, load, cmd)
    print()
    print(text)
    if args.readme:
        write_readme(text)


if __name__ == "__main__":
    main()

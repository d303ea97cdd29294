#!/usr/bin/env python3
"""Search power on real scenarios: our samplers against VerifAI 2.2.0's and NSGA-II (pymoo).

Issue 20 item 1. Three scenarios, the ego driven by highway-env's IDM ("idm" driver):

* ``following`` — example 2 (``example_tests/test_02_vehicle_following.py``, 5 parameters);
* ``left_turn`` — example 7 (``example_tests/test_07_oncoming_left_turn.py``, 5 parameters);
* ``cut_in``    — a highway cut-in defined below (5 parameters): a car in the adjacent lane,
  ahead of the ego, changes into the ego's lane.

Every scenario keeps its monitors (progress, distance, ttc, lane_keeping, collision) and its
priority (collision > distance > ttc > progress > lane_keeping). The counterexample searched
for (the *target*) is a violation of the top-priority metric, ``collision``, in all three; a
failure of any other monitor is a failure (it counts for the failure modes) but not the
target. Random sampling hits a collision in about 20 % of left_turn cases, 4 % of cut_in
cases and none of 1,000 following cases (there ``ttc`` fails in 5 %). So example 2
is run a second time as ``following_ttc``: the same simulations (shared cache), searching
for a ttc violation, with ttc put first in the priority order the tools are told.

Every tool searches the unit cube of the scenario's parameters (mapped by the scenario's own
FeatureSpace) and is answered by the same simulator in this process:

* ours — random, halton, ce, mab, sa, bo, told the whole ρ mapping with the scenario's
  priority order, as the plugin tells them;
* VerifAI 2.2.0 — halton, ce, mab on the scalar ρ of the target (VerifAI's single-objective
  interface), and mab in its multi-objective mode (the ρ vector with the same priority as a
  chain graph), in its own virtual environment (``--venv``, default ``~/.venvs/verifai``);
* NSGA-II — pymoo's ``NSGA2`` configured with OpenSBT's default search configuration
  (population 20, random initial population, SBX crossover prob 0.7 eta 20, polynomial
  mutation prob 1/d eta 15, duplicates eliminated), driven through pymoo's ask/tell
  interface, on the ρ vector of the five monitors (``nsga2``, OpenSBT's multi-objective
  use) and on the target's ρ alone (``nsga2-1``), in the same virtual environment as VerifAI.

The external tools run in one subprocess of this script (``--worker``) that asks points on
its stdout and reads ρ on its stdin (JSON lines); ρ sent out is clipped to [-100, 100] (no
infinities on the wire, and a bounded objective for NSGA-II's crowding distance). Within one
seed, every case of a scenario gets the same simulation seed (``case.rng``: the lead's
wobble in example 2), so all tools face the same deterministic objective; simulations are
cached by (scenario, parameters, simulation seed).

Measured per scenario and tool:

1. samples to the first counterexample (target violated): mean and median over ``--seeds``
   seeds (default 20), budget 300 (a seed that finds none counts as 300; "not found" says
   how many);
2. over ``--mode-seeds`` seeds (default 5), 200 samples each: distinct failure modes, and
   ε-coverage of the 200 points (``report.coverage.epsilon_coverage``, tol 0.01: the
   report's ε over the unit cube of the continuous parameters). A *failure mode* is the set
   of violated monitors plus the critical agent (the agent named by the highest-priority
   violated monitor), over every failing case (any monitor violated, not only the target).

Usage (repository root; the venv once, see bench/README.md "Search on real scenarios"):

    python bench/bench_search.py            # full: 20 seeds x 300, 5 seeds x 200
    python bench/bench_search.py --quick    # 2 seeds, 1 mode seed
    python bench/bench_search.py --report results.json   # the tables of a --json run again
"""

from __future__ import annotations

import os

for _v in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_v, "1")

import argparse  # noqa: E402
import importlib.util  # noqa: E402
import json  # noqa: E402
import math  # noqa: E402
import statistics  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
ANCHOR = Path("/work/shared/anchors/verifai_samplers_bench.py")
CAP = 100.0  # |ρ| sent to the external tools is clipped to this
NSGA_POP = 20

OURS = ["random", "halton", "ce", "mab", "sa", "bo"]
THEIRS = ["verifai-halton", "verifai-ce", "verifai-mab", "verifai-mab-multi", "nsga2", "nsga2-1"]
# which external tools get the ρ vector (the others the target's ρ)
VECTOR = {"verifai-mab-multi", "nsga2"}


# == the external side (runs inside the VerifAI/pymoo venv; imports nothing of the project) ====

def _verifai_points(kind: str, d: int, m: int, seed: int):
    spec = importlib.util.spec_from_file_location("anchor_bench", ANCHOR)
    anchor = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(anchor)
    from verifai.features import Box, Feature, FeatureSpace
    from verifai.samplers import FeatureSampler

    anchor.seed_all(seed)
    space = FeatureSpace({"x": Feature(Box(*[(0, 1)] * d))})
    if kind == "mab-multi":
        import networkx as nx

        p = anchor.ce_like_params(0.0, 5, 0.9)  # VerifAI's mab defaults, plus the graph
        g = nx.DiGraph()
        g.add_nodes_from(range(m))
        g.add_edges_from((i, i + 1) for i in range(m - 1))
        p.priority_graph = g
        sampler = FeatureSampler.multiArmedBanditSamplerFor(space, p)
    else:
        sampler = anchor.SAMPLERS[kind](space)
    while True:
        x, feed = anchor.draw(sampler)
        f = yield [float(v) for v in x]
        feed(tuple(f) if isinstance(f, list) else f)


def _nsga_points(d: int, m: int, seed: int):
    from pymoo.algorithms.moo.nsga2 import NSGA2
    from pymoo.core.evaluator import Evaluator
    from pymoo.core.problem import Problem
    from pymoo.operators.crossover.sbx import SBX
    from pymoo.operators.mutation.pm import PM
    from pymoo.operators.sampling.rnd import FloatRandomSampling
    from pymoo.problems.static import StaticProblem

    problem = Problem(n_var=d, n_obj=m, xl=np.zeros(d), xu=np.ones(d))
    # OpenSBT's default search configuration (population 20, crossover 0.7 with eta 20,
    # mutation 1/n_var with eta 15), passed to pymoo's NSGA2 the way OpenSBT passes it
    algorithm = NSGA2(pop_size=NSGA_POP, sampling=FloatRandomSampling(),
                      crossover=SBX(prob=0.7, eta=20), mutation=PM(prob=1.0 / d, eta=15),
                      eliminate_duplicates=True)
    algorithm.setup(problem, termination=("n_eval", 10 ** 9), seed=seed, verbose=False)
    while True:
        pop = algorithm.ask()
        F = []
        for x in pop.get("X"):
            f = yield [float(v) for v in x]
            F.append(f if isinstance(f, list) else [f])
        Evaluator().eval(StaticProblem(problem, F=np.asarray(F, float)), pop)
        algorithm.tell(infills=pop)


def worker() -> None:
    """Serve points: {"op": "start", tool, d, m, seed} -> {"x"}; {"op": "tell", f, more} ->
    {"x"} while more; {"op": "quit"}."""
    import warnings

    warnings.filterwarnings("ignore")
    gen = None
    for line in sys.stdin:
        msg = json.loads(line)
        if msg["op"] == "quit":
            return
        if msg["op"] == "start":
            tool, d, m, seed = msg["tool"], msg["d"], msg["m"], msg["seed"]
            if tool.startswith("nsga2"):
                gen = _nsga_points(d, m, seed)
            else:
                gen = _verifai_points(tool.removeprefix("verifai-"), d, m, seed)
            x = next(gen)
        elif msg["more"]:
            x = gen.send(msg["f"])
        else:
            gen = None
            continue
        sys.stdout.write(json.dumps({"x": x}) + "\n")
        sys.stdout.flush()


# == the scenarios and the simulator (our venv) =============================================

def cut_in_scenario():
    """The highway cut-in (defined here, declared like any scenario test)."""
    from pytest_avscenario import Uniform, scenario
    from pytest_avscenario.monitors import collision, distance, lane_keeping, progress, ttc
    from pytest_avscenario.sim import behaviors as b

    @scenario(
        ego_speed=Uniform(8.0, 14.0, nominal=11.0),  # [m/s] ego, also its IDM target speed
        dx=Uniform(10.0, 60.0, nominal=30.0),  # [m] cutter's centre ahead of the ego's
        dv=Uniform(-4.0, 2.0, nominal=0.0),  # [m/s] cutter's speed minus the ego's
        cut_at=Uniform(0.5, 5.0, nominal=3.0),  # [s] when the cutter starts its lane change
        cut_duration=Uniform(1.5, 4.0, nominal=3.0),  # [s] about how long the change takes
        samples=60, sampler=["halton", "mab"],
        monitors=[progress(11.0), distance(5.0), ttc(2.0), lane_keeping(0.5), collision()],
        priority=["collision", "distance", "ttc", "progress", "lane_keeping"],
    )
    def test_cut_in(case, world):
        road = world.straight_road(lanes=2, length=600, speed_limit=16.0)
        world.ego(road.lane(1), s=50.0, speed=case.ego_speed)
        world.car(road.lane(0), s=50.0 + case.dx, speed=case.ego_speed + case.dv,
                  behavior=b.change_lane("right", at=case.cut_at, duration=case.cut_duration))
        world.run(seconds=12)

    return test_cut_in


def load_scenarios() -> dict:
    sys.path.insert(0, str(ROOT / "example_tests"))
    import test_02_vehicle_following as ex2
    import test_07_oncoming_left_turn as ex7

    return {"following": (ex2.test_vehicle_following, "collision"),
            "left_turn": (ex7.test_oncoming_left_turn, "collision"),
            "cut_in": (cut_in_scenario(), "collision"),
            # example 2 again, searching for its common failure: ttc put first in the
            # priority order the tools rank by (same simulations, shared cache)
            "following_ttc": (ex2.test_vehicle_following, "ttc")}


CACHE: dict = {}  # (scenario function, parameters, simulation seed) -> monitor results


class Simulator:
    """One scenario's objective: parameters -> monitor results, cached."""

    def __init__(self, name: str, func, target: str, driver: str = "idm"):
        from pytest_avscenario.monitors import MonitorSet
        from pytest_avscenario.space import FeatureSpace

        spec = func.pytestmark[0].args[0]
        self.name, self.func, self.target, self.driver = name, func, target, driver
        self.space = FeatureSpace.coerce(spec.parameters)
        self.monitors = MonitorSet(list(spec.monitors), priority=spec.priority)
        order = list(self.monitors.priority_order)
        self.order = order  # the scenario's priority, highest first
        self.metrics = [target] + [n for n in order if n != target]  # what the tools rank
        self.cache = CACHE
        self.sims = 0
        self.cpu = 0.0
        self.violations = {n: 0 for n in order}
        self.errors = 0

    def __call__(self, params: dict, sim_seed: int) -> dict:
        key = (self.func.__name__, tuple(round(float(params[n]), 12) for n in self.space.names),
               sim_seed)
        hit = self.cache.get(key)
        if hit is not None:
            return hit
        from pytest_avscenario.case import Case
        from pytest_avscenario.runner import run_case
        from pytest_avscenario.sim import World

        case = Case(params, 0, sim_seed, "bench", test=self.name)
        t0 = time.process_time()
        out = run_case(self.func, ("case", "world"), {}, case, self.monitors,
                       lambda c: World(seed=c.seed, rng=c.rng, driver=self.driver, name=self.name))
        self.cpu += time.process_time() - t0
        self.sims += 1
        if out.verdict == "error":
            self.errors += 1
            rec = {"error": out.error, "rho": None, "violated": [], "mode": None}
        else:
            violated = [n for n in self.order if n in out.violated]
            for n in violated:
                self.violations[n] += 1
            mode = None
            if violated:
                mode = ("+".join(violated), out.results[violated[0]].agent)
            rec = {"rho": dict(out.rho), "violated": violated, "mode": mode}
        self.cache[key] = rec
        return rec

    def is_ce(self, rec: dict) -> bool:
        return rec["rho"] is not None and rec["rho"][self.target] < 0

    def feedback(self, rec: dict, vector: bool):
        """What an external tool is told: the target's ρ or the ρ vector (self.metrics),
        clipped to ±CAP; an errored case as a harmless +CAP."""
        if rec["rho"] is None:
            return [CAP] * len(self.metrics) if vector else CAP
        clip = lambda v: float(min(max(v, -CAP), CAP))  # noqa: E731
        if vector:
            return [clip(rec["rho"][n]) for n in self.metrics]
        return clip(rec["rho"][self.target])


class External:
    """The worker subprocess in the VerifAI/pymoo venv."""

    def __init__(self, python: Path):
        self.proc = subprocess.Popen([str(python), __file__, "--worker"], stdin=subprocess.PIPE,
                                     stdout=subprocess.PIPE, text=True, bufsize=1,
                                     env=dict(os.environ))

    def _send(self, msg: dict) -> None:
        self.proc.stdin.write(json.dumps(msg) + "\n")
        self.proc.stdin.flush()

    def _recv(self) -> list:
        line = self.proc.stdout.readline()
        if not line:
            sys.exit(f"the external worker ended (exit {self.proc.wait()}); run it by hand "
                     f"to see why: {self.proc.args[0]} {__file__} --worker")
        return json.loads(line)["x"]

    def points(self, tool: str, d: int, m: int, seed: int):
        """A generator of unit points; send it the feedback of each."""
        self._send({"op": "start", "tool": tool, "d": d, "m": m, "seed": seed})
        x = self._recv()
        try:
            while True:
                f = yield x
                self._send({"op": "tell", "f": f, "more": True})
                x = self._recv()
        finally:
            self._send({"op": "tell", "f": None, "more": False})

    def close(self) -> None:
        self._send({"op": "quit"})
        self.proc.wait(timeout=30)


def run_tool(sim: Simulator, tool: str, seed: int, n: int, stop_at_ce: bool,
             ext: External | None) -> dict:
    """``n`` samples of ``tool`` (or up to the first target counterexample)."""
    from pytest_avscenario import samplers

    sim_seed = 7919 * seed + 17
    units, recs = [], []
    if tool in OURS:
        s = (samplers.make(tool, sim.space, seed=seed, metrics=sim.metrics, priority=sim.metrics)
             if samplers.base.is_active(tool) else samplers.make(tool, sim.space, seed=seed))
        for _ in range(n):
            p = s.ask()
            rec = sim(p, sim_seed)
            s.tell(p, None if rec["rho"] is None else rec["rho"])
            units.append(sim.space.to_unit(p))
            recs.append(rec)
            if stop_at_ce and sim.is_ce(rec):
                break
    else:
        vector = tool in VECTOR
        gen = ext.points(tool, sim.space.d, len(sim.metrics) if vector else 1, seed)
        x = next(gen)
        for i in range(n):
            u = np.clip(np.asarray(x, float), 0.0, 1.0)
            p = sim.space.from_unit(u)
            rec = sim(p, sim_seed)
            units.append(sim.space.to_unit(p))
            recs.append(rec)
            if (stop_at_ce and sim.is_ce(rec)) or i == n - 1:
                break
            x = gen.send(sim.feedback(rec, vector))
        gen.close()
    first = next((i + 1 for i, r in enumerate(recs) if sim.is_ce(r)), None)
    return {"units": np.asarray(units), "recs": recs, "first": first}


# == main ===================================================================================

def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--worker", action="store_true", help=argparse.SUPPRESS)
    ap.add_argument("--quick", action="store_true", help="2 seeds, 1 mode seed")
    ap.add_argument("--venv", default=str(Path.home() / ".venvs" / "verifai"),
                    help="venv with verifai==2.2.0 and pymoo (default ~/.venvs/verifai)")
    ap.add_argument("--seeds", type=int, default=20, help="seeds for the first counterexample")
    ap.add_argument("--budget", type=int, default=300)
    ap.add_argument("--mode-seeds", type=int, default=5, help="seeds for modes and coverage")
    ap.add_argument("--mode-samples", type=int, default=200)
    ap.add_argument("--scenarios", default="following,left_turn,cut_in,following_ttc")
    ap.add_argument("--tools", default=",".join(OURS + THEIRS))
    ap.add_argument("--json", help="also write the raw results here")
    ap.add_argument("--report", metavar="JSON", help="print the tables of an earlier --json run")
    args = ap.parse_args()
    if args.worker:
        worker()
        return
    if args.report:
        saved = json.loads(Path(args.report).read_text())
        for key in ("seeds", "budget", "mode_seeds", "mode_samples"):
            setattr(args, key, saved["args"][key])
        report(saved["results"], saved["args"]["tools"], args, saved["wall_s"], live=False)
        return
    if args.quick:
        args.seeds, args.mode_seeds = 2, 1

    sys.path.insert(0, str(ROOT))
    from pytest_avscenario.report.coverage import epsilon_coverage

    tools = args.tools.split(",")
    unknown = set(tools) - set(OURS + THEIRS)
    if unknown:
        sys.exit(f"unknown tool(s) {sorted(unknown)}; choose from {OURS + THEIRS}")
    ext = None
    if any(t in THEIRS for t in tools):
        py = Path(args.venv) / "bin" / "python"
        if not py.exists():
            sys.exit(f"no venv at {args.venv}: python3 -m venv {args.venv} && {args.venv}/bin/pip "
                     f"install verifai==2.2.0 pymoo==0.6.1.5 (or pass --tools "
                     f"{','.join(OURS)})")
        ext = External(py)
    scen = load_scenarios()
    names = args.scenarios.split(",")
    started = time.time()
    print(f"# bench_search: {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime(started))}, "
          f"load {os.getloadavg()[0]:.1f}; first CE: {args.seeds} seeds, budget {args.budget}; "
          f"modes/coverage: {args.mode_seeds} seeds x {args.mode_samples}", flush=True)
    results: dict = {}
    for sname in names:
        func, target = scen[sname]
        sim = Simulator(sname, func, target)
        res = results[sname] = {}
        t_s = time.time()
        for tool in tools:
            t0 = time.time()
            modes, eps, ces, fails, union = [], [], [], [], set()
            for seed in range(args.mode_seeds):
                r = run_tool(sim, tool, seed, args.mode_samples, False, ext)
                ms = {rec["mode"] for rec in r["recs"] if rec["mode"] is not None}
                union |= ms
                modes.append(len(ms))
                ces.append(sum(sim.is_ce(rec) for rec in r["recs"]))
                fails.append(sum(rec["mode"] is not None for rec in r["recs"]))
                eps.append(epsilon_coverage(r["units"], tol=0.01))
            firsts = []
            for seed in range(args.seeds):
                f = run_tool(sim, tool, seed, args.budget, True, ext)["first"]
                firsts.append(f)
            found = [f if f is not None else args.budget for f in firsts]
            res[tool] = dict(firsts=firsts, mean=statistics.mean(found),
                             median=statistics.median(found),
                             miss=sum(f is None for f in firsts), modes=modes,
                             modes_mean=statistics.mean(modes), modes_union=sorted((list(m) for m in union), key=str),
                             ces=ces, fails=fails, eps=statistics.mean(eps))
            print(f"  {sname:9s} {tool:18s} first CE mean {res[tool]['mean']:6.1f} median "
                  f"{res[tool]['median']:6.1f} miss {res[tool]['miss']:2d}  modes "
                  f"{res[tool]['modes_mean']:.1f} (union {len(union)})  eps {res[tool]['eps']:.3f}"
                  f"  [{time.time() - t0:.0f} s, {sim.sims} sims so far]", flush=True)
        res["_sim"] = dict(target=target, sims=sim.sims, cpu_s=sim.cpu, errors=sim.errors,
                           violations=sim.violations, wall_s=time.time() - t_s,
                           d=sim.space.d, metrics=sim.metrics)
    if ext is not None:
        ext.close()
    wall = time.time() - started
    if args.json:
        saved = {"args": dict(vars(args), tools=tools), "wall_s": wall, "results": results}
        Path(args.json).write_text(json.dumps(saved, indent=1, default=str))
    report(results, tools, args, wall)


def label(tool: str) -> str:
    return tool if tool in THEIRS else f"ours {tool}"


def summary(results: dict, tools: list, args) -> None:
    """The tables of bench/README.md: one row per tool, one column per scenario."""
    names = list(results)
    head = "| tool | " + " | ".join(names) + " |\n|---|" + "--:|" * len(names)
    print(f"\nSamples to the first counterexample, mean / median (not found of {args.seeds}; "
          f"budget {args.budget}, a miss counts as {args.budget}):\n")
    print(head)
    for tool in tools:
        cells = [f"{r['mean']:.1f} / {r['median']:.1f}" + (f" ({r['miss']})" if r["miss"] else "")
                 for r in (results[n][tool] for n in names)]
        print(f"| {label(tool)} | " + " | ".join(cells) + " |")
    print(f"\nIn {args.mode_samples} samples, mean over {args.mode_seeds} seeds: distinct failure "
          f"modes (their union over the seeds), target counterexamples, ε-coverage:\n")
    print(head)
    for tool in tools:
        cells = [f"{r['modes_mean']:.1f} ({len(r['modes_union'])}) · "
                 f"{statistics.mean(r['ces']):.0f} · {r['eps']:.2f}"
                 for r in (results[n][tool] for n in names)]
        print(f"| {label(tool)} | " + " | ".join(cells) + " |")
    print("\nGoals (issue 20 item 2), ratios of means in this run:\n")
    print("| scenario | our best (mean) | VerifAI mab | ratio (≤ 0.33) | best NSGA-II | "
          "ratio (≤ 0.5) | modes: ours / VerifAI mab / NSGA-II (≥ both) |\n|---|---|--:|--:|--:|--:|---|")
    for n in names:
        res = results[n]
        ours = [t for t in tools if t in OURS]
        best = min(ours, key=lambda t: res[t]["mean"])
        b, v = res[best], res.get("verifai-mab")
        nb = min((t for t in ("nsga2", "nsga2-1") if t in res), key=lambda t: res[t]["mean"],
                 default=None)
        if v is None or nb is None:
            continue
        nm = max(res[t]["modes_mean"] for t in ("nsga2", "nsga2-1") if t in res)
        ok = lambda c: "met" if c else "**missed**"  # noqa: E731
        print(f"| {n} | {best} ({b['mean']:.1f}) | {v['mean']:.1f} | {b['mean'] / v['mean']:.2f} "
              f"{ok(b['mean'] <= v['mean'] / 3)} | {nb} {res[nb]['mean']:.1f} | "
              f"{b['mean'] / res[nb]['mean']:.2f} {ok(b['mean'] <= res[nb]['mean'] / 2)} | "
              f"{b['modes_mean']:.1f} / {v['modes_mean']:.1f} / {nm:.1f} "
              f"{ok(b['modes_mean'] >= max(v['modes_mean'], nm))} |")


def report(results: dict, tools: list, args, wall: float, live: bool = True) -> None:
    print(f"\nwall {wall / 60:.1f} min" + (f", load now {os.getloadavg()[0]:.1f}" if live else ""))
    summary(results, tools, args)
    for sname, res in results.items():
        s = res["_sim"]
        print(f"\n### {sname}: target `{s['target']}`, {s['d']} parameters; {s['sims']} "
              f"simulations not in the cache ({1000 * s['cpu_s'] / max(s['sims'], 1):.1f} ms CPU each), "
              f"{s['errors']} errors; cases violating each monitor: "
              + ", ".join(f"{k} {v}" for k, v in s["violations"].items()))
        print(f"\n| tool | first CE mean | median | not found (of {args.seeds}) | modes in "
              f"{args.mode_samples} (mean) | modes, union of {args.mode_seeds} seeds | "
              f"target CEs in {args.mode_samples} | ε-coverage |")
        print("|---|--:|--:|--:|--:|--:|--:|--:|")
        for tool in tools:
            r = res[tool]
            print(f"| {label(tool)} | {r['mean']:.1f} | {r['median']:.1f} | {r['miss']} | "
                  f"{r['modes_mean']:.1f} | {len(r['modes_union'])} | "
                  f"{statistics.mean(r['ces']):.1f} | {r['eps']:.3f} |")
        ours = [t for t in tools if t in OURS and t not in ("random", "halton")]
        if not ours:
            continue
        best = min(ours, key=lambda t: res[t]["mean"])
        b = res[best]
        lines = [f"best of ours by mean first CE: {best} ({b['mean']:.1f})"]
        if "verifai-mab" in res:
            v = res["verifai-mab"]
            lines.append(f"vs VerifAI mab {v['mean']:.1f}: ratio {b['mean'] / v['mean']:.2f} "
                         f"(goal <= 0.33: {'met' if b['mean'] <= v['mean'] / 3 else 'MISSED'})")
        nsga = [t for t in ("nsga2", "nsga2-1") if t in res]
        if nsga:
            nb = min(nsga, key=lambda t: res[t]["mean"])
            n = res[nb]
            lines.append(f"vs NSGA-II (best variant {nb}) {n['mean']:.1f}: ratio "
                         f"{b['mean'] / n['mean']:.2f} "
                         f"(goal <= 0.5: {'met' if b['mean'] <= n['mean'] / 2 else 'MISSED'})")
        others = [t for t in ("verifai-mab", "nsga2", "nsga2-1") if t in res]
        if others:
            top = max(res[t]["modes_mean"] for t in others)
            lines.append(f"modes: {best} {b['modes_mean']:.1f} vs best of VerifAI mab / NSGA-II "
                         f"{top:.1f} (goal >=: {'met' if b['modes_mean'] >= top else 'MISSED'}); "
                         f"most of ours: "
                         + max((f"{res[t]['modes_mean']:.1f} ({t})" for t in tools if t in OURS),
                               key=lambda z: float(z.split()[0])))
        for line in lines:
            print(f"* {line}")
        print("\nmodes seen (union over tools):",
              sorted({tuple(m) for t in tools for m in res[t]["modes_union"]}, key=str))
        for tool in tools:
            print(f"  firsts {tool}: {res[tool]['firsts']}")


if __name__ == "__main__":
    main()

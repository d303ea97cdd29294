"""Turn the report of example-suite runs into the Markdown tables of README.md.

    python example_tests/results_table.py avs-report                     # one run
    python example_tests/results_table.py autopilot=avs-report idm=/tmp/idm-report
    python example_tests/results_table.py --failures avs-report          # worst case per metric
    python example_tests/results_table.py --modules avs-report           # cases, failed per module

Reads ``summary.json`` (the paper's table: samples, violations per metric, epsilon) and, with
``--failures``, ``errors.jsonl`` (one row per case) to list for every scenario and metric how
many cases violated it and the parameters of the most violating one.
"""

from __future__ import annotations

import argparse
import json
import math
import os

SHORT = {"progress": "Prog", "distance": "Dist", "ttc": "TTC", "lane_keeping": "Lane",
         "collision": "Coll", "school_bus": "Bus", "parked": "Park", "clearance": "Clear",
         "ran_stop": "Stop", "post_encroachment_time": "PET", "off_road": "Off"}
EXTRA = ("collision", "school_bus", "parked", "clearance", "ran_stop", "post_encroachment_time", "off_road")


def _name(test: str) -> str:
    return test.split("/")[-1].split("::")[0].removesuffix(".py").removeprefix("test_")


def summary(path: str) -> list[dict]:
    with open(os.path.join(path, "summary.json")) as f:
        rows = json.load(f)["tests"]
    return sorted(rows, key=lambda r: (_name(r["test"]), r["sampler"] != "halton"))


def table(runs: list[tuple[str, str]]) -> str:
    lines = []
    head = "| scenario | sampler |"
    rule = "|---|---|"
    for label, _ in runs:
        head += f" {label}: n | cex (unavoid.) | Prog | Dist | TTC | Lane | other | ε |"
        rule += "--:|--:|--:|--:|--:|--:|---|--:|"
    lines += [head, rule]
    data = [{(_name(r["test"]), r["sampler"]): r for r in summary(p)} for _, p in runs]
    for key in sorted(set().union(*data)):
        if key[1] == "replay":
            continue
        line = f"| {key[0]} | {key[1]} |"
        for d in data:
            r = d.get(key)
            if r is None:
                line += " – | | | | | | | |"
                continue
            v = r["violations"]
            other = ", ".join(f"{SHORT[m]} {v[m]}" for m in EXTRA if m in v)
            eps = r.get("epsilon")
            missing = eps is None or (isinstance(eps, float) and math.isnan(eps))
            eps_s = "—" if missing else f"{eps:.2f}"
            cex = f"{r['counterexamples']}" + (f" ({r['unavoidable']})" if r.get("judged") else "")
            line += (f" {r['samples']} | {cex} | {v.get('progress', 0)} | {v.get('distance', 0)} |"
                     f" {v.get('ttc', 0)} | {v.get('lane_keeping', 0)} | {other} | {eps_s} |")
        lines.append(line)
    return "\n".join(lines)


def modules(path: str) -> str:
    """Per module: cases, failed (counterexamples), errors, passed (the rest)."""
    per: dict[str, list[int]] = {}
    for r in summary(path):
        if r["sampler"] == "replay":
            continue
        n = per.setdefault(r["test"].split("::")[0].split("/")[-1], [0, 0, 0])
        n[0] += r["cases"]
        n[1] += r["counterexamples"]
        n[2] += r["errors"]
    lines = ["| module | cases | failed | errors | passed |", "|---|--:|--:|--:|--:|"]
    for name, (cases, failed, errors) in per.items():
        lines.append(f"| `{name}` | {cases} | {failed} | {errors} | {cases - failed - errors} |")
    total = [sum(n[i] for n in per.values()) for i in range(3)]
    lines.append(f"| all | {total[0]} | {total[1]} | {total[2]} | {total[0] - total[1] - total[2]} |")
    return "\n".join(lines)


def failures(path: str) -> str:
    rows = []
    with open(os.path.join(path, "errors.jsonl")) as f:
        for line in f:
            rows.append(json.loads(line))
    out = []
    by_test: dict[str, list[dict]] = {}
    for r in rows:
        by_test.setdefault(_name(r["test"]), []).append(r)
    for name in sorted(by_test):
        rs = by_test[name]
        n_fail = sum(r["verdict"] == "fail" for r in rs)
        n_err = sum(r["verdict"] == "error" for r in rs)
        out.append(f"{name}: {n_fail}/{len(rs)} failed, {n_err} errors")
        metrics = sorted({m for r in rs for m in r["rho"]})
        for m in metrics:
            vals = [(r["rho"][m], r) for r in rs if isinstance(r["rho"].get(m), (int, float))]
            bad = [(v, r) for v, r in vals if v < 0]
            if not bad:
                continue
            v, r = min(bad, key=lambda t: t[0])
            ps = ", ".join(f"{k}={x:.3g}" if isinstance(x, float) else f"{k}={x}"
                           for k, x in r["params"].items())
            out.append(f"  {m}: {len(bad)} cases; worst rho={v:+.2f} "
                       f"({r['sampler']}-{r['index']:03d}: {ps})")
    return "\n".join(out)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("runs", nargs="+", help="DIR or LABEL=DIR of a report")
    ap.add_argument("--failures", action="store_true")
    ap.add_argument("--modules", action="store_true", help="cases, failed and passed per module")
    args = ap.parse_args()
    runs = [(r.split("=", 1) if "=" in r else (os.path.basename(r.rstrip("/")), r))
            for r in args.runs]
    if args.modules:
        for label, path in runs:
            print(f"## {label}\n{modules(path)}\n")
    elif args.failures:
        for label, path in runs:
            print(f"## {label}\n{failures(path)}\n")
    else:
        print(table(runs))


if __name__ == "__main__":
    main()

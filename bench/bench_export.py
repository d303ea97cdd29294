"""What exporting a counterexample costs (issue #30): the writers' import per process, the CPU
and bytes of one export per road kind, and ASAM's checkers' start-up against their per-file
cost. CPU times (``resource.getrusage``), so the figures hold on a loaded machine.

    python bench/bench_export.py [--qc-venv /tmp/avs-asam-qc-venv]

Prints:
* ``import``: CPU [s] of a fresh process loading scenariogeneration as the export does
  (``export._writers.load``: scipy.integrate and xmlschema deferred) and as a plain
  ``import scenariogeneration`` (the anchor), each after numpy and shapely (which the
  plugin's process has already);
* per case (a braking lead on a straight road, the oncoming left turn at the built
  intersection, a vehicle following on Town06): CPU [ms] of ``export_case`` (the second
  export in the process: the import is paid once) and the bytes of each file written;
* ``qc``: with ASAM's checkers installed, the CPU [s] of a checker process on one file and on
  all the files written here (``.ci/asam_qc_batch.py``): start-up vs per file.
"""

from __future__ import annotations

import argparse
import os
import resource
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "example_tests"))


def cpu() -> float:
    r = resource.getrusage(resource.RUSAGE_SELF)
    return r.ru_utime + r.ru_stime


def child_cpu(code: str) -> float:
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True, cwd=ROOT, env=dict(os.environ, PYTHONPATH=str(ROOT)))
    return float(out.stdout.strip().splitlines()[-1])


IMPORT = """
import resource, numpy, shapely
def cpu():
    r = resource.getrusage(resource.RUSAGE_SELF); return r.ru_utime + r.ru_stime
c0 = cpu()
{stmt}
print(cpu() - c0)
"""


def cases():

    from pytest_avscenario.case import Case
    from pytest_avscenario.sim import behaviors as b
    from pytest_avscenario.sim.world import World

    def blind(observation):
        return 0.0, 0.0

    w = World(7, driver=blind)
    road = w.straight_road(lanes=2, length=300)
    w.ego(road.lane(0), s=20, speed=15)
    w.car(road.lane(0), s=50, speed=10, behavior=b.brake_at(1.0, decel=6))
    w.run(seconds=6)
    yield "braking lead (straight)", w, {}
    from test_07_oncoming_left_turn import test_oncoming_left_turn

    case = Case(dict(d_ego=20.0, ego_speed=8.0, d_adv=20.0, adv_speed=7.0, adv_go_within=30.0),
                0, 5, "halton")
    w = World(5, rng=case.rng, driver=blind)
    test_oncoming_left_turn(case, w)
    yield "oncoming left turn (intersection)", w, dict(case.params)
    from test_maps_town06_following import test_town06_vehicle_following

    case = Case(dict(lane="11/0/4", gap=20.0, lead_speed=10.0, brake_at=2.0, lead_decel=5.0,
                     lead_final_speed=0.0), 0, 5, "halton")
    w = World(5, rng=case.rng)
    test_town06_vehicle_following(case, w)
    yield "vehicle following (Town06)", w, dict(case.params)


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--qc-venv", default="/tmp/avs-asam-qc-venv")
    args = ap.parse_args()
    deferred = child_cpu(IMPORT.format(
        stmt="from pytest_avscenario.export._writers import load; load()"))
    plain = child_cpu(IMPORT.format(stmt="import scenariogeneration"))
    print(f"import: {deferred:.2f} s CPU as the export loads it, {plain:.2f} s plain "
          f"({deferred / plain:.2f}x)")
    from pytest_avscenario.export import export_case

    out = Path(tempfile.mkdtemp(prefix="avs-bench-export-"))
    written = []
    for name, world, params in cases():
        export_case(world, params, out / "warm", "warm")  # the import and first-use costs
        c0 = cpu()
        res = export_case(world, params, out, name.split(" (")[0].replace(" ", "_"))
        ms = (cpu() - c0) * 1000
        sizes = ", ".join(f"{k} {os.path.getsize(v) / 1000:.0f} kB" for k, v in res.files.items())
        print(f"{name}: {ms:.0f} ms CPU; {sizes}")
        written += [v for k, v in res.files.items() if k in ("xosc", "xosc_1_0", "xodr")]
    py = Path(args.qc_venv) / "bin" / "python"
    if py.exists():
        batch = str(ROOT / ".ci" / "asam_qc_batch.py")
        t = []
        for files in (written[:1], written):
            r0 = resource.getrusage(resource.RUSAGE_CHILDREN)
            subprocess.run([str(py), batch, *files], capture_output=True, check=False)
            r1 = resource.getrusage(resource.RUSAGE_CHILDREN)
            t.append(r1.ru_utime + r1.ru_stime - r0.ru_utime - r0.ru_stime)
        per = (t[1] - t[0]) / max(len(written) - 1, 1)
        print(f"qc: one checker process {t[0]:.2f} s CPU for 1 file, {t[1]:.2f} s for "
              f"{len(written)}: {per * 1000:.0f} ms CPU per further file")
    else:
        print(f"qc: no checkers at {args.qc_venv} (bash .ci/asam-qc.sh makes them)")


if __name__ == "__main__":
    main()

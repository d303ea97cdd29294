"""What having the plugin installed costs a pytest run that has no scenario test.

Runs ``python -m pytest -q -p no:cacheprovider`` on a one-test project (a plain
``def test_x(): pass``) ``--repeats`` times with the plugin and as many times with
``-p no:avscenario``, interleaved so machine load hits both alike, and prints the median
CPU and wall times, their difference and ratio, and which of the package's modules the run
with the plugin imported (listed at ``pytest_sessionfinish`` by a conftest). The package is
taken from this checkout (put first on ``PYTHONPATH``); ``--also DIR`` measures another
checkout (e.g. the one before a change) in the same interleaved runs:

    python bench/bench_load.py --repeats 15 --also /work/main
"""

from __future__ import annotations

import argparse
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent

CONFTEST = """
import sys

def pytest_sessionfinish(session):
    mods = sorted(m for m in sys.modules if m.startswith("pytest_avscenario"))
    with open("modules.txt", "w") as fh:
        fh.write("\\n".join(mods))
"""


def _cpu() -> float:
    use = resource.getrusage(resource.RUSAGE_CHILDREN)
    return use.ru_utime + use.ru_stime


def _run(project: Path, env: dict[str, str], plugin: bool) -> tuple[float, float]:
    """(wall [s], CPU [s]) of one pytest process; CPU time is what machine load disturbs least."""
    cmd = [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", "test_plain.py"]
    if not plugin:
        cmd[6:6] = ["-p", "no:avscenario"]
    cpu0, start = _cpu(), time.perf_counter()
    proc = subprocess.run(cmd, cwd=project, env=env, capture_output=True, text=True)
    wall, cpu = time.perf_counter() - start, _cpu() - cpu0
    if proc.returncode != 0:
        raise SystemExit(f"pytest failed:\n{proc.stdout}\n{proc.stderr}")
    return wall, cpu


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=15)
    parser.add_argument("--also", type=Path, default=None, help="another checkout to measure alike")
    args = parser.parse_args()

    def env_for(root: Path) -> dict[str, str]:
        env = dict(os.environ)
        env["PYTHONPATH"] = os.pathsep.join([str(root), env.get("PYTHONPATH", "")]).rstrip(os.pathsep)
        env.pop("PYTEST_ADDOPTS", None)
        return env

    env = env_for(ROOT)
    other = env_for(args.also) if args.also is not None else None
    also: list[tuple[float, float]] = []
    with tempfile.TemporaryDirectory() as tmp:
        project = Path(tmp)
        (project / "test_plain.py").write_text("def test_x():\n    pass\n")
        (project / "conftest.py").write_text(CONFTEST)
        _run(project, env, False)  # warm the disk cache and the .pyc files
        _run(project, env, True)  # (the bare run lists no module: it never imports the package)
        modules = (project / "modules.txt").read_text().split()
        with_plugin, bare = [], []
        for _ in range(args.repeats):
            with_plugin.append(_run(project, env, True))
            bare.append(_run(project, env, False))
            if other is not None:
                also.append(_run(project, other, True))
    print(f"python {sys.version.split()[0]}, {args.repeats} runs each, load average "
          f"{os.getloadavg()[0]:.1f}")
    for k, what in ((1, "CPU"), (0, "wall")):
        w = statistics.median(r[k] for r in with_plugin)
        b = statistics.median(r[k] for r in bare)
        print(f"{what:>4}: bare pytest (-p no:avscenario) median {b:.3f} s, with the plugin "
              f"{w:.3f} s: added {w - b:+.3f} s, ratio {w / b:.2f}")
        if also:
            a = statistics.median(r[k] for r in also)
            print(f"      {args.also} with its plugin: {a:.3f} s: added {a - b:+.3f} s, ratio {a / b:.2f}")
    report = [m for m in modules if m.startswith("pytest_avscenario.report")]
    print(f"package modules imported: {len(modules)}, of them report.*: {len(report)}")
    print("  " + " ".join(modules))


if __name__ == "__main__":
    main()

"""Stopping a large campaign: seconds from SIGTERM to the process's exit.

Run ``python bench/bench_stop.py`` (``--samples N``, default 100000; ``--at N`` rows, default
30000; ``--scaling`` instead stops campaigns of 2,000 and 20,000 cases at 90 % of their rows,
to show the stop does not grow with the campaign; ``--ctrl-c-xdist`` instead stops a 300-case
campaign under ``-n 2`` with Ctrl-C, see below). The script writes a one-parameter Halton
campaign with an empty body into a temp dir, runs ``pytest -p no:xdist --avs-db=none`` on it,
sends SIGTERM once ``errors.jsonl`` holds ``--at`` rows, and times the rest:

* *stop*: SIGTERM to exit, as a CI runner waits for it before its SIGKILL;
* *report*: the plugin's end-of-run work (``pytest_sessionfinish``: summary, index, cards,
  JUnit properties), from a conftest that stamps the hooks;
* *teardown*: the rest of pytest's end (its garbage collections while unconfiguring) and the
  interpreter's exit.

Issue #32 (item 6) measured 108 s for 32,210 rows of 100,000 before: the space plot divided
every value by a scale recomputed from all values (O(n²)), and pytest's five full garbage
collections at its end, then the interpreter's, walked the whole heap of a large session.
The machine is shared: the load average is printed with the numbers.

``--ctrl-c-xdist``: a 300-case campaign whose body sleeps 50 ms, run with ``-n 2`` in a process
group of its own; once ``errors.jsonl`` holds ``--at`` rows (default 60) the whole group gets
SIGINT, as a terminal's Ctrl-C reaches the controller and its workers (``--signal term``:
SIGTERM to the group; ``term-controller``: SIGTERM to pytest's process alone). Per run
(``--repeat``, default 3) it prints the seconds from the signal to exit (issue #33 item 6: ≤ 3 s),
the lines printed after it and how many are the one-per-worker lines, the rows against JUnit's
test cases, the CPU time spent after the interrupt (from a conftest's stamps at
``pytest_keyboard_interrupt`` and at exit in each process), and the modules the controller
imported after it. The runs use a warm bytecode cache in a temp dir (``--as-is`` keeps the
environment's setting); ``--preloaded`` makes the controller's end-of-run imports before the
run (what an interrupt costs once ``pytest_plugin/preload.py`` is done). ``--whole-xdist`` runs
the same campaign to its end (wall, CPU).
"""

from __future__ import annotations

import argparse
import os
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

TEST = """
from pytest_avscenario import scenario, Uniform

@scenario(x=Uniform(0, 1), samples={samples}, sampler="halton")
def test_x(case):
    pass
"""

CONFTEST = """
import time
import pytest

def _mark(name):
    with open("times.txt", "a") as f:
        f.write(f"{name} {time.monotonic():.3f}\\n")

@pytest.hookimpl(wrapper=True, tryfirst=True)
def pytest_sessionfinish(session):
    _mark("report_start")
    try:
        return (yield)
    finally:
        _mark("report_end")
"""


def rows(path: Path) -> int:
    try:
        with open(path / "avs-report" / "errors.jsonl", "rb") as fh:
            return sum(1 for _ in fh)
    except FileNotFoundError:
        return 0


def stop_once(samples: int, at: int) -> dict[str, float]:
    with tempfile.TemporaryDirectory(prefix="avs-bench-stop-") as tmp:
        path = Path(tmp)
        (path / "test_stop.py").write_text(TEST.format(samples=samples))
        (path / "conftest.py").write_text(CONFTEST)
        t0 = time.monotonic()
        proc = subprocess.Popen([sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider",
                                 "-p", "no:xdist", "--avs-db=none", "test_stop.py"], cwd=path,
                                stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        try:
            while (n := rows(path)) < at:
                if proc.poll() is not None:
                    raise SystemExit(f"the run ended before {at} rows ({n})")
                time.sleep(0.2)
            signalled = time.monotonic()
            proc.send_signal(signal.SIGTERM)
            status = proc.wait(900)
            ended = time.monotonic()
        finally:
            if proc.poll() is None:
                proc.kill()
                proc.wait()
        marks = dict(line.split() for line in (path / "times.txt").read_text().splitlines())
        start, end = float(marks["report_start"]), float(marks["report_end"])
        return {"rows": n, "run_s": signalled - t0, "stop_s": ended - signalled,
                "report_s": end - start, "teardown_s": ended - end, "status": status}


SLEEPING = """
import time
from pytest_avscenario import scenario, Uniform

@scenario(x=Uniform(0, 1), samples=300, sampler="halton")
def test_x(case):
    time.sleep(0.05)
"""

# Stamps in each process of the run (controller "ctl", workers "gw0"...): the process's CPU
# time and its modules when the interrupt reaches pytest, and its CPU time at exit; the
# controller also lists the packages it imported after the interrupt.
STAMPS = """
import atexit, json, os, sys, time
import pytest

_WHO = os.environ.get("PYTEST_XDIST_WORKER", "ctl")
_AT = {}

def _write(what, **data):
    with open(os.path.join(os.path.dirname(__file__), "stamps.jsonl"), "a") as f:
        f.write(json.dumps(dict(who=_WHO, what=what, t=time.monotonic(), cpu=time.process_time(), **data)) + "\\n")

@pytest.hookimpl(tryfirst=True)
def pytest_keyboard_interrupt(excinfo):
    _AT["modules"] = set(sys.modules)
    _write("interrupt", modules=len(sys.modules))

if _WHO == "ctl" and os.environ.get("AVS_BENCH_PRELOADED"):
    # --preloaded: the end-of-run imports made before the run, as the preload thread makes
    # them while the workers run when they have time to: what is left for the interrupt
    from pytest_avscenario.pytest_plugin import preload
    preload._import([*preload.REPORT_MODULES, *preload.COVERAGE_MODULES, *preload.HYPOTHESIS_MODULES])

@atexit.register
def _at_exit():
    if "modules" in _AT:
        new = sorted(set(sys.modules) - _AT["modules"])
        _write("exit", new=len(new), packages=sorted({m.split(".")[0] for m in new}))
"""


def ctrl_c_xdist(at: int, repeat: int, how: str, as_is: bool, preloaded: bool = False) -> None:
    """``repeat`` runs of the 300-case campaign under ``-n 2``, each signalled at ``at`` rows
    (``how``: "int" SIGINT to the process group as a terminal's Ctrl-C, "term" SIGTERM to the
    group, "term-controller" SIGTERM to pytest's process alone, as ``kill PID`` does)."""
    import json
    import resource
    import threading

    env = dict(os.environ)
    if preloaded:
        env["AVS_BENCH_PRELOADED"] = "1"
        print("the controller's end-of-run imports made before the run (--preloaded)")
    with tempfile.TemporaryDirectory(prefix="avs-bench-ctrl-c-") as tmp:
        if not as_is:
            # a user's steady state: compiled modules cached (pytest's rewritten ones too).
            # The cache lives in the temp dir, so nothing is written beside the sources; a
            # first run (not counted) fills it
            env.pop("PYTHONDONTWRITEBYTECODE", None)
            env["PYTHONPYCACHEPREFIX"] = os.path.join(tmp, "pycache")
        print(f"bytecode cache: {'as the environment says (PYTHONDONTWRITEBYTECODE=' + env.get('PYTHONDONTWRITEBYTECODE', '') + ')' if as_is else 'warm (PYTHONPYCACHEPREFIX in a temp dir, filled by a first run not counted)'}")
        runs = repeat + (0 if as_is else 1)
        for run in range(runs):
            path = Path(tmp) / f"run{run}"
            path.mkdir()
            (path / "test_stop.py").write_text(SLEEPING)
            (path / "conftest.py").write_text(STAMPS)

            def group_with_ctrl_c() -> None:
                signal.signal(signal.SIGINT, signal.SIG_DFL)  # as a terminal's foreground job has it
                os.setsid()

            before = resource.getrusage(resource.RUSAGE_CHILDREN)
            load = os.getloadavg()[0]
            proc = subprocess.Popen([sys.executable, "-u", "-m", "pytest", "-p", "no:cacheprovider", "-n", "2",
                                     "--avs-db=none", "--junitxml=out.xml", "test_stop.py"], cwd=path, env=env,
                                    stdout=subprocess.PIPE, stderr=subprocess.STDOUT, preexec_fn=group_with_ctrl_c)
            lines: list[tuple[float, str]] = []
            reader = threading.Thread(target=lambda: lines.extend(
                (time.monotonic(), raw.decode(errors="replace")) for raw in proc.stdout))
            reader.start()
            try:
                while (n := rows(path)) < at:
                    if proc.poll() is not None:
                        raise SystemExit(f"the run ended before {at} rows ({n})")
                    time.sleep(0.02)
                signalled = time.monotonic()
                if how == "int":
                    os.killpg(proc.pid, signal.SIGINT)
                elif how == "term":
                    os.killpg(proc.pid, signal.SIGTERM)
                else:
                    proc.send_signal(signal.SIGTERM)
                status = proc.wait(300)
                ended = time.monotonic()
            finally:
                if proc.poll() is None:
                    os.killpg(proc.pid, signal.SIGKILL)
                    proc.wait()
            reader.join()
            after = resource.getrusage(resource.RUSAGE_CHILDREN)
            cpu_all = (after.ru_utime + after.ru_stime) - (before.ru_utime + before.ru_stime)
            stamps = [json.loads(line) for line in (path / "stamps.jsonl").read_text().splitlines()]
            at_interrupt = {s["who"]: s for s in stamps if s["what"] == "interrupt"}
            at_exit = {s["who"]: s for s in stamps if s["what"] == "exit"}
            ctl_in, ctl_out = at_interrupt.get("ctl"), at_exit.get("ctl")
            said = "".join(text for t, text in lines if t >= signalled).splitlines()
            workers = [line for line in said if "avscenario: worker gw" in line]
            junit = (path / "out.xml").read_text().count("<testcase ")
            if run == 0 and not as_is:
                print(f"(first run, filling the bytecode cache: exit {ended - signalled:.2f} s after the signal)")
                continue
            print(f"{how} at {n} rows (load {load:.1f}): exit {ended - signalled:.2f} s after the signal, "
                  f"status {status}; {len(said)} lines after it, {len(workers)} of them 'avscenario: worker' "
                  f"lines; rows {rows(path)} = JUnit test cases {junit}", flush=True)
            if ctl_in and ctl_out:
                print(f"    CPU after the interrupt: controller {ctl_out['cpu'] - ctl_in['cpu']:.2f} s "
                      f"(to its atexit), all processes {cpu_all - sum(s['cpu'] for s in at_interrupt.values()):.2f} s "
                      f"(to their ends; {len(at_interrupt)} of 3 reached pytest's interrupt handling, a "
                      f"process that did not counts whole); the whole run {cpu_all:.2f} s. The controller reached pytest's "
                      f"interrupt handling {ctl_in['t'] - signalled:.2f} s after the signal and imported "
                      f"{ctl_out['new']} modules after it ({', '.join(ctl_out['packages'][:8]) or 'none'}"
                      f"{' ...' if len(ctl_out['packages']) > 8 else ''})", flush=True)
            else:
                print("    (the controller's stamps are missing: it did not reach pytest's interrupt handling)")


def whole_xdist(repeat: int, as_is: bool) -> None:
    """The same 300-case campaign under ``-n 2`` run to its end: wall and CPU (all processes),
    to show what the controller's imports made while the workers run cost a finished run."""
    import resource

    env = dict(os.environ)
    with tempfile.TemporaryDirectory(prefix="avs-bench-whole-") as tmp:
        if not as_is:
            env.pop("PYTHONDONTWRITEBYTECODE", None)
            env["PYTHONPYCACHEPREFIX"] = os.path.join(tmp, "pycache")
        for run in range(repeat + (0 if as_is else 1)):
            path = Path(tmp) / f"run{run}"
            path.mkdir()
            (path / "test_stop.py").write_text(SLEEPING)
            before = resource.getrusage(resource.RUSAGE_CHILDREN)
            load = os.getloadavg()[0]
            t0 = time.monotonic()
            status = subprocess.run([sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", "-n", "2",
                                     "--avs-db=none", "test_stop.py"], cwd=path, env=env,
                                    stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL).returncode
            wall = time.monotonic() - t0
            after = resource.getrusage(resource.RUSAGE_CHILDREN)
            cpu = (after.ru_utime + after.ru_stime) - (before.ru_utime + before.ru_stime)
            if run == 0 and not as_is:
                continue
            print(f"whole run, 300 cases under -n 2 (load {load:.1f}): wall {wall:.2f} s, CPU {cpu:.2f} s "
                  f"(all processes), rows {rows(path)}, status {status}", flush=True)


def show(samples: int, r: dict[str, float]) -> None:
    print(f"{samples:>7} cases, SIGTERM at {r['rows']:>6} rows (after {r['run_s']:.0f} s): "
          f"stop {r['stop_s']:.1f} s (report {r['report_s']:.1f} s, teardown {r['teardown_s']:.1f} s), "
          f"exit status {r['status']}", flush=True)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--samples", type=int, default=100_000)
    parser.add_argument("--at", type=int, default=30_000)
    parser.add_argument("--scaling", action="store_true")
    parser.add_argument("--ctrl-c-xdist", action="store_true")
    parser.add_argument("--repeat", type=int, default=3, help="--ctrl-c-xdist: measured runs")
    parser.add_argument("--signal", choices=("int", "term", "term-controller"), default="int",
                        help="--ctrl-c-xdist: SIGINT to the group (a terminal's Ctrl-C), SIGTERM to "
                             "the group, or SIGTERM to pytest's process alone")
    parser.add_argument("--as-is", action="store_true",
                        help="--ctrl-c-xdist: keep the environment's bytecode setting (this machine "
                             "sets PYTHONDONTWRITEBYTECODE: every run compiles, and pytest rewrites, "
                             "Hypothesis and the plugin afresh)")
    parser.add_argument("--preloaded", action="store_true",
                        help="--ctrl-c-xdist: the controller makes its end-of-run imports before the "
                             "run (what an interrupt costs once the preload thread is done)")
    parser.add_argument("--whole-xdist", action="store_true",
                        help="the --ctrl-c-xdist campaign run to its end (wall and CPU)")
    args = parser.parse_args()
    print(f"load average {os.getloadavg()[0]:.2f} on {os.cpu_count()} cores")
    if args.whole_xdist:
        whole_xdist(args.repeat, args.as_is)
    elif args.ctrl_c_xdist:
        ctrl_c_xdist(args.at if args.at != parser.get_default("at") else 60, args.repeat, args.signal, args.as_is,
                     args.preloaded)
    elif args.scaling:
        for samples in (2_000, 20_000):
            show(samples, stop_once(samples, int(samples * 0.9)))
    else:
        show(args.samples, stop_once(args.samples, args.at))


if __name__ == "__main__":
    main()

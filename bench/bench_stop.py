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
group of its own; once ``errors.jsonl`` holds ``--at`` rows (default 30) the whole group gets
SIGINT, as a terminal's Ctrl-C reaches the controller and its workers. It prints the seconds
to exit and the lines printed after the signal (issue #33 item 6: ~12 s and ~280 lines of
worker tracebacks before).
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


def ctrl_c_xdist(at: int) -> None:
    import threading

    with tempfile.TemporaryDirectory(prefix="avs-bench-ctrl-c-") as tmp:
        path = Path(tmp)
        (path / "test_stop.py").write_text(SLEEPING)

        def group_with_ctrl_c() -> None:
            signal.signal(signal.SIGINT, signal.SIG_DFL)  # as a terminal's foreground job has it
            os.setsid()

        proc = subprocess.Popen([sys.executable, "-u", "-m", "pytest", "-p", "no:cacheprovider", "-n", "2",
                                 "--avs-db=none", "--junitxml=out.xml", "test_stop.py"], cwd=path,
                                stdout=subprocess.PIPE, stderr=subprocess.STDOUT, preexec_fn=group_with_ctrl_c)
        lines: list[tuple[float, str]] = []
        reader = threading.Thread(target=lambda: lines.extend(
            (time.monotonic(), raw.decode(errors="replace")) for raw in proc.stdout))
        reader.start()
        try:
            while (n := rows(path)) < at:
                if proc.poll() is not None:
                    raise SystemExit(f"the run ended before {at} rows ({n})")
                time.sleep(0.05)
            signalled = time.monotonic()
            os.killpg(proc.pid, signal.SIGINT)
            status = proc.wait(300)
            ended = time.monotonic()
        finally:
            if proc.poll() is None:
                os.killpg(proc.pid, signal.SIGKILL)
                proc.wait()
        reader.join()
        after = [text for t, text in lines if t >= signalled]
        junit = (path / "out.xml").read_text().count("<testcase ")
        print(f"Ctrl-C under -n 2 at {n} rows: exit {ended - signalled:.1f} s, status {status}, "
              f"{len(after)} lines printed after it ({sum(len(t.splitlines()) for _, t in lines)} in all), "
              f"rows {rows(path)}, JUnit test cases {junit}", flush=True)


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
    args = parser.parse_args()
    print(f"load average {os.getloadavg()[0]:.2f} on {os.cpu_count()} cores")
    if args.ctrl_c_xdist:
        ctrl_c_xdist(args.at if args.at != parser.get_default("at") else 30)
    elif args.scaling:
        for samples in (2_000, 20_000):
            show(samples, stop_once(samples, int(samples * 0.9)))
    else:
        show(args.samples, stop_once(args.samples, args.at))


if __name__ == "__main__":
    main()

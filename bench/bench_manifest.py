"""Benchmark: recording a report's files in the report directory's manifest.

Every file of a report is recorded before it is written (``ReportFolder.add``), so a killed
run's files are still known to the next one. The example suite's report holds ~2,000 files
(a card per counterexample plus pictures). This times N adds through ``ReportFolder`` against
the anchor, writing the same N files themselves atomically (``atomic_write_bytes``, a 9 KB
card each, fsynced — and again with ``durable=False``, as the report writes its per-case
files), in the same run, and prints the ratios.

    python bench/bench_manifest.py [--files 2000] [--repeat 3]
"""

from __future__ import annotations

import argparse
import platform
import statistics
import tempfile
import time
from pathlib import Path

from pytest_avscenario.report.folder import atomic_write_bytes, claim_report_dir


def manifest_s(root: Path, n: int) -> float:
    folder, _ = claim_report_dir(root)
    t = time.perf_counter()
    for i in range(n):
        folder.add(folder.path / "cases" / f"test_x-{i:08x}.html")
    folder.release()
    return time.perf_counter() - t


def files_s(root: Path, n: int, durable: bool = True) -> float:
    data = b"x" * 9000
    t = time.perf_counter()
    for i in range(n):
        atomic_write_bytes(root / "cases" / f"test_x-{i:08x}.html", data, durable=durable)
    return time.perf_counter() - t


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--files", type=int, default=2000)
    ap.add_argument("--repeat", type=int, default=3)
    a = ap.parse_args()
    m, f, q = [], [], []
    for r in range(a.repeat):
        with tempfile.TemporaryDirectory() as tmp:
            m.append(manifest_s(Path(tmp) / f"m{r}", a.files))
            f.append(files_s(Path(tmp) / f"f{r}", a.files))
            q.append(files_s(Path(tmp) / f"q{r}", a.files, durable=False))
    mm, fm, qm = statistics.median(m), statistics.median(f), statistics.median(q)
    print(f"python {platform.python_version()}, {a.files} files, median of {a.repeat}")
    print(f"manifest (add x{a.files} + release): {mm:.3f} s  ({1000 * mm / a.files:.3f} ms/file)")
    print(f"anchor (the files' own atomic writes): {fm:.3f} s  ({1000 * fm / a.files:.3f} ms/file)")
    print(f"the same, durable=False (as cards and case pictures are written): {qm:.3f} s  "
          f"({1000 * qm / a.files:.3f} ms/file)")
    print(f"ratio manifest / files: {mm / fm:.3f};  durable=False / durable: {qm / fm:.3f}")


if __name__ == "__main__":
    main()

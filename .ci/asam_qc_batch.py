"""ASAM's OpenSCENARIO and OpenDRIVE checkers over many files in one process.

Run with the checkers' own interpreter (``.ci/asam-qc.sh`` makes that environment):

    python .ci/asam_qc_batch.py FILE.xosc FILE.xodr ...

Each file gets the same checks as ``qc_openscenario -c CONFIG`` / ``qc_opendrive -c CONFIG``
(the bundles' own ``run_checks`` with a configuration naming the file), but the checkers'
import and start-up (about a second each on 2 cores) are paid once for all files instead of
once per file. Prints one line per file (checks completed, issues, seconds) and every issue;
exits 1 when a file has an issue, a check did not complete, or a checker failed on it.
"""

from __future__ import annotations

import logging
import os
import sys
import time


def _check(path: str, main, bundle: str) -> tuple[int, int, list[str]]:
    from qc_baselib import Configuration, Result

    config = Configuration()
    config.set_config_param("InputFile", path)
    config.register_checker_bundle(bundle)
    result = Result()
    result.register_checker_bundle(name=main.constants.BUNDLE_NAME, description=bundle,
                                   version=main.constants.BUNDLE_VERSION, summary="")
    result.set_result_version(version=main.constants.BUNDLE_VERSION)
    main.run_checks(config, result)
    checkers = result.get_checker_results(main.constants.BUNDLE_NAME)
    done = sum(c.status.value == "completed" for c in checkers)
    issues = []
    for c in checkers:
        for issue in c.issues:
            issues.append(f"{issue.level.name} {c.checker_id}: {issue.description}")
    return done, len(checkers), issues


def main(paths: list[str]) -> int:
    logging.disable(logging.CRITICAL)  # the bundles log every check at INFO
    t0 = time.perf_counter()
    from qc_opendrive import main as odr
    from qc_openscenario import main as osc

    print(f"asam-qc: checkers imported in {time.perf_counter() - t0:.2f} s")
    status = 0
    for path in map(os.path.abspath, paths):  # the .xosc checks read the road beside it
        t = time.perf_counter()
        main_mod, bundle = (osc, "xoscBundle") if path.endswith(".xosc") else (odr, "xodrBundle")
        name = path.rsplit("/", 1)[-1]
        try:
            done, total, issues = _check(path, main_mod, bundle)
        except Exception as exc:  # a checker that breaks on a file is a failure, said so
            print(f"{name}: the checker failed: {type(exc).__name__}: {exc}")
            status = 1
            continue
        print(f"{name}: {done}/{total} checks completed, {len(issues)} issue(s) "
              f"({time.perf_counter() - t:.2f} s)")
        for line in issues:
            print("   ", line)
        if issues or not done:  # no check ran: not a file the checker could read
            status = 1
        elif done < total:
            print(f"    ({total - done} check(s) skipped: preconditions or version)")
    print(f"asam-qc: {len(paths)} file(s) in {time.perf_counter() - t0:.1f} s")
    return status


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))

#!/usr/bin/env bash
# CI quick mode of the example suite (~30-60 s on 2 cores):
#  1. every scenario's nominal case passes against the autopilot (must pass);
#  2. 5 cases per scenario test and sampler run end to end and write the report. The
#     scenarios are hard for the autopilot by design, so new counterexamples are expected
#     failures here (--avs-accept regressions): the exit status is 0 unless a case could not
#     be judged (an error) — the acceptance criteria decide, no script over summary.json.
set -uo pipefail
cd "$(dirname "$0")/.."
report="${AVS_CI_REPORT:-avs-report-ci}"

pytest example_tests/test_nominal_cases.py -q -p no:cacheprovider || exit 1

exec pytest example_tests -m scenario -n 2 -q -p no:cacheprovider --avs-seed=0 --avs-samples 5 \
    --avs-db none --avs-report "$report" --avs-accept regressions

#!/usr/bin/env bash
# CI quick mode of the example suite (~30-60 s on 2 cores):
#  1. every scenario's nominal case passes against the autopilot (must pass);
#  2. 5 cases per scenario test and sampler run end to end and write the report; failing
#     items are the expected counterexamples (pytest exit 1 is fine), but no case may be an
#     error and every test must have run its cases.
set -uo pipefail
cd "$(dirname "$0")/.."
report="${AVS_CI_REPORT:-avs-report-ci}"

pytest example_tests/test_nominal_cases.py -q -p no:cacheprovider || exit 1

pytest example_tests -m scenario -n 2 -q -p no:cacheprovider --avs-seed=0 --avs-samples 5 \
    --avs-db none --avs-report "$report"
status=$?
if [ "$status" -ne 0 ] && [ "$status" -ne 1 ]; then
    echo "example suite: pytest exited with $status (not a plain test failure)" >&2
    exit "$status"
fi

python - "$report" <<'EOF'
import json, sys
tests = json.load(open(f"{sys.argv[1]}/summary.json"))["tests"]
bad = [t["test"] + " " + t["sampler"] for t in tests
       if t["sampler"] in ("halton", "mab") and (t["errors"] or t["samples"] != 5)]
names = {t["test"] for t in tests}
if bad or len(names) != 11:
    sys.exit(f"example suite: {len(names)} scenario tests reported; errors or missing cases in {bad}")
print(f"example suite: {len(names)} scenario tests x 2 samplers ran without errors")
EOF

#!/usr/bin/env bash
# ASAM's own checkers (asam-qc-openscenarioxml, asam-qc-opendrive) on exported counterexamples.
# They pin an older lxml than the project's environment, so they live in a throwaway virtual
# environment under /tmp (AVS_QC_VENV), never in the project's. Usage:
#
#     .ci/asam-qc.sh [REPORT_DIR]
#
# checks every distinct .xosc and .xodr under REPORT_DIR/cases; without REPORT_DIR it first
# runs the example suite's quick mode (example_tests/ci_quick.sh, which exports its
# counterexamples) into a temporary report. Files are deduplicated by content (a test's cases
# often share their road) and all of them go through ONE checker process
# (.ci/asam_qc_batch.py): the checkers' start-up, ~2-4 s a process, is paid once, each file
# then costs 0.01-0.15 s. Exit status 1 when a checker finds an issue or cannot run.
set -euo pipefail
cd "$(dirname "$0")/.."
venv="${AVS_QC_VENV:-/tmp/avs-asam-qc-venv}"
work="$(mktemp -d /tmp/avs-asam-qc.XXXXXX)"
trap 'rm -rf "$work"' EXIT
report="${1:-}"
if [ -z "$report" ]; then
    report="$work/report"
    SECONDS=0
    AVS_CI_REPORT="$report" bash example_tests/ci_quick.sh >"$work/quick.log" 2>&1 || {
        tail -30 "$work/quick.log"; echo "asam-qc: the example suite's quick mode failed"; exit 1; }
    echo "asam-qc: the example suite's quick mode exported in ${SECONDS} s"
fi
SECONDS=0
if [ ! -x "$venv/bin/python" ] || ! "$venv/bin/python" -c "import qc_opendrive, qc_openscenario" 2>/dev/null; then
    python -m venv "$venv"
    "$venv/bin/pip" install --quiet --disable-pip-version-check \
        "asam-qc-openscenarioxml==1.0.0" "asam-qc-opendrive==1.0.0"
    echo "asam-qc: checkers installed in ${SECONDS} s"
fi
shopt -s nullglob
files=("$report"/cases/*.xosc "$report"/cases/*.xodr)
if [ ${#files[@]} -eq 0 ]; then
    echo "asam-qc: no .xosc/.xodr under $report/cases (was --avs-export none, or is scenariogeneration missing?)"
    exit 1
fi
# one file per distinct content; an .xosc keeps its own folder (the checker reads the road
# file it names beside it), so distinct scenarios are checked in place
mapfile -t distinct < <(sha256sum "${files[@]}" | sort -k1,1 -u | cut -c67-)
echo "asam-qc: ${#files[@]} exported file(s), ${#distinct[@]} distinct"
"$venv/bin/python" .ci/asam_qc_batch.py "${distinct[@]}"

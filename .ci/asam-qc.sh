#!/usr/bin/env bash
# ASAM's own checkers (asam-qc-openscenarioxml, asam-qc-opendrive) on exported counterexamples.
# They pin an older lxml than the project's environment, so they live in a throwaway virtual
# environment under /tmp (AVS_QC_VENV), never in the project's. Usage:
#
#     .ci/asam-qc.sh [REPORT_DIR]
#
# checks every .xosc and .xodr under REPORT_DIR/cases; without REPORT_DIR it first runs the
# example suite's quick mode (example_tests/ci_quick.sh, which exports its counterexamples)
# into a temporary report. AVS_QC_MAX=N checks at most N distinct files of each kind (CI's
# long set keeps its time bounded so). Exit status 1 when a checker finds an issue or cannot
# run.
set -euo pipefail
cd "$(dirname "$0")/.."
venv="${AVS_QC_VENV:-/tmp/avs-asam-qc-venv}"
work="$(mktemp -d /tmp/avs-asam-qc.XXXXXX)"
report="${1:-}"
if [ -z "$report" ]; then
    report="$work/report"
    AVS_CI_REPORT="$report" bash example_tests/ci_quick.sh >"$work/quick.log" 2>&1 || {
        tail -30 "$work/quick.log"; echo "asam-qc: the example suite's quick mode failed"; exit 1; }
fi
if [ ! -x "$venv/bin/qc_openscenario" ] || [ ! -x "$venv/bin/qc_opendrive" ]; then
    python -m venv "$venv"
    "$venv/bin/pip" install --quiet --disable-pip-version-check \
        "asam-qc-openscenarioxml==1.0.0" "asam-qc-opendrive==1.0.0"
fi
shopt -s nullglob
files=("$report"/cases/*.xosc "$report"/cases/*.xodr)
if [ ${#files[@]} -eq 0 ]; then
    echo "asam-qc: no .xosc/.xodr under $report/cases (was --avs-export none, or is scenariogeneration missing?)"
    exit 1
fi
status=0
declare -A seen  # a test's cases share their road: each distinct file is checked once
declare -A kinds  # extension -> distinct files checked
for f in "${files[@]}"; do
    sum="$(sha256sum "$f" | cut -c1-64)"
    if [ -n "${seen[$sum]:-}" ]; then continue; fi
    seen[$sum]=1
    kind="${f##*.}"
    if [ -n "${AVS_QC_MAX:-}" ] && [ "${kinds[$kind]:-0}" -ge "$AVS_QC_MAX" ]; then continue; fi
    kinds[$kind]=$(( ${kinds[$kind]:-0} + 1 ))
    case "$f" in
        *.xosc) bundle=xoscBundle; checker=qc_openscenario ;;
        *.xodr) bundle=xodrBundle; checker=qc_opendrive ;;
    esac
    name="$(basename "$f")"
    cat >"$work/$name.config.xml" <<EOF
<?xml version="1.0" encoding="UTF-8"?>
<Config>
  <Param name="InputFile" value="$f"/>
  <CheckerBundle application="$bundle">
    <Param name="resultFile" value="$work/$name.xqar"/>
  </CheckerBundle>
</Config>
EOF
    if ! "$venv/bin/$checker" -c "$work/$name.config.xml" >"$work/$name.log" 2>&1; then
        echo "asam-qc: $checker failed on $name:"; tail -5 "$work/$name.log"; status=1; continue
    fi
    python - "$work/$name.xqar" "$name" <<'EOF' || status=1
import sys
import xml.etree.ElementTree as ET

root = ET.parse(sys.argv[1]).getroot()
checkers = root.findall(".//Checker")
issues = root.findall(".//Issue")
done = sum(c.get("status") == "completed" for c in checkers)
print(f"{sys.argv[2]}: {done}/{len(checkers)} checks completed, {len(issues)} issue(s)")
for issue in issues:
    print("   ", issue.get("level"), issue.get("description"))
sys.exit(1 if issues or not checkers else 0)
EOF
done
rm -rf "$work"
exit $status

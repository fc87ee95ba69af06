#!/usr/bin/env bash
# The soak of issue 23 (tests/soak_test.cc): 8 robots against one placerec-server for SECONDS
# (default 1800; CI runs the 180-second version through ctest), with one SIGKILL and restart,
# one disk-full episode and a query-only tail, the server's memory sampled every second. Writes
# OUT/soak.json (frames, answers by status, restart time, acknowledged places and any lost,
# latency per phase, memory) and OUT/memory.csv. Needs root (private network and mount
# namespaces) and ../shared/data. Usage: scripts/soak.sh [SECONDS] [OUT] (OUT default soak-out).
# Builds first (scripts/build.sh). Environment: BUILD_DIR (default build), PLACEREC_DATA (the data
# when not at ../shared/data).
set -euo pipefail

usage() {
  sed -n '2,9p' "$0" | sed 's/^# \{0,1\}//'
}

if [ "${1:-}" = "--help" ] || [ "${1:-}" = "-h" ]; then
  usage
  exit 0
fi
root=$(cd "$(dirname "$0")/.." && pwd)
build_dir=${BUILD_DIR:-$root/build}
seconds=${1:-1800}
out=$(mkdir -p "${2:-soak-out}" && cd "${2:-soak-out}" && pwd)

bash "$root/scripts/build.sh"
echo "soak: ${seconds} s, report in $out"
PLACEREC_SOAK_SECONDS=$seconds PLACEREC_SOAK_OUT=$out \
  "$build_dir/tests/placerec_soak_test" --gtest_brief=1

#!/usr/bin/env bash
# The test command: installs what is missing, builds, and runs every test (unit tests, the
# end-to-end evaluation on ../shared/data, and the server/client integration tests), then each
# fuzz target for FUZZ_SECONDS seconds (default 60; 0 skips them; scripts/fuzz.sh).
# Tests that need ../shared/data skip with a message when it is absent (set PLACEREC_DATA to
# point elsewhere; a relative path is taken from the current folder). A missing data folder is
# warned about before the build; PLACEREC_REQUIRE_DATA=1 (CI) makes it an error instead.
# The PostgreSQL tests (label postgres) start their own throw-away clusters with scripts/pg.sh;
# install-deps installs postgresql-15 for them.
# Usage: scripts/test.sh [ctest options...]   (e.g. -R pg -L postgres)
# Environment: BUILD_DIR (default build), TEST_JOBS (ctest -j, default 2), FUZZ_SECONDS, JOBS.
set -euo pipefail

usage() {
  sed -n '2,11p' "$0" | sed 's/^# \{0,1\}//'
}

if [ "${1:-}" = "--help" ] || [ "${1:-}" = "-h" ]; then
  usage
  exit 0
fi
root=$(cd "$(dirname "$0")/.." && pwd)
build_dir=${BUILD_DIR:-$root/build}

# The data the tests read: PLACEREC_DATA, else the build's default (PLACEREC_DEFAULT_DATA_DIR in
# CMakeCache.txt, ../shared/data beside the repository unless configured otherwise). Exported as
# an absolute path: ctest runs each test in build/tests, where a relative path names nothing.
data=${PLACEREC_DATA:-}
if [ -z "$data" ]; then
  data=$(sed -n 's/^PLACEREC_DEFAULT_DATA_DIR:[A-Z]*=//p' "$build_dir/CMakeCache.txt" 2>/dev/null || true)
  data=${data:-$root/../shared/data}
fi
data=$(realpath -m -- "$data")
export PLACEREC_DATA=$data
# The datasets the end-to-end tests read; the data is missing when any of them is.
missing_data() {
  local name
  for name in gardens_point rtabmap_indoor stanford_background msrc_v2 camvid; do
    [ -d "$data/$name" ] || echo "$name"
  done
}
missing=$(missing_data | paste -sd ' ')
# Loud, before the build and again after the tests (the build's output hides the first).
warn_no_data() {
  [ -n "$missing" ] || return 0
  {
    echo "test: ==================================================================================="
    echo "test: WARNING: the evaluation data folder $data lacks: $missing."
    echo "test: The end-to-end and data tests that need it will SKIP, and the run can still pass."
    echo "test: Set PLACEREC_DATA to the folder holding gardens_point/, rtabmap_indoor/ and the"
    echo "test: other datasets (default ../shared/data beside the repository);"
    echo "test: PLACEREC_REQUIRE_DATA=1 fails instead."
    echo "test: ==================================================================================="
  } >&2
}
if [ -n "$missing" ] && [ "${PLACEREC_REQUIRE_DATA:-}" = 1 ]; then
  echo "test: the evaluation data folder $data lacks $missing, and PLACEREC_REQUIRE_DATA=1 asks" \
    "for it; put the shared data there (../shared/data beside the repository) or set" \
    "PLACEREC_DATA to the folder holding gardens_point/ and rtabmap_indoor/" >&2
  exit 1
fi
warn_no_data

bash "$root/scripts/build.sh"
bash "$root/scripts/check-format.sh"
cd "$build_dir"
rc=0
ctest --output-on-failure -j "${TEST_JOBS:-2}" "$@" || rc=$?
warn_no_data
[ "$rc" -eq 0 ] || exit "$rc"
if [ "${FUZZ_SECONDS:-60}" != 0 ]; then
  bash "$root/scripts/fuzz.sh" "${FUZZ_SECONDS:-60}"
fi

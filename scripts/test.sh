#!/usr/bin/env bash
# The test command: installs what is missing, builds, and runs every test (unit tests, the
# end-to-end evaluation on ../shared/data, and the server/client integration tests), then each
# fuzz target for FUZZ_SECONDS seconds (default 60; 0 skips them; scripts/fuzz.sh).
# Tests that need ../shared/data skip with a message when it is absent (set PLACEREC_DATA to
# point elsewhere).
# The PostgreSQL tests (label postgres) start their own throw-away clusters with scripts/pg.sh;
# install-deps installs postgresql-15 for them.
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
build_dir=${BUILD_DIR:-$root/build}

bash "$root/scripts/build.sh"
bash "$root/scripts/check-format.sh"
cd "$build_dir"
ctest --output-on-failure -j "${TEST_JOBS:-2}" "$@"
if [ "${FUZZ_SECONDS:-60}" != 0 ]; then
  bash "$root/scripts/fuzz.sh" "${FUZZ_SECONDS:-60}"
fi

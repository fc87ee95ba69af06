#!/usr/bin/env bash
# Builds the libFuzzer targets of tests/fuzz with Clang 15 and AddressSanitizer into
# build-fuzz/ (FUZZ_BUILD_DIR) and runs each for SECONDS seconds (default 60) from a copy of its
# committed seed corpus (tests/fuzz/corpus/<target>). Prints each target's executions, and any
# crash with the input that caused it (saved under build-fuzz/fuzz/findings/<target>/). Exits 1
# when a target crashed. Usage: scripts/fuzz.sh [SECONDS] [TARGET...] (targets: frame image map);
# scripts/fuzz.sh --seeds rewrites the seed corpus. Installs missing packages first
# (scripts/install-deps.sh). Environment: FUZZ_BUILD_DIR (default build-fuzz), JOBS (build jobs,
# default: number of cores).
set -euo pipefail

usage() {
  sed -n '2,9p' "$0" | sed 's/^# \{0,1\}//'
}

if [ "${1:-}" = "--help" ] || [ "${1:-}" = "-h" ]; then
  usage
  exit 0
fi
root=$(cd "$(dirname "$0")/.." && pwd)
build_dir=${FUZZ_BUILD_DIR:-$root/build-fuzz}
jobs=${JOBS:-$(nproc)}

bash "$root/scripts/install-deps.sh"
command -v clang++-15 >/dev/null || { echo "fuzz: clang++-15 is missing (scripts/install-deps.sh installs it)" >&2; exit 1; }
CC=clang-15 CXX=clang++-15 cmake -S "$root" -B "$build_dir" -DCMAKE_BUILD_TYPE=RelWithDebInfo \
  -DPLACEREC_FUZZ=ON -DPLACEREC_BUILD_TESTS=OFF -DPLACEREC_BUILD_BENCHMARKS=OFF \
  -DPLACEREC_WERROR=OFF >/dev/null

if [ "${1:-}" = "--seeds" ]; then
  cmake --build "$build_dir" -j "$jobs" --target placerec_fuzz_seeds
  rm -rf "$root/tests/fuzz/corpus"
  "$build_dir/fuzz/placerec_fuzz_seeds" "$root/tests/fuzz/corpus"
  echo "fuzz: seeds written to tests/fuzz/corpus"
  exit 0
fi

seconds=${1:-60}
shift || true
targets=("$@")
[ ${#targets[@]} -gt 0 ] || targets=(frame image map)
build_targets=()
for t in "${targets[@]}"; do build_targets+=("placerec_${t}_fuzzer"); done
cmake --build "$build_dir" -j "$jobs" --target "${build_targets[@]}"

# Inputs larger than these are not tried: frames and images of a few KB exercise the decoders'
# headers; a map needs a few pages.
declare -A max_len=([frame]=8192 [image]=8192 [map]=32768)
failed=0
for t in "${targets[@]}"; do
  work=$build_dir/fuzz/work/$t
  findings=$build_dir/fuzz/findings/$t
  rm -rf "$work"
  mkdir -p "$work" "$findings"
  cp "$root/tests/fuzz/corpus/$t/"* "$work/"
  log=$build_dir/fuzz/$t.log
  set +e
  ASAN_OPTIONS=detect_leaks=1 "$build_dir/fuzz/placerec_${t}_fuzzer" "$work" \
    -max_total_time="$seconds" -max_len="${max_len[$t]}" -rss_limit_mb=2048 -timeout=10 \
    -print_final_stats=1 -artifact_prefix="$findings/" > "$log" 2>&1
  rc=$?
  set -e
  runs=$(sed -n 's/^stat::number_of_executed_units: *//p' "$log" | tail -1)
  if [ $rc -eq 0 ]; then
    echo "fuzz: $t: ${runs:-?} executions in ${seconds} s, no crash (corpus $(ls "$work" | wc -l) inputs)"
  else
    failed=1
    echo "fuzz: $t: CRASH after ${runs:-?} executions (exit $rc); input and log:" >&2
    ls "$findings" >&2
    grep -m 20 -E "ERROR|SUMMARY|==[0-9]+==|#[0-9]+ 0x" "$log" >&2 || tail -30 "$log" >&2
  fi
done
exit $failed

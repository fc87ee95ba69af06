#!/usr/bin/env bash
# Throughput of one placerec-server with 1 and with 2 worker threads (issue 24 item 3): the first
# FRAMES frames (0: all 400; the run holds robot left's frames, then right's) of Gardens Point
# day_left_then_day_right sent by robots `left` and `right` at once
# (`placerec-client run --concurrent-robots`), once per worker count, each on a fresh map.
# Prints frames per second and the ratio; OUT/workers_N/ holds each client summary.json and the
# server log. Runs in a private network namespace as root (loopback only).
#
#   bash scripts/workers.sh [FRAMES] [OUT]      (default all frames, out/workers)
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
build_dir=${BUILD_DIR:-$root/build}
data=${PLACEREC_DATA:-$root/../shared/data}
frames=${1:-0}
out=${2:-$root/out/workers}
case "$frames" in '' | *[!0-9]*) echo "workers: FRAMES must be a number" >&2; exit 2 ;; esac
if [ "$frames" -gt 0 ] && [ "$frames" -le 200 ]; then
  # The run's first 200 frames are robot left's: fewer would send one robot only.
  echo "workers: FRAMES must be 0 (all) or above 200, so that both robots send" >&2
  exit 2
fi

if [ -z "${PLACEREC_WORKERS_STAGE:-}" ]; then
  if [ "$(id -u)" -ne 0 ] || ! unshare -n true 2>/dev/null; then
    echo "workers: needs root and unshare -n (a private network namespace)" >&2
    exit 1
  fi
  [ -x "$build_dir/bin/placerec-server" ] || { echo "workers: build first (bash scripts/build.sh)" >&2; exit 1; }
  exec unshare -n -- env PLACEREC_WORKERS_STAGE=netns bash "$0" "$frames" "$out"
fi

source "$root/scripts/service.sh"
service_private_network
url="udpm://239.255.76.67:7667?ttl=0&recv_buf_size=8388608"
server="$build_dir/bin/placerec-server"
client="$build_dir/bin/placerec-client"
mkdir -p "$out"
keys=$out/keys
(umask 077 && bash "$root/scripts/make-key.sh" workers-robots both > "$keys")

server_pid=
trap 'service_stop "$server_pid"' EXIT

declare -A fps cpu_ms
for workers in 1 2; do
  dir=$out/workers_$workers
  rm -rf "$dir"
  mkdir -p "$dir"
  service_start_server "$dir/server.log" "$server" --db "$dir/map.db" --lcm-url "$url" \
    --keys "$keys" --workers "$workers" || exit 1
  /usr/bin/time -f "%U %S %e" -o "$dir/client.time" \
    "$client" run --dataset "$data/gardens_point" --run day_left_then_day_right --out "$dir" \
    --lcm-url "$url" --key-file "$keys" --concurrent-robots --max-frames "$frames" > "$dir/client.log"
  # The server's CPU seconds (utime + stime, fields 14 and 15 of /proc/PID/stat).
  server_cpu=$(awk -v hz="$(getconf CLK_TCK)" '{ print ($14 + $15) / hz }' "/proc/$server_pid/stat")
  service_stop "$server_pid"
  server_pid=
  fps[$workers]=$(sed -n 's/.*"frames_per_second": *\([0-9.]*\).*/\1/p' "$dir/summary.json" | head -n 1)
  sent=$(sed -n 's/.*"frames": *\([0-9]*\).*/\1/p' "$dir/summary.json" | head -n 1)
  cpu_ms[$workers]=$(awk -v c="$server_cpu" -v n="$sent" 'BEGIN { printf "%.0f", 1000 * c / n }')
  read -r cu cs ce < "$dir/client.time"
  echo "workers: $workers worker(s): ${fps[$workers]} frames/s; CPU seconds: server ${server_cpu}, client $(awk -v u="$cu" -v s="$cs" 'BEGIN { print u + s }') in ${ce} s"
done
awk -v a="${fps[1]}" -v b="${fps[2]}" 'BEGIN { printf "workers: 2 workers / 1 worker = %.2fx\n", b / a }'
# The robots' frames are sent at once, so the map each frame meets (and the work of verifying its
# candidates) depends on how the workers interleave them: the ratio compares throughput only when
# both runs spent about the same server CPU per frame. Also the ratio at equal cost per frame:
# the two-worker run's frames per second had its frames cost what the one-worker run's did.
awk -v a="${fps[1]}" -v b="${fps[2]}" -v c1="${cpu_ms[1]}" -v c2="${cpu_ms[2]}" 'BEGIN {
  printf "workers: server CPU per frame %d ms with 1 worker, %d ms with 2; at equal cost per frame: %.2fx\n",
         c1, c2, b / a * c2 / c1
  if (c2 < 0.9 * c1 || c2 > 1.1 * c1)
    print "workers: the runs did different work (CPU per frame differs by more than 10 %); compare the ratio at equal cost"
}'

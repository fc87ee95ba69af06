#!/usr/bin/env bash
# Throughput of one placerec-server with 1 and with 2 worker threads (issue 24 item 3): two robots
# send their frames at once (`placerec-client run --concurrent-robots`), once per worker count,
# each on a fresh map. Prints frames per second, the server's CPU per frame and the ratio;
# OUT/workers_N/ holds each client summary.json and the server log. Runs in a private network
# namespace as root (loopback only).
#
# WORKERS_ROUTES chooses the two robots:
#   apart (default)  Gardens Point day_left cut in two: robot `first` walks frames 0-99, robot
#                    `second` frames 100-199, routes that do not overlap, so the work a frame
#                    costs hardly depends on how the workers interleave the robots' frames.
#   crossing         day_left_then_day_right: robots `left` and `right` walk the same path, so
#                    right's frames meet more or fewer of left's places depending on the
#                    interleaving (the two runs may do different work; compare at equal cost).
#
# WORKERS_SERVER_FLAGS adds flags to both servers (e.g. "--opencv-threads 0"). PLACEREC_DATA: the
# data when not at ../shared/data; BUILD_DIR: the build (default build; build it first).
#
#   bash scripts/workers.sh [FRAMES] [OUT]      (default all frames, out/workers)
set -euo pipefail

usage() {
  sed -n '2,19p' "$0" | sed 's/^# \{0,1\}//'
}

if [ "${1:-}" = "--help" ] || [ "${1:-}" = "-h" ]; then
  usage
  exit 0
fi
root=$(cd "$(dirname "$0")/.." && pwd)
build_dir=${BUILD_DIR:-$root/build}
data=${PLACEREC_DATA:-$root/../shared/data}
frames=${1:-0}
out=${2:-$root/out/workers}
routes=${WORKERS_ROUTES:-apart}
case "$frames" in '' | *[!0-9]*) echo "workers: FRAMES must be a number (see --help)" >&2; exit 2 ;; esac
case "$routes" in
  apart) first_robot_frames=100 ;;
  crossing) first_robot_frames=200 ;;
  *) echo "workers: WORKERS_ROUTES must be apart or crossing" >&2; exit 2 ;;
esac
if [ "$frames" -gt 0 ] && [ "$frames" -le "$first_robot_frames" ]; then
  # The run's first frames are one robot's: fewer would send one robot only.
  echo "workers: FRAMES must be 0 (all) or above $first_robot_frames, so that both robots send" >&2
  exit 2
fi

if [ -z "${PLACEREC_WORKERS_STAGE:-}" ]; then
  [ -f "$data/gardens_point/runs/day_left_then_day_right.frames.csv" ] ||
    { echo "workers: no Gardens Point runs under $data (set PLACEREC_DATA)" >&2; exit 1; }
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

# The run both worker counts replay.
if [ "$routes" = apart ]; then
  dataset=$out/run
  run=day_left_halves
  mkdir -p "$dataset/runs"
  # Robot left's 200 frames of day_left_then_day_right, the first hundred as robot `first`, the
  # others as `second`; images by absolute path, capture times as recorded.
  awk -F, -v dir="$(cd "$data/gardens_point" && pwd)" 'NR == 1 { print; next }
    $2 == "left" { print $1 "," ($1 < 100 ? "first" : "second") "," dir "/" $3 "," $4 }' \
    "$data/gardens_point/runs/day_left_then_day_right.frames.csv" > "$dataset/runs/$run.frames.csv"
  echo "query,reference" > "$dataset/runs/$run.positives.csv"  # the robots revisit nothing
else
  dataset=$data/gardens_point
  run=day_left_then_day_right
fi

server_pid=
trap 'service_stop "$server_pid"' EXIT

declare -A fps cpu_ms
for workers in 1 2; do
  dir=$out/workers_$workers
  rm -rf "$dir"
  mkdir -p "$dir"
  service_start_server "$dir/server.log" "$server" --db "$dir/map.db" --lcm-url "$url" \
    --keys "$keys" --workers "$workers" ${WORKERS_SERVER_FLAGS:-} || exit 1
  /usr/bin/time -f "%U %S %e" -o "$dir/client.time" \
    "$client" run --dataset "$dataset" --run "$run" --out "$dir" \
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
awk -v a="${fps[1]}" -v b="${fps[2]}" -v r="$routes" 'BEGIN { printf "workers: 2 workers / 1 worker = %.2fx (routes %s)\n", b / a, r }'
# The robots' frames are sent at once, so the map each frame meets (and the work of verifying its
# candidates) may depend on how the workers interleave them (much on crossing routes): the ratio
# compares throughput only when both runs spent about the same server CPU per frame. Also the
# ratio at equal cost per frame: the two-worker run's frames per second had its frames cost what
# the one-worker run's did.
awk -v a="${fps[1]}" -v b="${fps[2]}" -v c1="${cpu_ms[1]}" -v c2="${cpu_ms[2]}" 'BEGIN {
  printf "workers: server CPU per frame %d ms with 1 worker, %d ms with 2; at equal cost per frame: %.2fx\n",
         c1, c2, b / a * c2 / c1
  if (c2 < 0.9 * c1 || c2 > 1.1 * c1)
    print "workers: the runs did different work (CPU per frame differs by more than 10 %); compare the ratio at equal cost"
}'

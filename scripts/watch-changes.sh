#!/usr/bin/env bash
# Scene-change alarms watched live (issue 22, seed §7.2.4): pastes real objects into half of a
# run's revisits (placerec-eval change --write-run, which also gives the offline figures), then
# replays the changed run through a placerec-server (fresh SQLite map) with placerec-client run
# while placerec-client watch prints every alarm as it arrives and saves its pictures and
# alarms.csv; finally placerec-eval alarms scores the watched alarms against the changes.
# As root, server and clients run in a private network namespace (loopback only); otherwise on
# the host's loopback with LCM TTL 0. Frames are signed with a fresh key.
#
# Usage: bash scripts/watch-changes.sh [DATASET RUN]   (default: rtabmap_indoor corridor_loop)
# Output in out/watch-changes/RUN: offline/change.json, run/ (the changed run), alarms/ (what
# watch saved), client/ (answers), alarms.json (the live scores), server.log.
# Set PLACEREC_DATA when the data is not at ../shared/data, BUILD_DIR when the build is not in
# build/; CHANGE_OPTIONS (e.g. "--change-sensitivity 0.7") is given to both the offline pass and
# the server.
set -euo pipefail

usage() {
  sed -n '2,15p' "$0" | sed 's/^# \{0,1\}//'
}

if [ "${1:-}" = "-h" ] || [ "${1:-}" = "--help" ]; then
  usage
  exit 0
fi
if [ "$#" -gt 2 ]; then
  usage
  exit 2
fi
root=$(cd "$(dirname "$0")/.." && pwd)
build_dir=${BUILD_DIR:-$root/build}
dataset=${1:-rtabmap_indoor}
run=${2:-corridor_loop}
out=$root/out/watch-changes/$run
read -r -a change_options <<< "${CHANGE_OPTIONS:-}"

source "$root/scripts/service.sh"
if [ -z "${PLACEREC_SERVICE_STAGE:-}" ]; then
  bash "$root/scripts/build.sh"
  rm -rf "$out"
  mkdir -p "$out"
  echo "watch-changes: pasting objects into the revisits of $dataset/$run (offline figures too)"
  "$build_dir/bin/placerec-eval" change --dataset "$dataset" --run "$run" --out "$out/offline" \
    --write-run "$out/run" "${change_options[@]}"
fi
service_stage watch-changes "$@"

url="udpm://239.255.76.67:7667?ttl=0&recv_buf_size=4194304"
server="$build_dir/bin/placerec-server"
client="$build_dir/bin/placerec-client"
keys=$out/keys
(umask 077 && bash "$root/scripts/make-key.sh" watch-robots both > "$keys")

server_pid=
watch_pid=
stop_all() {
  service_stop "$watch_pid"
  service_stop "$server_pid"
}
trap stop_all EXIT
trap 'exit 130' INT TERM
service_start_server "$out/server.log" "$server" --db "$out/map.db" --lcm-url "$url" \
  --keys "$keys" "${change_options[@]}" || exit 1

"$client" watch --out "$out/alarms" --lcm-url "$url" &
watch_pid=$!
sleep 1
echo "watch-changes: replaying ${run}_changed through the server; alarms print as they arrive"
"$client" run --dataset "$out/run" --run "${run}_changed" --out "$out/client" \
  --lcm-url "$url" --key-file "$keys" --quiet --no-loops
sleep 2  # the last answer's alarms are published with it; let watch print them
stop_all
trap - EXIT

"$build_dir/bin/placerec-eval" alarms --changes "$out/run/runs/${run}_changed.changes.csv" \
  --alarms "$out/alarms/alarms.csv" --out "$out"
echo "watch-changes: offline figures in $out/offline/change.json, live in $out/alarms.json"

#!/usr/bin/env bash
# The main job: installs what is missing, builds, starts placerec-server on an SQLite map
# (out/demo/map.db, fresh each time), and feeds the Gardens Point day_left_then_day_right run
# through placerec-client over LCM as robots `left` and `right`. Each loop closure is printed as
# its answer arrives, then a summary; the server is stopped at the end (and on Ctrl-C).
# As root, server and client run in a private network namespace (loopback only), so no LCM
# traffic leaves the machine; otherwise they use the host's loopback with TTL 0.
# Frames are signed: the demo makes a fresh key for the robots (out/demo/keys, mode 600) and gives
# it to server (--keys) and client (--key-file).
# Output: out/demo/answers.csv, summary.json, pr_curve.png, map.db, keys, server.log.
# Usage: scripts/demo.sh [placerec-client run options...]
# Extra arguments go to `placerec-client run` (e.g. --max-frames 40). Set PLACEREC_DATA when the
# data is not at ../shared/data; BUILD_DIR when the build is not in build/.
set -euo pipefail

usage() {
  sed -n '2,13p' "$0" | sed 's/^# \{0,1\}//'
}

if [ "${1:-}" = "--help" ] || [ "${1:-}" = "-h" ]; then
  usage
  exit 0
fi
root=$(cd "$(dirname "$0")/.." && pwd)
build_dir=${BUILD_DIR:-$root/build}
data=${PLACEREC_DATA:-$root/../shared/data}

source "$root/scripts/service.sh"
if [ -z "${PLACEREC_SERVICE_STAGE:-}" ]; then
  # The data first: a missing folder is reported before minutes of installing and building.
  if [ ! -f "$data/gardens_point/runs/day_left_then_day_right.frames.csv" ]; then
    echo "demo: $data/gardens_point is missing; set PLACEREC_DATA to the folder holding gardens_point/" >&2
    exit 1
  fi
  bash "$root/scripts/build.sh"
fi
service_stage demo "$@"

out=$root/out/demo
mkdir -p "$out"
rm -f "$out/map.db" "$out/map.db-wal" "$out/map.db-shm"
# TTL 0 keeps packets on this machine; the receive buffer holds bursts of large frames.
url="udpm://239.255.76.67:7667?ttl=0&recv_buf_size=4194304"
server="$build_dir/bin/placerec-server"
client="$build_dir/bin/placerec-client"
keys=$out/keys
(umask 077 && bash "$root/scripts/make-key.sh" demo-robots both > "$keys")

server_pid=
trap 'service_stop "$server_pid"' EXIT
trap 'exit 130' INT TERM
service_start_server "$out/server.log" "$server" --db "$out/map.db" --lcm-url "$url" \
  --keys "$keys" || exit 1
echo "demo: placerec-server is up (map $out/map.db); feeding day_left_then_day_right as robots left and right"

rc=0
"$client" run --dataset "$data/gardens_point" --run day_left_then_day_right --out "$out" \
  --lcm-url "$url" --key-file "$keys" "$@" || rc=$?
"$client" status --lcm-url "$url" --timeout 3 || true
service_stop "$server_pid"
echo "demo: server stopped; log in $out/server.log"
exit "$rc"

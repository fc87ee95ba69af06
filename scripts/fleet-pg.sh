#!/usr/bin/env bash
# Fleet figures for several servers on one PostgreSQL map (issue 24 items 4 and 5), on this
# machine: a throw-away cluster (scripts/pg.sh), SERVERS placerec-servers on it, robot fleetNNN
# answered by server NNN mod SERVERS (--robots), and `placerec-client fleet` replaying
# rtabmap_indoor corridor_loop as ROBOTS robots at RATE frames/s each for DURATION seconds.
# Afterwards the same probe frames are asked (query only) through every server and through one
# more server started on the finished map, and their answers compared (OUT/probes.txt).
#
#   scripts/fleet-pg.sh SERVERS ROBOTS RATE DURATION OUT [WORKERS] [KILL_AFTER]
#
# WORKERS: worker threads per server (default 2). KILL_AFTER (seconds, default 0: never): the
# last fleet server is killed (SIGKILL) that long into the fleet and started again 3 s later on
# the same robots (log OUT/serverN.restart.log); afterwards every place the fleet saw
# acknowledged is looked up in the map (OUT/lost.txt lists any that is missing,
# OUT/unacknowledged.txt the places stored without an answer). Frames sent while their server
# was down are answered when their resend reaches the restarted server, or refused (bad
# request: a robot's sequence must increase) when a newer frame of the robot got there first.
# Runs as root in a private network namespace of its own (unshare -n: LCM multicast on loopback
# only). Binaries from ${BUILD_DIR:-build}/bin; data from ${PLACEREC_DATA:-../shared/data} (its
# rtabmap_indoor/). Writes OUT/fleet.json and acknowledged.csv (placerec-client fleet),
# OUT/server*.log, OUT/probe*.txt, OUT/probes.txt.
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)

if [ $# -lt 5 ] || [ "$1" = "--help" ] || [ "$1" = "-h" ]; then
  sed -n '2,21p' "$0" | sed 's/^# \{0,1\}//'
  [ $# -ge 1 ] && { [ "$1" = "--help" ] || [ "$1" = "-h" ]; } && exit 0
  exit 2
fi
servers=$1 robots=$2 rate=$3 duration=$4 out=$5 workers=${6:-2} kill_after=${7:-0}
case "$kill_after" in '' | *[!0-9]*) echo "fleet-pg: KILL_AFTER must be whole seconds" >&2; exit 2 ;; esac
bin=${BUILD_DIR:-$root/build}/bin
# The data as placerec-client finds it (common/util/paths.cc): PLACEREC_DATA when set and not
# empty, else ../shared/data beside the repository. Checked before anything starts; exported as an
# absolute path so that the fleet client and the probes read the same folder.
data=${PLACEREC_DATA:-$root/../shared/data}
if [ ! -f "$data/rtabmap_indoor/runs/corridor_loop.frames.csv" ]; then
  echo "fleet-pg: no rtabmap_indoor/runs/corridor_loop.frames.csv under $data; set PLACEREC_DATA" \
    "to the folder holding rtabmap_indoor/ (default ../shared/data beside the repository)" >&2
  exit 1
fi
PLACEREC_DATA=$(cd "$data" && pwd)
export PLACEREC_DATA

if [ -z "${PLACEREC_FLEET_NETNS:-}" ]; then
  [ "$(id -u)" -eq 0 ] || { echo "fleet-pg: run as root (private network namespace)" >&2; exit 1; }
  exec unshare -n env PLACEREC_FLEET_NETNS=1 bash "$0" "$@"
fi
source "$root/scripts/service.sh"
service_private_network
lcm="udpm://239.255.76.67:7667?ttl=0&recv_buf_size=4194304"

mkdir -p "$out"
out=$(cd "$out" && pwd)
pgdir=$(mktemp -d /tmp/placerec-pg-XXXXXX)
pids=()
killer=
cleanup() {
  # The killer first: it must not kill or start anything once the cluster is going away.
  if [ -n "$killer" ]; then
    kill "$killer" 2>/dev/null || true
    wait "$killer" 2>/dev/null || true
  fi
  local restarted=
  [ -f "$out/restarted.pid" ] && restarted=$(cat "$out/restarted.pid")
  for pid in "${pids[@]}" $restarted; do kill "$pid" 2>/dev/null || true; done
  for pid in "${pids[@]}"; do wait "$pid" 2>/dev/null || true; done
  # The restarted server is no child of this shell: wait until it has gone.
  if [ -n "$restarted" ]; then
    while kill -0 "$restarted" 2>/dev/null; do sleep 0.1; done
    rm -f "$out/restarted.pid"
  fi
  bash "$root/scripts/pg.sh" stop "$pgdir" || true
}
trap cleanup EXIT
db=$(bash "$root/scripts/pg.sh" start "$pgdir")
bash "$root/scripts/make-key.sh" fleet both >"$out/keys"
chmod 600 "$out/keys"

# Starts a server answering the ids in $2 (comma-separated), logging to $out/$1.log; waits until
# it serves.
start_server() {
  local name=$1 ids=$2
  "$bin/placerec-server" --db "$db" --lcm-url "$lcm" --keys "$out/keys" --robots "$ids" \
    --workers "$workers" >"$out/$name.log" 2>&1 &
  pids+=($!)
  # A server started by the killer (a subshell) is found by the cleanup through this file.
  [ "$name" = "${name%.restart}" ] || echo "$!" >"$out/restarted.pid"
  for _ in $(seq 1 600); do
    grep -q '\] placerec-server ' "$out/$name.log" && return 0
    sleep 0.1
  done
  echo "fleet-pg: $name did not start; its log:" >&2
  tail -n 20 "$out/$name.log" >&2
  exit 1
}

server_ids=()
for ((k = 0; k < servers; k++)); do
  ids="probe$k"
  for ((i = k; i < robots; i += servers)); do ids+=$(printf ',fleet%03d' "$i"); done
  server_ids+=("$ids")
  start_server "server$k" "$ids"
done

if [ "$kill_after" -gt 0 ]; then
  victim=$((servers - 1))
  (
    sleep "$kill_after"
    kill -KILL "${pids[$victim]}"
    echo "fleet-pg: server$victim killed (SIGKILL) ${kill_after} s into the fleet;" \
      "restarting it in 3 s"
    sleep 3
    start_server "server$victim.restart" "${server_ids[$victim]}"
    echo "fleet-pg: server$victim serves again"
  ) &
  killer=$!
fi

"$bin/placerec-client" fleet --robots "$robots" --rate "$rate" --duration "$duration" \
  --dataset rtabmap_indoor --run corridor_loop --out "$out" --lcm-url "$lcm" \
  --key-file "$out/keys" --quiet >"$out/fleet.txt" 2>&1 || true
cat "$out/fleet.txt"
if [ "$kill_after" -gt 0 ]; then
  wait "$killer" || true
  killer=
  # Every acknowledged place is in the map, under the id its answer gave; and which places the map
  # holds that no answer acknowledged (a server killed between its commit and its answer).
  if [ -f "$out/acknowledged.csv" ]; then
    psql "$db" -Atc "SELECT robot || ',' || sequence || ',' || id FROM places" |
      sort >"$out/stored.txt"
    tail -n +2 "$out/acknowledged.csv" | sort >"$out/acknowledged.sorted"
    comm -23 "$out/acknowledged.sorted" "$out/stored.txt" >"$out/lost.txt"
    comm -13 "$out/acknowledged.sorted" "$out/stored.txt" >"$out/unacknowledged.txt"
    echo "fleet-pg: $(wc -l <"$out/acknowledged.sorted") places acknowledged," \
      "$(wc -l <"$out/lost.txt") of them missing from the map (OUT/lost.txt);" \
      "$(wc -l <"$out/unacknowledged.txt") stored without an answer (OUT/unacknowledged.txt)"
  else
    echo "fleet-pg: the fleet wrote no acknowledged.csv; see OUT/fleet.txt" >&2
  fi
fi

# Probes: every 8th frame of the run, asked through each server and a server started now.
dataset=$PLACEREC_DATA/rtabmap_indoor
images=()
while IFS=, read -r frame _ image _; do
  [ "$frame" = frame ] && continue
  ((frame % 8 == 0)) && images+=("$dataset/$image")
done <"$dataset/runs/corridor_loop.frames.csv"
start_server late "probe$servers"
for ((k = 0; k <= servers; k++)); do
  "$bin/placerec-client" query --robot "probe$k" --lcm-url "$lcm" --key-file "$out/keys" \
    "${images[@]}" 2>&1 | sed -E 's/[0-9.]+ ms//g; s/probe[0-9]+/probe/g' >"$out/probe$k.txt" || true
done
{
  echo "probe answers of ${#images[@]} frames; server $servers started after the fleet"
  for ((k = 1; k <= servers; k++)); do
    same=$(paste -d '\n' "$out/probe0.txt" "$out/probe$k.txt" | paste - - -d '\t' |
      awk -F'\t' '$1 == $2' | wc -l)
    echo "server $k: $same of $(wc -l <"$out/probe0.txt") lines equal to server 0's"
  done
} | tee "$out/probes.txt"

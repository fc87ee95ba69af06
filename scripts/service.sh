# Sourced by the scripts that run a placerec-server beside its clients (demo.sh, workers.sh,
# watch-changes.sh, fleet-pg.sh): running in a private network (or on the host's loopback), a
# server started and awaited, a process stopped. Expects $client (placerec-client) and $url (LCM
# URL) where it says so. Not a command: `source "$root/scripts/service.sh"` in such a script.

# Run on its own (e.g. with --help): this text, and nothing done.
if [ "${BASH_SOURCE[0]}" = "$0" ]; then
  sed -n '1,4p' "$0" | sed 's/^# \{0,1\}//'
  case "${1:-}" in --help | -h) exit 0 ;; esac
  exit 2
fi

# service_stage NAME ARG...: the second stage of a script that runs a server. The first run
# (PLACEREC_SERVICE_STAGE unset) re-runs the script with ARG...: as root in a private network
# namespace (loopback only), otherwise on the host's loopback (LCM TTL 0 keeps it there). The
# second run gets PLACEREC_SERVICE_STAGE=netns (loopback set up here) or host.
service_stage() {
  local name=$1
  shift
  case "${PLACEREC_SERVICE_STAGE:-}" in
    netns) service_private_network; return 0 ;;
    host) return 0 ;;
  esac
  if [ "$(id -u)" -eq 0 ] && unshare -n true 2>/dev/null; then
    echo "$name: running server and clients in a private network namespace"
    exec unshare -n -- env PLACEREC_SERVICE_STAGE=netns bash "$0" "$@"
  fi
  echo "$name: not root (or unshare is not allowed): using the host's loopback, LCM TTL 0"
  PLACEREC_SERVICE_STAGE=host exec bash "$0" "$@"
}

# Inside `unshare -n`: loopback up and multicast routed to it, so LCM stays on this machine.
service_private_network() {
  export PATH="$PATH:/usr/sbin:/sbin"
  ip link set lo up
  ip link set lo multicast on
  ip route add 224.0.0.0/4 dev lo
}

# service_start_server LOG ARG...: starts placerec-server ARG... (stderr to LOG), sets
# server_pid and waits until it answers `placerec-client status` on $url: 30 tries 1 s apart, each
# waiting up to 2 s for the answer (30 to 90 s in all).
# Returns 1, with the log's tail, when it does not come up.
service_start_server() {
  local log=$1
  shift
  "$@" 2> "$log" &
  server_pid=$!
  for _ in $(seq 1 30); do
    if "$client" status --lcm-url "$url" --timeout 2 > /dev/null 2>&1; then
      return 0
    fi
    kill -0 "$server_pid" 2>/dev/null || break
    # A status that fails at once (no server subscribed yet) must not use up the tries.
    sleep 1
  done
  echo "placerec-server did not come up; see $log" >&2
  tail -n 20 "$log" >&2
  return 1
}

# service_stop PID: SIGTERM and wait, when PID is set and running.
service_stop() {
  if [ -n "${1:-}" ] && kill -0 "$1" 2>/dev/null; then
    kill -TERM "$1"
    wait "$1" || true
  fi
}

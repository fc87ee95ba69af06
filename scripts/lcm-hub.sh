#!/usr/bin/env bash
# The LCM TCP hub that remote devices reach the server through (`--lcm-url tcpq://HOST:PORT` on
# placerec-server and placerec-client): LCM's own relay, class lcm.lcm.TCPService in the lcm.jar
# of Debian's liblcm-java, run with default-jre-headless (scripts/install-deps.sh installs both).
# Every message a connected client publishes goes to every connected client subscribed to its
# channel. The hub listens on PORT on every interface of the machine (the class takes no address)
# and has no access control of its own: frames are signed (proto/README.md, protocol 4).
#
#   scripts/lcm-hub.sh start PORT   start it in the background, wait until it accepts
#                                   connections; pid in $LCM_HUB_DIR/lcm-hub-PORT.pid, log beside
#   scripts/lcm-hub.sh stop PORT    stop the hub started by `start PORT` (SIGTERM; SIGKILL when it
#                                   is still alive 5 s later; exit 1 when even that fails)
#   scripts/lcm-hub.sh status PORT  exit 0 when the hub started by `start PORT` runs
#   scripts/lcm-hub.sh run PORT     run it in the foreground (tests; Ctrl-C stops it)
#
# LCM_HUB_DIR defaults to ${TMPDIR:-/tmp}; LCM_JAR to /usr/share/java/lcm.jar.
set -euo pipefail

usage() {
  sed -n '2,16p' "$0" | sed 's/^# \{0,1\}//'
}

if [ $# -lt 1 ] || [ "$1" = "--help" ] || [ "$1" = "-h" ]; then
  usage
  [ $# -ge 1 ] && exit 0
  exit 2
fi
command=$1
port=${2:-}
if ! [[ "$port" =~ ^[0-9]+$ ]] || [ "$port" -lt 1 ] || [ "$port" -gt 65535 ]; then
  echo "lcm-hub: give a TCP port (1-65535) after '$command', e.g. scripts/lcm-hub.sh $command 7700" >&2
  exit 2
fi
jar=${LCM_JAR:-/usr/share/java/lcm.jar}
dir=${LCM_HUB_DIR:-${TMPDIR:-/tmp}}
pid_file=$dir/lcm-hub-$port.pid
log_file=$dir/lcm-hub-$port.log

check_java() {
  if [ ! -f "$jar" ]; then
    echo "lcm-hub: $jar is missing; install liblcm-java (bash scripts/install-deps.sh)" >&2
    exit 1
  fi
  if ! command -v java >/dev/null; then
    echo "lcm-hub: no java; install default-jre-headless (bash scripts/install-deps.sh)" >&2
    exit 1
  fi
}

# Whether something accepts TCP connections on 127.0.0.1:PORT.
accepting() {
  (exec 3<>"/dev/tcp/127.0.0.1/$port") 2>/dev/null
}

# Whether process $1 is a hub on this port: its command line holds lcm.lcm.TCPService PORT (a pid
# alone may name another process by now, when the hub ended without removing its pid file).
is_hub() {
  local cmdline
  [[ "${1:-}" =~ ^[0-9]+$ ]] || return 1
  cmdline=$(tr '\0' ' ' 2>/dev/null <"/proc/$1/cmdline") || return 1
  [[ " $cmdline " == *" lcm.lcm.TCPService $port "* ]]
}

# Whether the hub named by the pid file runs. A pid file naming no hub is stale: removed.
running() {
  local pid
  [ -f "$pid_file" ] || return 1
  pid=$(cat "$pid_file" 2>/dev/null || true)
  if is_hub "$pid"; then
    return 0
  fi
  echo "lcm-hub: removed the stale pid file $pid_file (pid ${pid:-none} is no hub on port $port)" >&2
  rm -f "$pid_file"
  return 1
}

case "$command" in
  run)
    check_java
    exec java -cp "$jar" lcm.lcm.TCPService "$port"
    ;;
  start)
    check_java
    if running; then
      echo "lcm-hub: already running on port $port (pid $(cat "$pid_file"))"
      exit 0
    fi
    if accepting; then
      echo "lcm-hub: port $port is taken by another program; choose another port" >&2
      exit 1
    fi
    mkdir -p "$dir"
    nohup java -cp "$jar" lcm.lcm.TCPService "$port" >"$log_file" 2>&1 &
    pid=$!
    echo "$pid" >"$pid_file"
    # Our own child: kill -0 (its command line is not java's yet right after the fork).
    for _ in $(seq 1 100); do
      if accepting; then
        echo "lcm-hub: listening on port $port (pid $pid, log $log_file)"
        exit 0
      fi
      if ! kill -0 "$pid" 2>/dev/null; then break; fi
      sleep 0.1
    done
    echo "lcm-hub: the hub did not start on port $port; its log ($log_file):" >&2
    cat "$log_file" >&2 || true
    kill "$pid" 2>/dev/null || true
    rm -f "$pid_file"
    exit 1
    ;;
  stop)
    if ! running; then
      echo "lcm-hub: no hub started by this script runs on port $port"
      rm -f "$pid_file"
      exit 0
    fi
    pid=$(cat "$pid_file")
    kill "$pid" 2>/dev/null || true
    for _ in $(seq 1 50); do
      is_hub "$pid" || break
      sleep 0.1
    done
    if is_hub "$pid"; then
      echo "lcm-hub: the hub (pid $pid, port $port) is still alive 5 s after SIGTERM; sending SIGKILL" >&2
      kill -9 "$pid" 2>/dev/null || true
      for _ in $(seq 1 20); do
        is_hub "$pid" || break
        sleep 0.1
      done
      if is_hub "$pid"; then
        echo "lcm-hub: the hub (pid $pid, port $port) is still alive after SIGKILL; it may belong to" \
          "another user (run as that user or root) or hang in the kernel (see ps -o stat,wchan -p $pid)" >&2
        exit 1
      fi
      rm -f "$pid_file"
      echo "lcm-hub: stopped with SIGKILL (port $port)"
      exit 0
    fi
    rm -f "$pid_file"
    echo "lcm-hub: stopped (port $port)"
    ;;
  status)
    if running; then
      echo "lcm-hub: running on port $port (pid $(cat "$pid_file"))"
    else
      echo "lcm-hub: not running on port $port"
      exit 1
    fi
    ;;
  *)
    echo "lcm-hub: unknown command '$command' (start, stop, status, run; see --help)" >&2
    exit 2
    ;;
esac

#!/usr/bin/env bash
# A throw-away PostgreSQL cluster for tests and demos of several servers on one map
# (`placerec-server --db postgresql://...`, common/storage/README.md). The cluster lives in one
# folder: initdb'd there, run as the `postgres` user when called as root (PostgreSQL refuses to
# run as root), listening on a unix socket in that folder only (no TCP), with one database
# `placerec`. Debian's postgresql-15 provides the binaries (scripts/install-deps.sh).
#
#   scripts/pg.sh start DIR   create the cluster in DIR when it holds none, start it, wait until it
#                             accepts connections and print its URL
#   scripts/pg.sh url DIR     print the URL of the cluster in DIR (for --db)
#   scripts/pg.sh down DIR    stop the cluster and keep its data (`start DIR` brings it back)
#   scripts/pg.sh stop DIR    stop the cluster and remove DIR with everything in it
#
# DIR must be an absolute path whose parent folders the postgres user can enter (e.g. under /tmp)
# and short enough for a unix socket path (about 90 characters). Exit code 3 when the PostgreSQL
# binaries are missing (tests skip then).
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
dir=${2:-}
if [ -z "$dir" ] || [ "${dir:0:1}" != "/" ]; then
  echo "pg: give the cluster's folder as an absolute path after '$command', e.g. scripts/pg.sh $command /tmp/placerec-pg" >&2
  exit 2
fi
dir=${dir%/}
data=$dir/data
port=5432  # only names the socket file $dir/.s.PGSQL.5432; there is no TCP listener

bindir=""
for candidate in $(ls -d /usr/lib/postgresql/*/bin 2>/dev/null | sort -V -r); do
  if [ -x "$candidate/initdb" ] && [ -x "$candidate/pg_ctl" ]; then
    bindir=$candidate
    break
  fi
done

need_binaries() {
  if [ -z "$bindir" ]; then
    echo "pg: the PostgreSQL server binaries (initdb, pg_ctl) are missing; install postgresql-15 (bash scripts/install-deps.sh)" >&2
    exit 3
  fi
}

# Runs a command as the cluster's owner: postgres when we are root, ourselves otherwise.
as_owner() {
  if [ "$(id -u)" -eq 0 ]; then
    runuser -u postgres -- "$@"
  else
    "$@"
  fi
}

url() {
  echo "postgresql:///placerec?host=$dir&port=$port&user=postgres"
}

running() {
  [ -n "$bindir" ] && [ -f "$data/postmaster.pid" ] && as_owner "$bindir/pg_ctl" -D "$data" status >/dev/null 2>&1
}

case "$command" in
  start)
    need_binaries
    if [ ! -f "$data/PG_VERSION" ]; then
      mkdir -p "$dir"
      if [ "$(id -u)" -eq 0 ]; then chown postgres: "$dir"; fi
      chmod 700 "$dir"
      as_owner "$bindir/initdb" -D "$data" -U postgres --auth=trust --no-instructions --no-sync \
        -E UTF8 --locale=C >"$dir/initdb.log" 2>&1 || {
        echo "pg: initdb failed; its log ($dir/initdb.log):" >&2
        cat "$dir/initdb.log" >&2
        exit 1
      }
      created=1
    else
      created=0
    fi
    if ! running; then
      as_owner "$bindir/pg_ctl" -D "$data" -l "$dir/server.log" -w -t 30 \
        -o "-c listen_addresses='' -k $dir -p $port -c fsync=on -c max_connections=50" \
        start >/dev/null || {
        echo "pg: the cluster did not start; its log ($dir/server.log):" >&2
        tail -n 30 "$dir/server.log" >&2 || true
        exit 1
      }
    fi
    if [ "$created" = 1 ]; then
      as_owner "$bindir/createdb" -h "$dir" -p "$port" -U postgres placerec
    fi
    url
    ;;
  url)
    url
    ;;
  down)
    if running; then
      as_owner "$bindir/pg_ctl" -D "$data" -m fast -w -t 30 stop >/dev/null
    fi
    ;;
  stop)
    if running; then
      as_owner "$bindir/pg_ctl" -D "$data" -m immediate -w -t 30 stop >/dev/null || true
    fi
    case "$dir" in
      / | /tmp | /var | /home | /root) echo "pg: refusing to remove $dir" >&2; exit 1 ;;
    esac
    rm -rf "$dir"
    ;;
  *)
    echo "pg: unknown command '$command' (start, url, down, stop; see --help)" >&2
    exit 2
    ;;
esac

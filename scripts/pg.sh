#!/usr/bin/env bash
# A throw-away PostgreSQL cluster for tests and demos of several servers on one map
# (`placerec-server --db postgresql://...`, common/storage/README.md). The cluster lives in one
# folder: initdb'd there, run as the `postgres` user when called as root (PostgreSQL refuses to
# run as root), listening on a unix socket in that folder only (no TCP), with one database
# `placerec`. Debian's postgresql-15 provides the binaries (scripts/install-deps.sh).
#
#   scripts/pg.sh start DIR   create the cluster in DIR when it holds none (DIR must be missing or
#                             empty then), start it, create database placerec when it is missing,
#                             wait until it accepts connections and print its URL
#   scripts/pg.sh url DIR     print the URL of the cluster in DIR (for --db)
#   scripts/pg.sh down DIR    stop the cluster and keep its data (`start DIR` brings it back)
#   scripts/pg.sh stop DIR    stop the cluster and remove DIR with everything in it; refused when
#                             DIR holds anything pg.sh did not make
#
# DIR must be an absolute path whose parent folders the postgres user can enter (e.g. under /tmp),
# short enough for a unix socket path (about 90 characters), without spaces, quotes or any of
# & ? # % (they break the socket option or the URL). Exit code 3 when the PostgreSQL binaries are
# missing (tests skip then).
set -euo pipefail

usage() {
  sed -n '2,19p' "$0" | sed 's/^# \{0,1\}//'
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
# The folder itself, as every command names it: `stop /tmp/x//` is `stop /tmp/x`, and a symlink
# is followed to the folder it names.
dir=$(realpath -m -- "$dir")
if [ "$dir" = / ]; then
  echo "pg: / cannot be a cluster's folder; give a folder of its own, e.g. scripts/pg.sh $command /tmp/placerec-pg" >&2
  exit 2
fi
case "$dir" in
  *[[:space:]\"\'\&\?#%]*)
    echo "pg: the folder '$dir' has a space, a quote or one of & ? # % in its path, which break" \
      "the server's socket option or the URL; give another folder, e.g. /tmp/placerec-pg" >&2
    exit 2
    ;;
esac
data=$dir/data
port=5432  # only names the socket file $dir/.s.PGSQL.5432; there is no TCP listener

bindir=""
for candidate in $(ls -d /usr/lib/postgresql/*/bin 2>/dev/null | sort -V -r); do
  if [ -x "$candidate/initdb" ] && [ -x "$candidate/pg_ctl" ] && [ -x "$candidate/psql" ]; then
    bindir=$candidate
    break
  fi
done

need_binaries() {
  if [ -z "$bindir" ]; then
    echo "pg: the PostgreSQL server binaries (initdb, pg_ctl, psql) are missing; install postgresql-15 (bash scripts/install-deps.sh)" >&2
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

# The entries of DIR that pg.sh did not make (one a line): anything but data/ (when it holds a
# cluster, or initdb.log says pg.sh ran initdb there), initdb.log, server.log and the server's
# socket and lock files .s.PGSQL.*.
foreign_entries() {
  local entry name
  for entry in "$dir"/* "$dir"/.[!.]* "$dir"/..?*; do
    [ -e "$entry" ] || [ -L "$entry" ] || continue
    name=${entry##*/}
    case "$name" in
      data)
        if [ -d "$entry" ] && [ ! -L "$entry" ] &&
          { [ -f "$entry/PG_VERSION" ] || [ -f "$dir/initdb.log" ]; }; then
          continue
        fi
        ;;
      initdb.log | server.log)
        if [ -f "$entry" ] && [ ! -L "$entry" ]; then continue; fi
        ;;
      .s.PGSQL.*)
        if [ ! -L "$entry" ]; then continue; fi
        ;;
    esac
    echo "$name"
  done
}

case "$command" in
  start)
    need_binaries
    if [ -e "$dir" ] && [ ! -d "$dir" ]; then
      echo "pg: $dir exists and is not a folder; give a missing or empty folder for a new cluster" >&2
      exit 1
    fi
    if [ ! -f "$data/PG_VERSION" ]; then
      # A new cluster goes only into a folder of its own: DIR's owner and mode are changed below.
      if [ -d "$dir" ] && [ -n "$(ls -A -- "$dir")" ]; then
        echo "pg: $dir is not empty and holds no cluster of pg.sh (no data/PG_VERSION); give a missing" \
          "or empty folder. (What an interrupted first start left, only data/ and initdb.log," \
          "scripts/pg.sh stop $dir removes; it refuses a folder holding anything else.)" >&2
        exit 1
      fi
      mkdir -p "$dir"
      if [ "$(id -u)" -eq 0 ]; then chown postgres: "$dir"; fi
      chmod 700 "$dir"
      as_owner "$bindir/initdb" -D "$data" -U postgres --auth=trust --no-instructions --no-sync \
        -E UTF8 --locale=C >"$dir/initdb.log" 2>&1 || {
        echo "pg: initdb failed; its log ($dir/initdb.log):" >&2
        cat "$dir/initdb.log" >&2
        exit 1
      }
    fi
    if ! running; then
      as_owner "$bindir/pg_ctl" -D "$data" -l "$dir/server.log" -w -t 30 \
        -o "-c listen_addresses='' -k '$dir' -p $port -c fsync=on -c max_connections=50" \
        start >/dev/null || {
        echo "pg: the cluster did not start; its log ($dir/server.log):" >&2
        tail -n 30 "$dir/server.log" >&2 || true
        exit 1
      }
    fi
    # Checked on every start: a first start interrupted before createdb left the cluster without it.
    exists=$(as_owner "$bindir/psql" -X -h "$dir" -p "$port" -U postgres -d postgres \
      -Atc "SELECT 1 FROM pg_database WHERE datname='placerec'") || {
      echo "pg: the cluster in $dir runs but psql cannot ask it for database placerec; see $dir/server.log" >&2
      exit 1
    }
    if [ "$exists" != 1 ]; then
      as_owner "$bindir/createdb" -h "$dir" -p "$port" -U postgres placerec || {
        echo "pg: could not create database placerec in the cluster in $dir; see $dir/server.log" >&2
        exit 1
      }
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
    if [ ! -e "$dir" ] && [ ! -L "$dir" ]; then
      echo "pg: $dir does not exist; nothing to stop or remove"
      exit 0
    fi
    if [ ! -d "$dir" ]; then
      echo "pg: refusing to remove $dir: it is not a folder, so it holds no cluster of pg.sh" >&2
      exit 1
    fi
    case "$dir" in
      /tmp | /var | /var/tmp | /home | /root | /usr | /etc)
        echo "pg: refusing to remove $dir; give the cluster's own folder, e.g. /tmp/placerec-pg" >&2
        exit 1
        ;;
    esac
    foreign=$(foreign_entries)
    if [ -n "$foreign" ]; then
      count=$(echo "$foreign" | wc -l)
      shown=$(echo "$foreign" | head -n 5 | paste -sd ',' | sed 's/,/, /g')
      [ "$count" -le 5 ] || shown+=" and $((count - 5)) more"
      echo "pg: refusing to remove $dir: it holds $shown, which pg.sh did not make (it makes only" \
        "data/, initdb.log, server.log and .s.PGSQL.*); nothing was stopped or removed. Check the" \
        "folder; scripts/pg.sh down $dir stops a cluster in it and keeps the folder" >&2
      exit 1
    fi
    if running; then
      as_owner "$bindir/pg_ctl" -D "$data" -m immediate -w -t 30 stop >/dev/null || true
    fi
    rm -rf -- "$dir"
    ;;
  *)
    echo "pg: unknown command '$command' (start, url, down, stop; see --help)" >&2
    exit 2
    ;;
esac

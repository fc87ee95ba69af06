#!/usr/bin/env bash
# Prints one line of a placerec keys file (server/README.md "Keys"): a new random key for a robot
# or device, 32 bytes from /dev/urandom as 64 hex digits.
#
#   scripts/make-key.sh ID PERMISSION >> keys     PERMISSION: insert, query or both
#
# Give the server the whole file (placerec-server --keys keys; kill -HUP reloads it) and each
# robot or device a file with its own line only (placerec-client --key-file FILE). Keep both
# readable by their owner only (chmod 600); the server and the client warn otherwise.
set -euo pipefail

if [ $# -ne 2 ] || [ "$1" = "--help" ] || [ "$1" = "-h" ]; then
  sed -n '2,9p' "$0" | sed 's/^# \{0,1\}//'
  [ $# -ge 1 ] && { [ "$1" = "--help" ] || [ "$1" = "-h" ]; } && exit 0
  exit 2
fi
id=$1
permission=$2
if ! [[ "$id" =~ ^[A-Za-z0-9_.-]{1,64}$ ]]; then
  echo "make-key: the id must be 1 to 64 ASCII letters, digits, '_', '-' or '.'" >&2
  exit 2
fi
case "$permission" in
  insert | query | both) ;;
  *)
    echo "make-key: PERMISSION must be insert, query or both" >&2
    exit 2
    ;;
esac
key=$(od -An -v -tx1 -N32 /dev/urandom | tr -d ' \n')
printf '%s %s %s\n' "$id" "$permission" "$key"

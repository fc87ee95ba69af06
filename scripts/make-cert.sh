#!/usr/bin/env bash
# Makes a self-signed certificate for placerec-gateway, for tests and demos: DIR/cert.pem and
# DIR/key.pem (RSA 2048, 30 days, for localhost and 127.0.0.1, or the names given). A deployed
# gateway uses a certificate from the site's own authority instead.
# Usage: scripts/make-cert.sh DIR [NAME...]
set -euo pipefail

usage() {
  sed -n '2,5p' "$0" | sed 's/^# \{0,1\}//'
}

if [ $# -lt 1 ] || [ "$1" = "--help" ] || [ "$1" = "-h" ]; then
  usage
  [ $# -ge 1 ] && exit 0
  exit 2
fi
dir=$1
shift
names=("$@")
[ ${#names[@]} -gt 0 ] || names=(localhost 127.0.0.1)
san=""
for n in "${names[@]}"; do
  if [[ $n =~ ^[0-9.]+$ ]]; then san+="${san:+,}IP:$n"; else san+="${san:+,}DNS:$n"; fi
done
command -v openssl >/dev/null || {
  echo "make-cert: openssl is missing; install it (bash scripts/install-deps.sh)" >&2
  exit 1
}
mkdir -p -- "$dir" || {
  echo "make-cert: cannot make the folder $dir; give a folder you can write in" >&2
  exit 1
}
# openssl's progress dots go to stderr too: shown only when it fails.
if ! err=$(openssl req -x509 -newkey rsa:2048 -nodes -days 30 -subj "/CN=${names[0]}" \
  -addext "subjectAltName=$san" -keyout "$dir/key.pem" -out "$dir/cert.pem" 2>&1 >/dev/null); then
  echo "make-cert: openssl could not make the certificate; it said:" >&2
  echo "$err" | grep -v '^[.+*]*$' >&2 || true
  echo "make-cert: check that $dir can be written in and that each NAME is a host name or an" \
    "IPv4 address (given: ${names[*]})" >&2
  exit 1
fi
chmod 600 "$dir/key.pem"
echo "make-cert: $dir/cert.pem and $dir/key.pem for ${names[*]}"

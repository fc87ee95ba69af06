#!/usr/bin/env bash
# Makes a self-signed certificate for placerec-gateway, for tests and demos: DIR/cert.pem and
# DIR/key.pem (RSA 2048, 30 days, for localhost and 127.0.0.1, or the names given). A deployed
# gateway uses a certificate from the site's own authority instead.
# Usage: scripts/make-cert.sh DIR [NAME...]
set -euo pipefail
dir=${1:?usage: scripts/make-cert.sh DIR [NAME...]}
shift || true
names=("$@")
[ ${#names[@]} -gt 0 ] || names=(localhost 127.0.0.1)
san=""
for n in "${names[@]}"; do
  if [[ $n =~ ^[0-9.]+$ ]]; then san+="${san:+,}IP:$n"; else san+="${san:+,}DNS:$n"; fi
done
mkdir -p "$dir"
openssl req -x509 -newkey rsa:2048 -nodes -days 30 -subj "/CN=${names[0]}" \
  -addext "subjectAltName=$san" -keyout "$dir/key.pem" -out "$dir/cert.pem" 2>/dev/null
chmod 600 "$dir/key.pem"
echo "make-cert: $dir/cert.pem and $dir/key.pem for ${names[*]}"

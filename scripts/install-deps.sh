#!/usr/bin/env bash
# Installs every Debian package placerec needs to build, test and run. Safe to run twice:
# packages already present are left alone and apt is only called when something is missing.
# Usage: scripts/install-deps.sh   (as root, or through sudo when not root)
set -euo pipefail

usage() {
  sed -n '2,4p' "$0" | sed 's/^# \{0,1\}//'
}

if [ "${1:-}" = "--help" ] || [ "${1:-}" = "-h" ]; then
  usage
  exit 0
fi

packages=(
  build-essential cmake pkg-config git ca-certificates
  libopencv-dev libopencv-contrib-dev
  libeigen3-dev
  liblcm-dev liblcm-bin libglib2.0-dev
  libflann-dev libhnswlib-dev liblz4-dev libxxhash-dev
  libsqlite3-dev sqlite3
  libpq-dev postgresql-15
  libgoogle-glog-dev libboost-program-options-dev nlohmann-json3-dev
  libgtest-dev libgmock-dev libbenchmark-dev clang-format
  clang-15 libfuzzer-15-dev
  libcpp-httplib-dev libssl-dev openssl chromium chromium-driver
  iproute2 util-linux procps time
  liblcm-java default-jre-headless
)

missing=()
for p in "${packages[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed"; then
    missing+=("$p")
  fi
done

if [ ${#missing[@]} -eq 0 ]; then
  echo "install-deps: all ${#packages[@]} packages present"
  exit 0
fi

echo "install-deps: installing ${missing[*]}"
sudo_cmd=()
if [ "$(id -u)" -ne 0 ]; then
  command -v sudo >/dev/null || { echo "install-deps: run as root or install sudo" >&2; exit 1; }
  sudo_cmd=(sudo)
fi
export DEBIAN_FRONTEND=noninteractive
"${sudo_cmd[@]}" apt-get update -qq
"${sudo_cmd[@]}" apt-get install -y -qq --no-install-recommends "${missing[@]}"

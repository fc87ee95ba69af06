#!/usr/bin/env bash
# The main job: installs what is missing, builds, and feeds the Gardens Point
# day_left_then_day_right run through the recognition pipeline, printing each loop closure as it
# is found and a summary. Output (answers.csv, summary.json, pr_curve.png, match pictures) goes
# to out/demo/. Set PLACEREC_DATA when the data is not at ../shared/data.
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
build_dir=${BUILD_DIR:-$root/build}

bash "$root/scripts/build.sh"
data=${PLACEREC_DATA:-$root/../shared/data}
if [ ! -f "$data/gardens_point/runs/day_left_then_day_right.frames.csv" ]; then
  echo "demo: $data/gardens_point is missing; set PLACEREC_DATA to the folder holding gardens_point/" >&2
  exit 1
fi
exec "$build_dir/bin/placerec-eval" run --dataset "$data/gardens_point" \
  --run day_left_then_day_right --out "$root/out/demo" --print-loops "$@"

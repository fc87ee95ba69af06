#!/usr/bin/env bash
# Issue 22: do the two halves of a run's mapping pass, mapped apart and joined by `placerec-map
# merge`, answer the second pass as the single map does? Runs, with build/bin/placerec-eval and
# build/bin/placerec-map:
#   single   the whole run in one process (the reference answers)
#   restart  frames [0, S) into a map file, then the second pass [S, end) on it in a new process
#            (a restarted server: what a merged map can at best give)
#   merged   frames [0, S/2) into map A, [S/2, S) into map B (each a fresh process), A and B
#            merged into C, then the second pass on C
#   split    a control: A merged with the restart map's places from frame S/2 on (the map pruned
#            before it), so B's places are the single run's, only under B's renamed robot id
# S, the second pass's first frame, is the run's first revisit (positives.csv). Every run inserts
# the second pass's frames as it answers them, as the single run does. Prints, per frame of the
# second pass whose answer differs, both answers (each run against the single run, then merged
# and split against restart); OUT/compare.txt keeps them.
#
# DATASET is a folder, or a name under ${PLACEREC_DATA:-../shared/data}. Needs build/bin (build
# first: bash scripts/build.sh).
#
#   bash scripts/merge-halves.sh DATASET RUN OUT [placerec-eval run options...]
#   bash scripts/merge-halves.sh rtabmap_indoor corridor_loop out/merge_corridor
set -euo pipefail

usage() {
  sed -n '2,21p' "$0" | sed 's/^# \{0,1\}//'
}

if [ "${1:-}" = "--help" ] || [ "${1:-}" = "-h" ]; then
  usage
  exit 0
fi
[ $# -ge 3 ] || { usage; exit 2; }
root=$(cd "$(dirname "$0")/.." && pwd)
dataset=$1 run=$2 out=$3
shift 3
data=${PLACEREC_DATA:-$root/../shared/data}
[ -d "$dataset" ] && dir=$dataset || dir=$data/$dataset
positives=$dir/runs/$run.positives.csv
[ -f "$positives" ] || { echo "merge-halves: no $positives" >&2; exit 1; }
second=$(awk -F, 'NR > 1 && (m == "" || $1 + 0 < m) { m = $1 + 0 } END { print m }' "$positives")
case "$second" in '' | *[!0-9]*) echo "merge-halves: no revisit in $positives" >&2; exit 1 ;; esac
if [ "$second" -lt 2 ]; then
  echo "merge-halves: the first revisit is frame $second: no mapping pass to split" >&2
  exit 1
fi
half=$((second / 2))
eval_bin=$root/build/bin/placerec-eval
map_bin=$root/build/bin/placerec-map
# OUT is replaced only when empty or written by this script before (its marker file).
if [ -e "$out" ] && [ ! -d "$out" ]; then
  echo "merge-halves: $out exists and is not a directory; give another OUT" >&2
  exit 1
fi
if [ -d "$out" ] && [ -n "$(ls -A "$out")" ] && [ ! -f "$out/.merge-halves" ]; then
  echo "merge-halves: $out exists and was not written by merge-halves.sh; give another OUT" >&2
  exit 1
fi
rm -rf "$out"
mkdir -p "$out"
touch "$out/.merge-halves"
feed() { "$eval_bin" run --dataset "$dir" --run "$run" --pictures 0 --quiet "$@" >/dev/null; }

echo "merge-halves: $dataset/$run, mapping pass [0, $second), halves [0, $half) and [$half, $second)"
feed --out "$out/single" --db "$out/single.db" "$@"
feed --out "$out/first" --max-frames "$second" --db "$out/restart.db" "$@"
cp "$out/restart.db" "$out/first.db"  # the process has ended: no -wal file is left
feed --out "$out/restart" --first-frame "$second" --db "$out/restart.db" "$@"
feed --out "$out/a" --max-frames "$half" --db "$out/a.db" "$@"
feed --out "$out/b" --first-frame "$half" --max-frames "$second" --db "$out/b.db" "$@"
"$map_bin" merge "$out/a.db" "$out/b.db" --out "$out/merged.db"
"$map_bin" info --db "$out/merged.db" > "$out/merged_info.txt"
feed --out "$out/merged" --first-frame "$second" --db "$out/merged.db" "$@"
half_utime=$(awk -F, -v f="$half" 'NR > 1 && $1 == f { print $4 }' "$dir/runs/$run.frames.csv")
"$map_bin" prune --db "$out/first.db" --before "$half_utime" >/dev/null
"$map_bin" merge "$out/a.db" "$out/first.db" --out "$out/split.db"
"$map_bin" info --db "$out/split.db" > "$out/split_info.txt"
feed --out "$out/split" --first-frame "$second" --db "$out/split.db" "$@"

# frame,reference,score of the second pass: run $2's against run $1's.
compare() {
  awk -F, -v second="$second" -v base="$1" -v name="$2" '
    FNR == 1 { next }
    NR == FNR { if ($1 + 0 >= second) { ref[$1] = $2; score[$1] = $3 }; next }
    { n++; if ($2 == ref[$1] && $3 == score[$1]) { same++; next }
      if ($2 == ref[$1]) sameref++
      printf "  frame %s: %s %s (score %s), %s %s (score %s)\n", $1, base, ref[$1], score[$1], name, $2, $3 }
    END { printf "%s against %s: %d frames compared, %d answers identical, %d differ (%d of them the same reference, another score)\n",
                 name, base, n, same, n - same, sameref }' "$out/$1/answers.csv" "$out/$2/answers.csv"
}
{
  compare single restart
  compare single merged
  compare single split
  compare restart merged
  compare restart split
  compare split merged
} | tee "$out/compare.txt"

#!/usr/bin/env bash
# Run time of two builds of aosr, A and B (e.g. two optimisation levels), on the same commands: a closed-loop
# simulation and every model-based reconstructor on two datasets, one thread, REPS runs each, the builds
# alternating so that a slow spell of the machine hits both; prints the minimum per command and B/A, and whether
# every output has the same bytes in both builds. Used for bench/results/build.md ("Stop 58").
# Usage: bench/ab_runtime.sh BUILD_A BUILD_B [WORK_DIR]   (REPS=3 by default)
set -euo pipefail
[ $# -ge 2 ] || { echo "usage: $0 BUILD_A BUILD_B [WORK_DIR]" >&2; exit 2; }
src=$(cd "$(dirname "$0")/.." && pwd)
a=$(cd "$1" && pwd)/aosr
b=$(cd "$2" && pwd)/aosr
work=${3:-$(mktemp -d)}
reps=${REPS:-3}
for x in "$a" "$b"; do [ -x "$x" ] || { echo "$x: no aosr executable there" >&2; exit 2; }; done
mkdir -p "$work"
times="$work/times.txt"
: > "$times"
for s in paper-sim-r4 crowded-stars; do
  [ -f "$work/$s/manifest.json" ] || "$a" simulate "$src/data/scenes/$s.json" -o "$work/$s" > /dev/null
done
run() {  # LABEL BUILD COMMAND...
  local label=$1 build=$2
  shift 2
  local t0 t1
  t0=$(date +%s.%N)
  "$@" > /dev/null 2>&1 || { echo "$label $build failed" >&2; exit 1; }
  t1=$(date +%s.%N)
  echo "$label $build $(echo "$t1 - $t0" | bc)" >> "$times"
}
for _ in $(seq "$reps"); do
  for build in A B; do
    exe=$a
    [ $build = B ] && exe=$b
    run simulate-paper-sim-r4 $build "$exe" simulate "$src/data/scenes/paper-sim-r4.json" -o "$work/sim_$build" --threads 1
    for d in paper-sim-r4 crowded-stars; do
      for m in tikhonov linear tv map; do
        run "$d-$m" $build "$exe" reconstruct "$work/$d" -m $m -o "$work/out_${build}_${d}_$m.fits" --threads 1
      done
    done
  done
done
/usr/bin/python3 - "$times" <<'PY'
import collections, sys
t = collections.defaultdict(list)
for line in open(sys.argv[1]):
    label, build, s = line.split()
    t[(label, build)].append(float(s))
print(f"{'command':30s} {'A [s]':>8s} {'B [s]':>8s} {'B/A':>6s}")
for label in sorted({k[0] for k in t}):
    ta, tb = min(t[(label, 'A')]), min(t[(label, 'B')])
    print(f"{label:30s} {ta:8.2f} {tb:8.2f} {tb / ta:6.2f}")
PY
same=1
for f in "$work"/out_A_*.fits "$work"/sim_A/frames.fits; do
  g=${f/out_A_/out_B_}
  g=${g/sim_A/sim_B}
  cmp -s "$f" "$g" || { echo "differ: $f $g"; same=0; }
done
[ $same = 1 ] && echo "every output has the same bytes in both builds"

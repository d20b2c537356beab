#!/usr/bin/env bash
# Alternates VAMP (build.sh's driver) and manyhands binaries on one core, A B A B:
#   compare.sh ROBOT PAIRS BIN... 
# ROBOT: panda or baxter (the MotionBenchMaker sets, `data mbm`), ur5 or fetch (VAMP's robots, problems made
# by `manyhands data problems --per-set 100 --seed 1` with the first BIN: VAMP's own problem sets
# of those robots are deliberately not used). Extra `bench mbm` arguments: MH_ARGS.
# Prints per run: each set's median planning time (µs) / median iterations, and the overall
# median; manyhands plans with its derived settings and certified checks (`bench mbm
# --no-simplify`), VAMP with its own settings for the robot (range: scripts' ROBOT_RRT_RANGES).
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
root="$(cd "$here/../.." && pwd)"
out="${OUT:-$root/target/vamp}"
robot=$1; pairs=$2; shift 2
case $robot in
  panda|baxter) range=1.0; [ "$robot" = baxter ] && range=0.5; mh=(--robot "$robot")
    # Where `bench mbm --robot panda` finds the MotionBenchMaker data (see README.md).
    for d in "${MANYHANDS_MBM_DIR:-}" "$root/../shared/benchmarks/mbm" \
      "${MANYHANDS_CACHE_DIR:-${XDG_CACHE_HOME:-$HOME/.cache}/manyhands}/mbm"; do
      if [ -n "$d" ] && [ -f "$d/$robot/problems.json" ]; then problems="$d/$robot/problems.json"; break; fi
    done
    [ -n "${problems:-}" ] || { echo "no MotionBenchMaker data: cargo run --release -- data mbm" >&2; exit 1; } ;;
  ur5) range=1.5 ;;
  fetch) range=1.0 ;;
  *) echo "robot: panda, baxter, ur5 or fetch" >&2; exit 2 ;;
esac
if [ "$robot" = ur5 ] || [ "$robot" = fetch ]; then
  urdf=$(ls "$out/robots/$robot/"*_spherized.urdf); srdf=$(ls "$out/robots/$robot/"*.srdf)
  problems="$out/$robot-problems.json"
  [ -f "$problems" ] || "$1" data problems --robot "$urdf" --srdf "$srdf" --per-set 100 --seed 1 --out "$problems" >&2
  mh=(--robot "$urdf" --srdf "$srdf" --problems "$problems")
fi
python3 "$here/problems_to_txt.py" "$problems" > "$out/$robot.txt"
for _ in $(seq 1 "$pairs"); do
  taskset -c 1 "$out/driver" "$robot" "$out/$robot.txt" 1 "$range" | python3 -c "
import statistics as st, sys, collections
rows = [l.split('\t') for l in sys.stdin]
by = collections.defaultdict(list)
for s, i, ok, it, ns in rows:
    by[s].append((int(ns) / 1000, int(it)))
print('vamp'.ljust(16), ' '.join('%s %.1f/%g' % (s, st.median(x[0] for x in v), st.median(x[1] for x in v)) for s, v in by.items()),
      '| overall %.1f, solved %d of %d' % (st.median(int(r[4]) / 1000 for r in rows), sum(int(r[2]) for r in rows), len(rows)))"
  for bin in "$@"; do
    # shellcheck disable=SC2086
    taskset -c 1 "$bin" bench mbm "${mh[@]}" --no-simplify --json ${MH_ARGS:-} | python3 -c "
import json, sys
d = json.load(sys.stdin)
o = d['overall']
print('$(basename "$bin")'[:16].ljust(16), ' '.join('%s %.1f/%g' % (s['set'], s['median_us'], s['iterations_median']) for s in d['sets']),
      '| overall %.1f, solved %d of %d, invalid %d' % (o['median_us'], o['solved'], o['runs'], o['invalid']))"
  done
done

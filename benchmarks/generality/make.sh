#!/bin/sh
# Rebuilds the generality suite (benchmarks/generality/README.md) from the repository root:
#   MANYHANDS=target/release/manyhands sh benchmarks/generality/make.sh
# Deterministic: the same binary gives the same files (robots from make_robots.py, spheres from
# `manyhands robot spherize`, problems from `manyhands data problems` with a fixed seed and an
# iteration bound).
set -eu
MH=${MANYHANDS:-target/release/manyhands}
HERE=benchmarks/generality
PER_SET=${PER_SET:-50}
TOL=0.03
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
python3 "$HERE/make_robots.py" "$tmp"
for r in ur5like xarm7like fetchlike; do
    "$MH" robot spherize "$tmp/$r.urdf" --tolerance $TOL --out "$HERE/$r"
done
# The dual-arm torso: robots/armar.urdf (the product's humanoid) spherized, its two 7-joint
# arms planned (base and hip at zero).
"$MH" robot spherize robots/armar.urdf --tolerance $TOL --out "$HERE/armar_arms"
ARMS=""
for side in left right; do
    for j in shoulder_1 shoulder_2 shoulder_3 elbow wrist_1 wrist_2 wrist_3; do
        ARMS="$ARMS${ARMS:+,}${side}_$j"
    done
done
for r in ur5like xarm7like fetchlike; do
    "$MH" data problems --robot "$HERE/$r/${r}_spherized.urdf" --per-set "$PER_SET" --seed 1 \
        --out "$HERE/$r/problems.json"
done
"$MH" data problems --robot "$HERE/armar_arms/armar_spherized.urdf" --joints "$ARMS" \
    --per-set "$PER_SET" --seed 1 --out "$HERE/armar_arms/problems.json"

#!/usr/bin/env bash
# Builds the outside reference (VAMP 0.6.4's RRTC, see README.md) into $OUT (default
# target/vamp): downloads VAMP's source package from PyPI and pdqsort's header (pinned as VAMP's
# CMake pins them), or takes them from VAMP_SDIST (the unpacked package) and PDQSORT_H.
# Needs g++ ≥ 11 and Eigen 3.4 (Debian: libeigen3-dev), python3 with pip.
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
root="$(cd "$here/../.." && pwd)"
out="${OUT:-$root/target/vamp}"
mkdir -p "$out"
if [ -z "${VAMP_SDIST:-}" ]; then
  python3 -m pip download --quiet --no-deps --no-binary :all: "vamp-planner==0.6.4" -d "$out/dl"
  tar -xzf "$out/dl/vamp_planner-0.6.4.tar.gz" -C "$out"
  VAMP_SDIST="$out/vamp_planner-0.6.4"
fi
if [ -z "${PDQSORT_H:-}" ]; then
  PDQSORT_H="$out/dep/pdqsort.h"
  mkdir -p "$out/dep"
  [ -f "$PDQSORT_H" ] || curl -fsSL -o "$PDQSORT_H" \
    https://raw.githubusercontent.com/orlp/pdqsort/b1ef26a55cdb60d236a5cb199c4234c704f46726/pdqsort.h
fi
rm -rf "$out/include" && cp -r "$VAMP_SDIST/src/impl" "$out/include"
cp "$here/nn_linear.hh" "$out/include/vamp/planning/nn.hh"
mkdir -p "$out/dep" && [ "$PDQSORT_H" -ef "$out/dep/pdqsort.h" ] || cp "$PDQSORT_H" "$out/dep/pdqsort.h"
# VAMP's Release flags (its cmake/CompilerSettings.cmake, GCC on x86-64).
g++ -std=c++17 -O3 -march=native -mavx2 -fno-math-errno -fno-signed-zeros -fno-trapping-math \
  -fno-rounding-math -ffp-contract=fast -fassociative-math -Wno-ignored-attributes \
  -I "$out/include" -I /usr/include/eigen3 -I "$out/dep" "$here/driver.cc" -o "$out/driver"
# The robots of VAMP's package (their URDF/SRDF), for `manyhands data problems` and `bench mbm`.
for r in panda ur5 fetch; do
  mkdir -p "$out/robots/$r" && cp "$VAMP_SDIST/resources/$r/"*.urdf "$VAMP_SDIST/resources/$r/"*.srdf "$out/robots/$r/"
done
echo "$out/driver"

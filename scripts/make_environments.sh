#!/usr/bin/env bash
# Writes the demo and test environments with `obscura sky` (docs/cli.md
# "sky", docs/math.md §14.7): analytic lat-long maps made here, nothing
# downloaded. Into OUTDIR (created):
#
#   overcast.exr        CIE overcast sky, Lz = 1, black ground     512x256
#   gradient.exr        L = 1 + 0.5 w_up                           512x256
#   texel.exr           one texel of radiance 1000 at elevation 30,
#                       azimuth 60, the rest black                 512x256
#   half.exr            upper hemisphere 1, lower black            512x256
#   sunsky_15.exr       Preetham clear sky, turbidity 3, the sun
#   sunsky_45.exr       at elevation 15 / 45 degrees, azimuth 30  2048x1024
#
# At 2048x1024 a texel spans 0.176 degrees, so the 0.53-degree sun (solid
# angle 6.72e-5 sr, about 7.1 / cos(elevation) texels of area: 7.4 at 15
# degrees, 10.1 at 45) touches 14-18 texels, each holding the disc's share
# of it (tests/test_sky.cpp prints the counts).
#
#   scripts/make_environments.sh OUTDIR
#
# Environment: BUILD_DIR (default build) or OBSCURA (the program).
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
if [[ $# -ne 1 ]]; then
  echo "usage: $0 OUTDIR" >&2
  exit 2
fi
out="$1"
obscura="${OBSCURA:-$root/${BUILD_DIR:-build}/obscura}"
if [[ ! -x "$obscura" ]]; then
  echo "make_environments: $obscura is not built (set BUILD_DIR or OBSCURA)" >&2
  exit 1
fi
mkdir -p "$out"
sky() {
  local name="$1"
  shift
  "$obscura" sky "$@" -o "$out/$name.exr"
  echo "$out/$name.exr"
}
sky overcast overcast --res 512x256
sky gradient gradient --res 512x256 -p a=1 -p b=0.5
sky texel texel --res 512x256 -p elevation=30 -p azimuth=60 -p L=1000
sky half half --res 512x256
for e in 15 45; do
  sky "sunsky_$e" sunsky --res 2048x1024 -p turbidity=3 -p elevation="$e" -p azimuth=30
done

#!/usr/bin/env bash
# The measurements of docs/performance.md "Environment lighting": `gi` under
# the sun-and-sky map, each figure from whole `obscura render` processes.
#
#   bench/env_bench.sh [tte|speed|cycles|all] OUTDIR
#
#   tte     time to RMSE 0.01 of shaded.R/G/B on scenes/default.gltf,
#           320x180, 2 threads: two MIS references (REF_SPP each, seeds
#           1001, 1002), then sweeps of spp 1, 2, 4, ... with
#           sampling=mis (to MIS_MAX) and sampling=cosine (to COS_MAX),
#           seed 0; obscura_bench_env_stats interpolates the crossing.
#   speed   gi at equal spp (SPEED_RES, SPEED_SPP, 2 threads) under --sky
#           and under the map with sampling=cosine and sampling=mis, on
#           scenes/default.gltf and the viking room, RUNS interleaved runs;
#           prints obscura:renderTime and the ray counts of each.
#   cycles  scenes/default.gltf, 512x512, 64 spp, 2 threads: `obscura
#           render -i gi` (max-depth unlimited and 12) against Cycles
#           (bench/cycles/render_env.py, 12 diffuse bounces), RUNS runs,
#           whole-process wall seconds (/usr/bin/time -f %e) and the mean
#           radiance over the pixels Obscura's A = 1.
#
# The map: `obscura sky sunsky --res 2048x1024 -p turbidity=3 -p
# elevation=45 -p azimuth=30` (scripts/make_environments.sh's sunsky_45;
# sun_radiance is the default 1e5 x Lz, Lz = 1).
#
# Environment: BUILD_DIR (default build), RUNS (5), REF_SPP (2048),
# MIS_MAX (2048), COS_MAX (256), SPEED_RES (640x360), SPEED_SPP (16),
# BLENDER (blender).
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
if [[ $# -ne 2 ]]; then
  echo "usage: $0 tte|speed|cycles|all OUTDIR" >&2
  exit 2
fi
what="$1"
out="$2"
build="$root/${BUILD_DIR:-build}"
obscura="$build/obscura"
stats="$build/bench/obscura_bench_env_stats"
for x in "$obscura" "$stats"; do
  [[ -x "$x" ]] || { echo "env_bench: $x is not built (ninja obscura obscura_bench_env_stats)" >&2; exit 1; }
done
runs="${RUNS:-5}"
default="$root/scenes/default.gltf"
viking="$root/../shared/scenes/viking_room/viking_room.glb"
mkdir -p "$out"
map="$out/sunsky_45.exr"
[[ -f "$map" ]] || "$obscura" sky sunsky --res 2048x1024 -p turbidity=3 -p elevation=45 -p azimuth=30 -o "$map"

header() {  # FILE: renderTime and ray counts
  "$stats" header "$1" obscura:renderTime obscura:rays:camera obscura:rays:closest obscura:rays:occlusion \
    obscura:rays:total | tr '\n' ' '
  echo
}

tte() {
  local d="$out/tte" r=(--res 320x180 --threads 2 --quiet)
  mkdir -p "$d"
  for s in 1001 1002; do
    [[ -f "$d/ref_$s.exr" ]] || "$obscura" render "$default" -i gi --environment "$map" --spp "${REF_SPP:-2048}" \
      --seed "$s" "${r[@]}" -o "$d/ref_$s.exr"
  done
  for m in mis cosine; do
    local max="${MIS_MAX:-2048}" files=()
    [[ "$m" == cosine ]] && max="${COS_MAX:-256}"
    for ((n = 1; n <= max; n *= 2)); do
      "$obscura" render "$default" -i gi -p sampling="$m" --environment "$map" --spp "$n" --seed 0 "${r[@]}" \
        -o "$d/${m}_$n.exr"
      files+=("$d/${m}_$n.exr")
    done
    echo "== sampling=$m"
    "$stats" rmse --target 0.01 "$d/ref_1001.exr" "$d/ref_1002.exr" -- "${files[@]}"
  done
}

speed() {
  local d="$out/speed" res="${SPEED_RES:-640x360}" spp="${SPEED_SPP:-16}"
  mkdir -p "$d"
  for scene in default viking; do
    local path="$default"
    [[ "$scene" == viking ]] && path="$viking"
    [[ -f "$path" ]] || { echo "speed: $path missing, skipped"; continue; }
    for ((i = 1; i <= runs; ++i)); do
      for c in sky cosine mis; do
        local light=(--environment "$map" -p sampling="$c")
        [[ "$c" == sky ]] && light=(--sky 1,1,1)
        local f="$d/${scene}_${c}_$i.exr"
        "$obscura" render "$path" -i gi "${light[@]}" --res "$res" --spp "$spp" --threads 2 --quiet -o "$f"
        echo "$scene $c run $i: $(header "$f")"
      done
    done
  done
}

cycles() {
  local d="$out/cycles" blender="${BLENDER:-blender}"
  mkdir -p "$d"
  for ((i = 1; i <= runs; ++i)); do
    for depth in -1 12; do
      local f="$d/obscura_d${depth}_$i.exr"
      /usr/bin/time -f "obscura max-depth=$depth run $i wall_seconds: %e" \
        "$obscura" render "$default" -i gi -p max-depth="$depth" --environment "$map" --res 512x512 --spp 64 \
        --threads 2 --quiet -o "$f"
      echo "  $(header "$f")"
    done
    /usr/bin/time -f "cycles run $i wall_seconds: %e" \
      "$blender" -b --factory-startup -P "$root/bench/cycles/render_env.py" -- --scene "$default" \
      --environment "$map" --res 512x512 --spp 64 --threads 2 --out "$d/cycles_$i.exr" 2>&1 |
      grep -E "seconds|mean_rgb|wall_seconds"
  done
  for depth in -1 12; do
    "$stats" mean "$d/obscura_d-1_1.exr" "$d/obscura_d${depth}_1.exr" shaded.R,shaded.G,shaded.B
  done
  "$stats" mean "$d/obscura_d-1_1.exr" "$d/cycles_1.exr" R,G,B
}

case "$what" in
  tte) tte ;;
  speed) speed ;;
  cycles) cycles ;;
  all) tte; speed; cycles ;;
  *) echo "usage: $0 tte|speed|cycles|all OUTDIR" >&2; exit 2 ;;
esac

#!/usr/bin/env bash
# Reproduces every figure of docs/iao_fit.md: `obscura fit` on the bundled
# scene, on the viking room and the classic Cornell box of ../shared/scenes
# (each alone), and on all four scenes pooled (the two Cornell boxes too);
# then `obscura compare` of `multibounce` with the published (`improved`) and
# the fitted coefficients against `gi` on each of the three scenes.
#
#   scripts/iao_fit.sh [OUT]          # default OUT=out/iao_fit
#
# Environment: BUILD_DIR (default build), THREADS (default 0 = all cores).
# Each fit prints its coefficients, standard errors and residuals to
# OUT/NAME.txt and writes OUT/NAME.json and the histogram OUT/NAME.csv; each
# compare writes OUT/compare_NAME/ (summary.md, results.csv) and its table to
# OUT/compare_NAME.txt. A missing shared scene is skipped with a message.
set -euo pipefail
OUT=${1:-out/iao_fit}
BIN=${BUILD_DIR:-build}/obscura
S=../shared/scenes
THREADS=${THREADS:-0}
mkdir -p "$OUT"
FIT=(--res 240x135 --spp 128 --threads "$THREADS" -q)
declare -A SCENES=([default]=scenes/default.gltf [viking]=$S/viking_room/viking_room.glb
                   [cornell]=$S/cornell_box_classic/cornell-box.gltf)
NAMES=()
for name in default viking cornell; do
  if [[ -f ${SCENES[$name]} ]]; then NAMES+=("$name"); else echo "iao_fit.sh: ${SCENES[$name]} is missing; skipped" >&2; fi
done
POOL=()
for name in "${NAMES[@]}"; do
  "$BIN" fit "${SCENES[$name]}" -o "$OUT/$name.json" --histogram "$OUT/$name.csv" "${FIT[@]}" > "$OUT/$name.txt"
  POOL+=("${SCENES[$name]}")
done
[[ -f $S/cornell_box_suzanne/cornell-box.glb ]] && POOL+=("$S/cornell_box_suzanne/cornell-box.glb")
"$BIN" fit "${POOL[@]}" -o "$OUT/pooled.json" --histogram "$OUT/pooled.csv" "${FIT[@]}" > "$OUT/pooled.txt"
for name in "${NAMES[@]}"; do
  "$BIN" compare "${SCENES[$name]}" -o "$OUT/compare_$name" --res 160x90 --spp 64 --reference-spp 1024 \
    --threads "$THREADS" -q \
    -c multibounce:mapping=gtao,rays=4 -c multibounce:mapping=improved,rays=4 \
    -c "multibounce:mapping=fitted,fit=$OUT/$name.json,rays=4" \
    -c "multibounce:mapping=fitted,fit=$OUT/pooled.json,rays=4" > "$OUT/compare_$name.txt"
done

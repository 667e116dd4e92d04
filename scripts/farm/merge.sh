#!/usr/bin/env bash
# Merges a shot's tiles into its frames (obscura merge), whatever runs it:
#
#   scripts/farm/merge.sh WORK/shot.sh [FRAME...]     # default: every frame of the shot
#
# A frame is left alone when its file is complete (scripts/farm/lib.sh,
# farm_complete) and no tile is newer; it is merged when all its tiles are
# complete. A frame with a missing or incomplete tile is reported and the
# script exits 1 after trying the others (submit.sh again redoes those tiles).
set -euo pipefail

if (($# < 1)); then
  echo "usage: $0 WORK/shot.sh [FRAME...]" >&2
  exit 2
fi
shot=$1
shift
source "$(dirname "${BASH_SOURCE[0]}")/lib.sh"
farm_load_shot "$shot"

tiles=$(farm_tiles)
if (($# == 0)); then
  set -- $(seq "$SHOT_FIRST" "$SHOT_STEP" "$SHOT_LAST")
fi
if ((tiles == 1)); then
  echo "farm: 1x1 grid: the tasks write the frames themselves; nothing to merge"
  exit 0
fi

failed=0
merged=0
for frame in "$@"; do
  [[ "$frame" =~ ^[0-9]+$ ]] && ((frame >= SHOT_FIRST && frame <= SHOT_LAST && (frame - SHOT_FIRST) % SHOT_STEP == 0)) ||
    farm_die "$shot: $frame is not a frame of the shot ($SHOT_FIRST-$SHOT_LAST:$SHOT_STEP)"
  final=$(farm_final_path "$frame")
  first_task=$(((frame - SHOT_FIRST) / SHOT_STEP * tiles))
  inputs=()
  for ((t = 0; t < tiles; t++)); do inputs+=("$(farm_task_output $((first_task + t)))"); done
  farm_read_headers "$final" "${inputs[@]}"
  missing=()
  newer=0
  for ((t = 0; t < tiles; t++)); do
    task=$((first_task + t))
    tile_file=${inputs[t]}
    if ! farm_complete "$tile_file" "$(farm_region "$t")" "$frame"; then
      missing+=("$task")
    elif [[ "$tile_file" -nt "$final" ]]; then
      newer=1
    fi
  done
  if farm_complete "$final" "$(farm_full_region)" "$frame" && ((newer == 0)); then
    echo "farm: frame $frame: $final is up to date"
    continue
  fi
  if ((${#missing[@]})); then
    echo "farm: error: frame $frame: tasks ${missing[*]} have no complete tile; resubmit the shot" >&2
    failed=$((failed + 1))
    continue
  fi
  start=$SECONDS
  if "$SHOT_OBSCURA" merge "$final" "${inputs[@]}"; then
    echo "farm: frame $frame: merged $tiles tiles into $final in $((SECONDS - start)) s"
    merged=$((merged + 1))
  else
    echo "farm: error: frame $frame: obscura merge failed" >&2
    failed=$((failed + 1))
  fi
done
echo "farm: merged $merged frame(s), $failed failed"
((failed == 0))

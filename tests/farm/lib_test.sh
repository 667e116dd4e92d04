#!/usr/bin/env bash
# scripts/farm/lib.sh without a scheduler or a render: the index scheme, the
# tile grid (every pixel in exactly one tile, for uneven sizes too), the '#'
# padding and the Slurm array lists. Run by tests/farm/slurm_test.sh; seconds.
set -euo pipefail
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)
source "$root/scripts/farm/lib.sh"

fails=0
check() {  # description, actual, expected
  if [[ "$2" != "$3" ]]; then
    echo "lib_test: FAIL: $1: got '$2', expected '$3'" >&2
    fails=$((fails + 1))
  fi
}

# Index scheme: task = frame_index * tiles + tile, for a few shots; each
# (frame, tile) pair appears exactly once.
for shot in "1 9 1 2 2" "1001 1010 3 3 1" "0 0 1 1 1" "5 20 5 4 3"; do
  read -r SHOT_FIRST SHOT_LAST SHOT_STEP SHOT_COLS SHOT_ROWS <<<"$shot"
  tiles=$((SHOT_COLS * SHOT_ROWS))
  declare -A seen=()
  n=0
  for ((f = SHOT_FIRST, i = 0; f <= SHOT_LAST; f += SHOT_STEP, i++)); do
    for ((t = 0; t < tiles; t++, n++)); do
      task=$((i * tiles + t))
      check "shot '$shot' task $task frame" "$(farm_frame_of "$task")" "$f"
      check "shot '$shot' task $task tile" "$(farm_tile_of "$task")" "$t"
      [[ -v "seen[$task]" ]] && check "shot '$shot' task $task" "twice" "once"
      seen[$task]=1
    done
  done
  check "shot '$shot' task count" "$(farm_task_count)" "$n"
  unset seen
done

# The grid partitions the frame: count each pixel's tiles.
for grid in "96 64 2 2" "97 61 3 7" "5 3 5 3" "1920 1080 7 1"; do
  read -r SHOT_W SHOT_H SHOT_COLS SHOT_ROWS <<<"$grid"
  area=0
  declare -A cover=()
  for ((t = 0; t < SHOT_COLS * SHOT_ROWS; t++)); do
    IFS=, read -r x0 y0 x1 y1 <<<"$(farm_region "$t")"
    ((x0 < x1 && y0 < y1)) || check "grid '$grid' tile $t" "empty" "non-empty"
    area=$((area + (x1 - x0) * (y1 - y0)))
    # Edges: each column/row boundary is shared by neighbours, never crossed.
    cover["x$x0-$x1"]=1
    cover["y$y0-$y1"]=1
  done
  check "grid '$grid' total area" "$area" "$((SHOT_W * SHOT_H))"
  xs=$(printf '%s\n' "${!cover[@]}" | sed -n 's/^x//p' | sort -t- -k1,1n | tr '\n' ' ')
  ys=$(printf '%s\n' "${!cover[@]}" | sed -n 's/^y//p' | sort -t- -k1,1n | tr '\n' ' ')
  # Consecutive intervals must chain 0 -> W (and 0 -> H) without gaps or overlaps.
  for axis in "x $SHOT_W $xs" "y $SHOT_H $ys"; do
    read -r name size rest <<<"$axis"
    at=0
    for iv in $rest; do
      check "grid '$grid' $name interval $iv starts where the last ended" "${iv%-*}" "$at"
      at=${iv#*-}
    done
    check "grid '$grid' $name intervals end at the frame's edge" "$at" "$size"
  done
  unset cover
done

check "pattern ####" "$(farm_pattern_frame /a/b.####.exr 7)" "/a/b.0007.exr"
check "pattern #" "$(farm_pattern_frame /a/b_#.exr 1234)" "/a/b_1234.exr"
check "pattern wider frame" "$(farm_pattern_frame b.##.exr 12345)" "b.12345.exr"
check "pattern without #" "$(farm_pattern_frame /a/still.exr 3)" "/a/still.exr"
check "pattern # in folder" "$(farm_pattern_frame '/s#1/b.###.exr' 5)" "/s#1/b.005.exr"

check "array spec run" "$(farm_array_spec 0 1 2 3 4 5 6 7)" "0-7"
check "array spec single" "$(farm_array_spec 6)" "6"
check "array spec mixed" "$(farm_array_spec 0 1 2 5 7 8 11)" "0-2,5,7-8,11"
check "array spec empty" "$(farm_array_spec)" ""

hdr=$'    obscura:region: "0,32,48,64"\n    obscura:spp: 8\n'
check "attr string" "$(farm_attr "$hdr" obscura:region)" "0,32,48,64"
check "attr number" "$(farm_attr "$hdr" obscura:spp)" "8"
check "attr absent" "$(farm_attr "$hdr" obscura:frame || echo absent)" "absent"

((fails == 0)) || { echo "lib_test: $fails failure(s)" >&2; exit 1; }
echo "lib_test: PASS"

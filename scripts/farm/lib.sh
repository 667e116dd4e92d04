# Shared by scripts/farm/{submit,task,merge}.sh; sourced, not run.
#
# A *shot* is described by a shot file (WORK/shot.sh, written by submit.sh with
# `declare -p`, so sourcing it is safe whatever the paths contain):
#   SHOT_FARM_DIR   absolute path of scripts/farm (the batch scripts run from
#                   Slurm's spool copy, so they cannot find their siblings)
#   SHOT_OBSCURA    the obscura binary (absolute)
#   SHOT_SCENE      the scene (absolute)
#   SHOT_W SHOT_H   frame size (--res)
#   SHOT_COLS SHOT_ROWS  tile grid
#   SHOT_FIRST SHOT_LAST SHOT_STEP  frames: FIRST, FIRST+STEP, ... <= LAST
#   SHOT_PATTERN    output pattern (absolute), one run of '#' = zero-padded frame
#   SHOT_WORK       work folder: shot.sh, tiles/, logs/
#   SHOT_OPTS       array: further `obscura render` options
#
# The index scheme (the same for Slurm, Deadline, OpenCue or a shell loop):
#   tiles = COLS * ROWS,  task = frame_index * tiles + tile,
#   frame_index = task / tiles, tile = task % tiles, frame = FIRST + frame_index * STEP,
#   tile t covers column t % COLS, row t / COLS of the grid, rows from the top:
#   [col*W/COLS, (col+1)*W/COLS) x [row*H/ROWS, (row+1)*H/ROWS) in integer division.

farm_die() {
  echo "farm: error: $*" >&2
  exit 1
}

farm_tiles() { echo $((SHOT_COLS * SHOT_ROWS)); }
farm_frame_count() { echo $(((SHOT_LAST - SHOT_FIRST) / SHOT_STEP + 1)); }
farm_task_count() { echo $(($(farm_frame_count) * $(farm_tiles))); }
# shellcheck disable=SC2017  # integer division on purpose: frame_index = task / tiles
farm_frame_of() { echo $((SHOT_FIRST + $1 / $(farm_tiles) * SHOT_STEP)); }  # task -> frame
farm_tile_of() { echo $(($1 % $(farm_tiles))); }                          # task -> tile

# Region X0,Y0,X1,Y1 of tile $1 (obscura render --region).
farm_region() {
  local t=$1 c r
  c=$((t % SHOT_COLS))
  r=$((t / SHOT_COLS))
  echo "$((c * SHOT_W / SHOT_COLS)),$((r * SHOT_H / SHOT_ROWS)),$(((c + 1) * SHOT_W / SHOT_COLS)),$(((r + 1) * SHOT_H / SHOT_ROWS))"
}

# The pattern with the run of '#' in its file name replaced by frame $2,
# zero-padded to the run's length (a name without '#' is the output of a
# one-frame shot; a '#' in a folder name is left alone).
farm_pattern_frame() {
  local dir="" name=$1 prefix rest hashes suffix
  if [[ "$1" == */* ]]; then
    dir=${1%/*}/
    name=${1##*/}
  fi
  prefix=${name%%#*}
  [[ "$prefix" == "$name" ]] && { echo "$1"; return; }
  rest=${name#"$prefix"}
  suffix=${rest##*#}
  hashes=${rest%"$suffix"}
  printf '%s%s%0*d%s\n' "$dir" "$prefix" "${#hashes}" "$2" "$suffix"
}

farm_final_path() { farm_pattern_frame "$SHOT_PATTERN" "$1"; }  # frame -> merged frame

# Task $1's output: the frame itself when the grid is 1x1, else a tile in WORK/tiles.
farm_task_output() {
  local task=$1 frame name digits
  frame=$(farm_frame_of "$task")
  if (($(farm_tiles) == 1)); then
    farm_final_path "$frame"
    return
  fi
  name=$(basename "$(farm_final_path "$frame")")
  digits=$((${#SHOT_COLS} + ${#SHOT_ROWS}))
  printf '%s/tiles/%s.t%0*d.exr\n' "$SHOT_WORK" "${name%.[eE][xX][rR]}" "$digits" "$(farm_tile_of "$task")"
}

# The value of header attribute $2 in `iinfo -v` text $1, quotes removed.
farm_attr() {
  local line
  line=$(grep -m1 -E "^[[:space:]]+$2: " <<<"$1") || return 1
  line=${line#*"$2: "}
  line=${line#\"}
  echo "${line%\"}"
}

# Is $1 a finished render of region $2 (X0,Y0,X1,Y1) of frame $3 of this shot?
#
# Complete means: the file exists, OpenImageIO reads its header, and the header
# says it is that region of that frame of this shot: obscura:region,
# obscura:resolution, obscura:scene (absolute, as obscura records it), and
# obscura:frame when the header carries one. A partial file cannot sit under
# the final name: obscura writes to a temporary sibling and renames it into
# place (core/image/image_io.cpp, OutputSet::commit), and `merge` does the same. The
# other settings are guarded per work folder (submit.sh refuses a work folder
# whose shot had other settings), and `obscura merge` refuses tiles whose
# settings differ. FARM_VERIFY_PIXELS=1 also reads every pixel (iinfo --hash),
# which catches a file truncated after the rename (a node that lost power
# before its page cache reached a local disk; obscura does not fsync).
# iinfo -v FILES..., reading every pixel too (--hash) with FARM_VERIFY_PIXELS=1.
farm_iinfo() {
  if [[ "${FARM_VERIFY_PIXELS:-0}" == 1 ]]; then iinfo -v --hash "$@"; else iinfo -v "$@"; fi
}

farm_complete() {
  local file=$1 region=$2 frame=$3 hdr value
  [[ -f "$file" ]] || return 1
  if [[ -v "FARM_HEADERS[$file]" ]]; then
    hdr=${FARM_HEADERS[$file]}
  else
    hdr=$(farm_iinfo "$file" 2>&1) || return 1
  fi
  if [[ "${FARM_VERIFY_PIXELS:-0}" == 1 ]]; then
    grep -qE 'SHA-1: [0-9A-Fa-f]{40}' <<<"$hdr" || return 1  # iinfo exits 0 on a failed read
  fi
  [[ "$(farm_attr "$hdr" obscura:region)" == "$region" ]] || return 1
  [[ "$(farm_attr "$hdr" obscura:resolution)" == "${SHOT_W}x${SHOT_H}" ]] || return 1
  [[ "$(farm_attr "$hdr" obscura:scene)" == "$SHOT_SCENE" ]] || return 1
  if value=$(farm_attr "$hdr" obscura:frame); then
    awk -v a="$value" -v b="$frame" 'BEGIN { exit !(a + 0 == b + 0) }' || return 1
  fi
  return 0
}

# Reads the headers of the existing files among $@ with one iinfo (starting
# OpenImageIO costs ~0.2-0.8 s a process; a shot has thousands of files) into
# FARM_HEADERS, where farm_complete looks first. Call it again after a file changes.
declare -gA FARM_HEADERS=()
farm_read_headers() {
  local files=() f line rest k=0 j cur=""
  FARM_HEADERS=()
  for f; do [[ -f "$f" ]] && files+=("$f"); done
  ((${#files[@]})) || return 0
  # iinfo prints each file it reads as "NAME<spaces>: W x H, ..." then its
  # attributes indented, in argument order (unreadable files: an error line).
  while IFS= read -r line; do
    if [[ "$line" != [[:space:]]* ]]; then
      cur=""
      for ((j = k; j < ${#files[@]}; j++)); do
        rest=${line#"${files[j]}"}
        if [[ "$rest" != "$line" && "$rest" =~ ^\ *: ]]; then
          cur=${files[j]}
          k=$((j + 1))
          FARM_HEADERS[$cur]=""
          break
        fi
      done
      continue
    fi
    [[ -n "$cur" ]] && FARM_HEADERS[$cur]+="$line"$'\n'
  done < <(farm_iinfo "${files[@]}" 2>/dev/null)
  return 0
}

farm_full_region() { echo "0,0,$SHOT_W,$SHOT_H"; }

# Is task $1 done: its output complete, or (tiles) its frame already merged?
farm_task_done() {
  local task=$1 frame
  frame=$(farm_frame_of "$task")
  farm_complete "$(farm_final_path "$frame")" "$(farm_full_region)" "$frame" && return 0
  (($(farm_tiles) > 1)) && farm_complete "$(farm_task_output "$task")" "$(farm_region "$(farm_tile_of "$task")")" "$frame"
}

# A sorted list of integers as a Slurm array spec: 0 1 2 5 7 8 -> 0-2,5,7-8.
farm_array_spec() {
  local spec="" start="" prev="" i
  for i in "$@" ""; do
    if [[ -n "$start" && "$i" == $((prev + 1)) ]]; then
      prev=$i
      continue
    fi
    if [[ -n "$start" ]]; then
      spec+="${spec:+,}$start"
      [[ "$prev" != "$start" ]] && spec+="-$prev"
    fi
    start=$i
    prev=$i
  done
  echo "$spec"
}

farm_load_shot() {
  [[ -f "$1" ]] || farm_die "$1: no such shot file (written by scripts/farm/submit.sh)"
  # shellcheck disable=SC1090
  source "$1"
  command -v iinfo >/dev/null || farm_die "iinfo (OpenImageIO tools, Debian package openimageio-tools) is not on PATH"
}

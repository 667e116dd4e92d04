#!/usr/bin/env bash
# Submits a shot to Slurm: a job array of the (frame, tile) tasks still missing,
# and a merge job that runs once they all succeeded. Run it again after a
# failure: it submits only what is missing (docs/production.md "Rendering a shot on a cluster").
#
#   scripts/farm/submit.sh -o OUT.####.exr --frames A-B[:STEP] [--tiles COLSxROWS] [--res WxH]
#       [--scene SCENE] [--obscura BIN] [--work DIR] [--cpus N] [--max-running N]
#       [--partition P] [--time LIMIT] [--sbatch ARG]... [--no-submit] [-- RENDER OPTIONS...]
#
# Prints what it submits; its last line is `jobs: RENDER_JOB MERGE_JOB` ('-' for none).
set -euo pipefail

farm_dir=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
source "$farm_dir/lib.sh"

usage() {
  sed -n '6,8p' "${BASH_SOURCE[0]}" | sed 's/^# \{0,1\}//' >&2
  exit 2
}
need() { (($2 >= 2)) || farm_die "$1 needs a value"; }

pattern="" frames="" grid="1x1" res="960x540" scene="" obscura="" work="" cpus=1
max_running="" no_submit=0
sbatch_args=()
opts=()
while (($#)); do
  case "$1" in
    -o) need "$1" $#; pattern=$2; shift 2 ;;
    --frames) need "$1" $#; frames=$2; shift 2 ;;
    --tiles) need "$1" $#; grid=$2; shift 2 ;;
    --res) need "$1" $#; res=$2; shift 2 ;;
    --scene) need "$1" $#; scene=$2; shift 2 ;;
    --obscura) need "$1" $#; obscura=$2; shift 2 ;;
    --work) need "$1" $#; work=$2; shift 2 ;;
    --cpus) need "$1" $#; cpus=$2; shift 2 ;;
    --max-running) need "$1" $#; max_running=$2; shift 2 ;;
    --partition) need "$1" $#; sbatch_args+=("--partition=$2"); shift 2 ;;
    --time) need "$1" $#; sbatch_args+=("--time=$2"); shift 2 ;;
    --sbatch) need "$1" $#; sbatch_args+=("$2"); shift 2 ;;
    --no-submit) no_submit=1; shift ;;
    -h | --help) usage ;;
    --) shift; opts=("$@"); break ;;
    *) farm_die "unknown option '$1' (render options go after --)" ;;
  esac
done

# --- the shot ------------------------------------------------------------------
[[ -n "$pattern" ]] || farm_die "-o OUT.####.exr is required"
[[ -n "$frames" ]] || farm_die "--frames A-B[:STEP] is required"
[[ "$pattern" =~ \.[eE][xX][rR]$ ]] || farm_die "-o $pattern: the output must end in .exr"
[[ "$frames" =~ ^([0-9]+)(-([0-9]+))?(:([0-9]+))?$ ]] || farm_die "--frames $frames: expected A-B[:STEP] (non-negative integers)"
first=$((10#${BASH_REMATCH[1]}))
last=$((10#${BASH_REMATCH[3]:-${BASH_REMATCH[1]}}))
step=$((10#${BASH_REMATCH[5]:-1}))
((first <= last)) || farm_die "--frames $frames: the first frame is after the last"
((step >= 1)) || farm_die "--frames $frames: STEP must be at least 1"
[[ "$grid" =~ ^([1-9][0-9]*)x([1-9][0-9]*)$ ]] || farm_die "--tiles $grid: expected COLSxROWS, e.g. 2x2"
cols=${BASH_REMATCH[1]} rows=${BASH_REMATCH[2]}
[[ "$res" =~ ^([1-9][0-9]*)x([1-9][0-9]*)$ ]] || farm_die "--res $res: expected WxH"
width=${BASH_REMATCH[1]} height=${BASH_REMATCH[2]}
((cols <= width && rows <= height)) || farm_die "--tiles $grid: more tiles than pixels across or down a ${res} frame"
[[ "$cpus" =~ ^[1-9][0-9]*$ ]] || farm_die "--cpus $cpus: expected a positive integer"
[[ -z "$max_running" || "$max_running" =~ ^[1-9][0-9]*$ ]] || farm_die "--max-running $max_running: expected a positive integer"

name=$(basename "$pattern")
hashes=${name//[^#]/}
if ((${#hashes})); then
  [[ "$name" =~ ^[^#]*#+[^#]*$ ]] || farm_die "-o $pattern: the file name must hold one run of '#' (the frame number)"
elif ((first != last)); then
  farm_die "-o $pattern: a shot of several frames needs '#' in the file name (e.g. out.####.exr)"
fi
for o in "${opts[@]}"; do
  case "$o" in
    -o | --output* | --res* | --region* | --frame | --frame=* | --frames*)
      farm_die "render option '$o' is set by the farm scripts; use submit.sh's own options" ;;
  esac
done

scene=${scene:-$farm_dir/../../scenes/default.gltf}
[[ -f "$scene" ]] || farm_die "--scene $scene: no such file"
scene=$(realpath -s "$scene")
# obscura records the scene as std::filesystem::absolute(..).lexically_normal();
# realpath -s normalizes the same way without resolving symlinks.
if [[ -z "$obscura" ]]; then
  obscura=$(command -v obscura) || farm_die "obscura is not on PATH; pass --obscura BIN"
fi
[[ -x "$obscura" ]] || farm_die "--obscura $obscura: not an executable file"
obscura=$(realpath -s "$obscura")
out_dir=$(dirname "$pattern")
mkdir -p "$out_dir" || farm_die "-o $pattern: cannot create the folder $out_dir"
pattern=$(realpath -s "$pattern")
if [[ -z "$work" ]]; then
  stem=${name%.[eE][xX][rR]}
  stem=${stem//#/}
  stem=${stem%%[._-]}
  work="$(dirname "$pattern")/.farm/${stem:-shot}"
fi
mkdir -p "$work/tiles" "$work/logs" || farm_die "--work $work: cannot create it"
work=$(realpath -s "$work")

SHOT_FARM_DIR=$farm_dir SHOT_OBSCURA=$obscura SHOT_SCENE=$scene SHOT_W=$width SHOT_H=$height
SHOT_COLS=$cols SHOT_ROWS=$rows SHOT_FIRST=$first SHOT_LAST=$last SHOT_STEP=$step
SHOT_PATTERN=$pattern SHOT_WORK=$work SHOT_OPTS=("${opts[@]}")
command -v iinfo >/dev/null || farm_die "iinfo (OpenImageIO tools, Debian package openimageio-tools) is not on PATH"

# What the files are a function of; a work folder holds one such shot, so a
# complete tile is never a leftover of other settings. The frame range, the
# binary and the Slurm options may change between submissions. The scene's
# content counts (its bytes; not the buffers or textures it refers to).
identity="$(declare -p SHOT_SCENE SHOT_W SHOT_H SHOT_COLS SHOT_ROWS SHOT_PATTERN SHOT_OPTS)
scene sha256 $(sha256sum <"$SHOT_SCENE" | cut -d' ' -f1)"  # an edited scene file makes the tiles stale
if [[ -f "$work/shot.id" ]] && [[ "$(cat "$work/shot.id")" != "$identity" ]]; then
  farm_die "$work/shot.id: this work folder holds a shot with other settings (scene path or content, size, tiles, output or render options); use another --work, or delete $work to start over"
fi

# --- what is missing -------------------------------------------------------------
# One name per work folder (squeue -n finds a shot's jobs; no commas or spaces in it).
job_name="obscura-$(basename "$work" | tr -c 'A-Za-z0-9._\n-' _)-$(printf %s "$work" | cksum | cut -d' ' -f1)"
if ((!no_submit)); then
  command -v sbatch >/dev/null || farm_die "sbatch is not on PATH (Slurm client)"
  if [[ -n "$(squeue -h -u "$(id -un)" -n "$job_name" -o %i 2>/dev/null)" ]]; then
    farm_die "jobs of this shot are still queued or running (squeue -n '$job_name'); wait for them or scancel them first"
  fi
fi
tiles=$((cols * rows))
total=$((((last - first) / step + 1) * tiles))
all_files=()
for ((f = first, task = 0; f <= last; f += step)); do
  all_files+=("$(farm_final_path "$f")")
  for ((t = 0; t < tiles && tiles > 1; t++, task++)); do all_files+=("$(farm_task_output "$task")"); done
done
farm_read_headers "${all_files[@]}"
missing=()
frames_to_merge=0
for ((f = first, task = 0; f <= last; f += step)); do
  if farm_complete "$(farm_final_path "$f")" "$(farm_full_region)" "$f"; then
    task=$((task + tiles))  # the frame is done: its tiles are not needed any more
    continue
  fi
  ((tiles > 1)) && frames_to_merge=$((frames_to_merge + 1))
  for ((t = 0; t < tiles; t++, task++)); do
    if ((tiles == 1)) || ! farm_complete "$(farm_task_output "$task")" "$(farm_region "$t")" "$f"; then
      missing+=("$task")
    fi
  done
done
echo "farm: shot $work: frames $first-$last:$step, ${cols}x${rows} tiles of ${width}x${height}: $total tasks, ${#missing[@]} to render, $frames_to_merge frame(s) to merge"

if ((${#missing[@]})) && ((!no_submit)); then
  max_array=$(scontrol show config 2>/dev/null | awk '$1 == "MaxArraySize" { print $3 }')
  if [[ -n "$max_array" ]] && ((missing[-1] >= max_array)); then
    farm_die "task index ${missing[-1]} is beyond Slurm's MaxArraySize ($max_array): submit the shot in frame ranges (--frames) of at most $((max_array / tiles)) frames, each with its own --work"
  fi
fi

# --- submit ------------------------------------------------------------------------
shot_file=$work/shot.sh
spec=$(farm_array_spec "${missing[@]}")
render_cmd=(sbatch --parsable --job-name="$job_name" --array="$spec${max_running:+%$max_running}"
  --cpus-per-task="$cpus" --output="$work/logs/render-%A_%a.log" "${sbatch_args[@]}"
  "$farm_dir/render.sbatch" "$shot_file")
merge_cmd=(sbatch --parsable --job-name="$job_name" --output="$work/logs/merge-%j.log" "${sbatch_args[@]}")


{
  echo "# Written by scripts/farm/submit.sh on $(date -u +%FT%TZ); read by task.sh and merge.sh."
  declare -p SHOT_FARM_DIR SHOT_OBSCURA SHOT_SCENE SHOT_W SHOT_H SHOT_COLS SHOT_ROWS \
    SHOT_FIRST SHOT_LAST SHOT_STEP SHOT_PATTERN SHOT_WORK SHOT_OPTS | sed 's/^declare -/declare -g -/'
} >"$shot_file.tmp"
mv "$shot_file.tmp" "$shot_file"
echo "$identity" >"$work/shot.id"

if ((no_submit)); then
  # For another scheduler, or by hand: the shot file is written, nothing is submitted.
  echo "farm: wrote $shot_file; tasks to run: ${spec:-none}"
  ((${#missing[@]})) && echo "farm: Slurm would run: $(printf '%q ' "${render_cmd[@]}")"
  dep=()
  ((${#missing[@]})) && dep=(--dependency=afterok:JOB --kill-on-invalid-dep=yes)
  ((frames_to_merge)) && echo "farm: Slurm would run: $(printf '%q ' "${merge_cmd[@]}" "${dep[@]}" "$farm_dir/merge.sbatch" "$shot_file")"
  echo "jobs: - -"
  exit 0
fi

render_job=- merge_job=-
if ((${#missing[@]})); then
  render_job=$("${render_cmd[@]}")
  render_job=${render_job%%;*}
  done_count=$((total - ${#missing[@]}))
  echo "farm: render job $render_job: --array=$spec (${#missing[@]} of $total tasks$( ((done_count)) && echo "; the other $done_count are complete"))"
fi
if ((frames_to_merge)); then
  dep=()
  [[ "$render_job" != - ]] && dep=(--dependency="afterok:$render_job" --kill-on-invalid-dep=yes)
  merge_job=$("${merge_cmd[@]}" "${dep[@]}" "$farm_dir/merge.sbatch" "$shot_file")
  merge_job=${merge_job%%;*}
  echo "farm: merge job $merge_job${dep:+ (after every task of job $render_job succeeded)}: $frames_to_merge frame(s)"
fi
((${#missing[@]} + frames_to_merge)) || echo "farm: every frame is complete; nothing submitted"
echo "jobs: $render_job $merge_job"

#!/usr/bin/env bash
# Tasks of a shot, whatever runs them (Slurm array, Deadline, OpenCue, a loop):
#
#   scripts/farm/task.sh WORK/shot.sh TASK [LAST]
#
# renders task TASK (through LAST, in turn, for schedulers that hand out chunks
# of indices): frame FIRST + (TASK / tiles) * STEP, tile TASK % tiles (index
# scheme: scripts/farm/lib.sh, docs/production.md "Rendering a shot on a cluster"), to its
# tile in WORK/tiles (or straight to the frame for a 1x1 grid). A task whose
# output is already complete, or whose frame is already merged, is skipped, so
# a requeued or resubmitted task never renders twice. Threads: $FARM_THREADS,
# else Slurm's $SLURM_CPUS_PER_TASK, else obscura's default (all cores), unless
# the shot's options set --threads.
set -euo pipefail

if (($# != 2 && $# != 3)); then
  echo "usage: $0 WORK/shot.sh TASK [LAST]" >&2
  exit 2
fi
shot=$1
source "$(dirname "${BASH_SOURCE[0]}")/lib.sh"
farm_load_shot "$shot"

count=$(farm_task_count)
for index in "$2" "${3:-$2}"; do
  [[ "$index" =~ ^[0-9]+$ ]] || farm_die "task index '$index' is not a non-negative integer"
  ((10#$index < count)) || farm_die "$shot: task $index is out of range: the shot has $count tasks (0-$((count - 1)))"
done
((10#${3:-$2} >= 10#$2)) || farm_die "task range $2-$3 is empty"

run_task() {
  local task=$1 frame tile out region cmd threads start
  frame=$(farm_frame_of "$task")
  tile=$(farm_tile_of "$task")
  out=$(farm_task_output "$task")
  if (($(farm_tiles) > 1)); then
    region=$(farm_region "$tile")
  else
    region=$(farm_full_region)
  fi
  echo "farm: task $task = frame $frame, tile $tile of $(farm_tiles), region $region -> $out"

  if farm_task_done "$task"; then
    echo "farm: task $task: already complete, nothing to do"
    return 0
  fi

  cmd=("$SHOT_OBSCURA" render "$SHOT_SCENE" -o "$out" --res "${SHOT_W}x${SHOT_H}" --frame "$frame")
  (($(farm_tiles) > 1)) && cmd+=(--region "$region")
  threads=${FARM_THREADS:-${SLURM_CPUS_PER_TASK:-}}
  if [[ -n "$threads" ]] && ! printf '%s\n' "${SHOT_OPTS[@]}" | grep -qE '^--threads(=|$)'; then
    cmd+=(--threads "$threads")
  fi
  cmd+=("${SHOT_OPTS[@]}")
  mkdir -p "$(dirname "$out")"
  echo "farm: $(printf '%q ' "${cmd[@]}")"
  start=$SECONDS
  "${cmd[@]}"
  # The header must now say what the task asked for; if not (e.g. a wrapper that
  # drops --region), fail the task so the shot's merge does not run on it.
  farm_complete "$out" "$region" "$frame" ||
    farm_die "$out: written, but its header is not region $region of frame $frame of this shot"
  echo "farm: task $task done in $((SECONDS - start)) s"
}

for ((task = 10#$2; task <= 10#${3:-$2}; task++)); do run_task "$task"; done

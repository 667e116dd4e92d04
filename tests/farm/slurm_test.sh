#!/usr/bin/env bash
# The farm scripts on a real single-node Slurm (Debian's slurm-wlm and munge),
# brought up here in a temporary folder and shut down on exit, pass or fail:
#
#   A  submit a 2-frame x 4-tile shot of scenes/default.gltf (96x64, its crate
#      animated so the frames differ, when obscura has --frame) through a
#      wrapper that SIGKILLs the obscura of one task: that task fails, the other
#      seven write their tiles, and the merge job (afterok) is cancelled;
#   B  submit again: only the killed task runs (its array is that one index, one
#      log, the other tiles keep their inode and mtime), then the merge job;
#   C  each merged frame is bit-identical to a single-process render of the
#      frame (SHA-1 of the pixels, which any one-ulp change alters: checked on
#      a copy scaled by 1 + 2^-23), and the two frames differ;
#   D  a third submit finds everything complete and submits nothing.
#
#   tests/farm/slurm_test.sh        # root; OBSCURA=path/to/obscura (default build/obscura)
#
# Environment: OBSCURA, BUILD_DIR, FARM_TEST_PORT (slurmctld's port, slurmd's is
# the next; default 16817), FARM_TEST_KEEP=1 keeps the temporary folder.
set -euo pipefail

root=$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)
cd "$root"
obscura=$(realpath "${OBSCURA:-$root/${BUILD_DIR:-build}/obscura}")
[[ -x "$obscura" ]] || { echo "slurm_test: error: $obscura: no obscura binary (build it, or set OBSCURA)" >&2; exit 1; }
((EUID == 0)) || { echo "slurm_test: error: must run as root (it starts munged, slurmctld and slurmd)" >&2; exit 1; }
source scripts/install_missing.sh
install_missing slurm-wlm munge openimageio-tools

fail() {
  echo "slurm_test: FAIL: $*" >&2
  exit 1
}
now() { date +%s.%N; }
t_start=$(now)
t_phase=$t_start
phase_name=""
phase() {  # ends the running phase (printing its time) and starts the next
  local t
  t=$(now)
  [[ -n "$phase_name" ]] && printf 'slurm_test: %-44s %6.1f s\n' "$phase_name" "$(awk -v a="$t" -v b="$t_phase" 'BEGIN { print a - b }')"
  phase_name=$1
  t_phase=$t
  [[ -n "$1" ]] && echo "== $1"
  return 0
}

tmp=$(mktemp -d /tmp/obscura-slurm.XXXXXX)
chmod 755 "$tmp"
slurm=$tmp/slurm
munge=$tmp/munge
export SLURM_CONF=$slurm/slurm.conf

stop_pidfile() {  # pid file, name: SIGTERM, then SIGKILL after 10 s
  local pid i
  [[ -f "$1" ]] || return 0
  pid=$(cat "$1")
  [[ "$pid" =~ ^[0-9]+$ ]] || return 0
  kill "$pid" 2>/dev/null || return 0
  for ((i = 0; i < 100; i++)); do
    kill -0 "$pid" 2>/dev/null || { echo "slurm_test: stopped $2 ($pid)"; return 0; }
    sleep 0.1
  done
  kill -KILL "$pid" 2>/dev/null || true
  echo "slurm_test: killed $2 ($pid)"
}
cleanup() {
  local rc=$?
  set +e
  trap - EXIT
  phase "shut down"
  if [[ -f "$slurm/slurmctld.pid" ]]; then
    scancel --quiet --full -u root 2>/dev/null  # our jobs, if a failure left any
    for ((i = 0; i < 50; i++)); do
      [[ -z "$(squeue -h -o %i 2>/dev/null)" ]] && break
      sleep 0.2
    done
  fi
  local t0=$(now)
  stop_pidfile "$slurm/slurmd.pid" slurmd & stop_pidfile "$slurm/slurmctld.pid" slurmctld & wait
  echo "slurm_test: slurm daemons down after $(awk -v a="$(now)" -v b="$t0" 'BEGIN { printf "%.1f", a - b }') s"
  stop_pidfile "$munge/munged.pid" munged
  phase ""
  if ((rc != 0)); then
    for f in "$slurm"/*.log "$tmp"/shot/.farm/*/logs/*.log; do
      [[ -f "$f" ]] && { echo "--- $f (last 30 lines)"; tail -n 30 "$f"; }
    done
  fi
  if [[ "${FARM_TEST_KEEP:-0}" == 1 ]]; then echo "slurm_test: kept $tmp"; else rm -rf "$tmp"; fi
  printf 'slurm_test: %-44s %6.1f s\n' "total" "$(awk -v a="$(now)" -v b="$t_start" 'BEGIN { print a - b }')"
  ((rc == 0)) && echo "slurm_test: PASS" || echo "slurm_test: FAIL (exit $rc)"
  exit "$rc"
}
trap cleanup EXIT
trap "exit 130" INT  # exit runs the EXIT trap: Slurm and munge stop on Ctrl-C too
trap "exit 143" TERM

# --- Slurm up -----------------------------------------------------------------------
phase "start munged, slurmctld, slurmd"
port=${FARM_TEST_PORT:-16817}
for p in "$port" $((port + 1)); do
  if (exec 3<>"/dev/tcp/127.0.0.1/$p") 2>/dev/null; then
    fail "port $p is in use (another Slurm?); set FARM_TEST_PORT"
  fi
done
mkdir -p "$munge" "$slurm/state" "$slurm/spool"
chown munge:munge "$munge"
chmod 711 "$munge"  # munged: the socket's folder must be searchable by all
# A private munge key, socket and daemon: a munged the machine may already run is left alone.
runuser -u munge -- mungekey --create --keyfile="$munge/munge.key"
runuser -u munge -- munged --socket="$munge/munge.socket" --key-file="$munge/munge.key" \
  --pid-file="$munge/munged.pid" --log-file="$munge/munged.log" --seed-file="$munge/munged.seed"
host=$(hostname -s)
cat >"$SLURM_CONF" <<EOF
ClusterName=obscuratest
SlurmctldHost=$host(127.0.0.1)
SlurmctldPort=$port
SlurmdPort=$((port + 1))
SlurmUser=root
SlurmdUser=root
AuthType=auth/munge
CredType=cred/munge
AuthInfo=socket=$munge/munge.socket
StateSaveLocation=$slurm/state
SlurmdSpoolDir=$slurm/spool
SlurmctldPidFile=$slurm/slurmctld.pid
SlurmdPidFile=$slurm/slurmd.pid
SlurmctldLogFile=$slurm/slurmctld.log
SlurmdLogFile=$slurm/slurmd.log
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
SelectType=select/cons_tres
SelectTypeParameters=CR_Core
ReturnToService=2
MinJobAge=3600
MpiDefault=none
NodeName=$host NodeAddr=127.0.0.1 CPUs=$(nproc) State=UNKNOWN
PartitionName=test Nodes=$host Default=YES MaxTime=INFINITE State=UP
EOF
slurmctld -f "$SLURM_CONF"
slurmd -f "$SLURM_CONF"
for ((i = 0; ; i++)); do
  state=$(sinfo -h -N -o %t 2>/dev/null || true)
  [[ "$state" == idle ]] && break
  ((i < 150)) || fail "the node is not idle after 30 s (sinfo: '$state')"
  sleep 0.2
done
echo "slurm_test: $(sinfo -h -N -o '%N %t %c CPUs') ($(sinfo -V))"

# --- the shot -------------------------------------------------------------------------
# The default scene with its crate sliding 12 units a second along +X (a glTF
# LINEAR translation animation added here: perl and its core JSON::PP come with
# build-essential), so frames 1 and 2 differ. Obscura without --frame (before
# glTF animation) renders the static default scene through a shim that drops
# --frame instead, and both frames are the same still.
real=$obscura
scene=$tmp/default_animated.gltf
animated=1
if "$obscura" render --help 2>&1 | grep -qE -- '--frame([ ,=]|$)'; then
  perl -MJSON::PP -MMIME::Base64 -e '
    local $/; open my $f, "<", $ARGV[0] or die "$ARGV[0]: $!"; my $d = JSON::PP->new->decode(<$f>);
    my ($crate) = grep { $d->{nodes}[$_]{name} eq "crate" } 0 .. $#{$d->{nodes}};
    defined $crate or die "$ARGV[0]: no node named crate";
    my @t = @{$d->{nodes}[$crate]{translation}};
    my $bin = pack("f<*", 0, 1, @t, $t[0] + 12, $t[1], $t[2]);
    push @{$d->{buffers}}, {byteLength => length($bin), uri => "data:application/octet-stream;base64," . encode_base64($bin, "")};
    my $b = $#{$d->{buffers}};
    push @{$d->{bufferViews}}, {buffer => $b, byteOffset => 0, byteLength => 8}, {buffer => $b, byteOffset => 8, byteLength => 24};
    my $v = $#{$d->{bufferViews}};
    push @{$d->{accessors}}, {bufferView => $v - 1, componentType => 5126, count => 2, type => "SCALAR", min => [0], max => [1]},
      {bufferView => $v, componentType => 5126, count => 2, type => "VEC3"};
    my $a = $#{$d->{accessors}};
    $d->{animations} = [{name => "crate_slide", samplers => [{input => $a - 1, output => $a, interpolation => "LINEAR"}],
      channels => [{sampler => 0, target => {node => $crate, path => "translation"}}]}];
    print JSON::PP->new->canonical->encode($d);' scenes/default.gltf >"$scene"
  echo "slurm_test: scene: scenes/default.gltf + animation crate_slide ($("$obscura" info "$scene" 2>&1 | grep -m1 crate_slide | sed 's/^ *//'))"
else
  echo "slurm_test: note: $obscura has no --frame yet; the tasks and references go through a shim that drops it"
  animated=0
  scene=scenes/default.gltf
  real=$tmp/bin/obscura-noframe
  mkdir -p "$tmp/bin"
  cat >"$real" <<EOF
#!/usr/bin/env bash
args=()
while ((\$#)); do
  if [[ "\$1" == --frame ]]; then shift 2; else args+=("\$1"); shift; fi
done
exec $(printf %q "$obscura") "\${args[@]}"
EOF
  chmod +x "$real"
fi
kill_task=6  # frame index 1 (frame 2), tile 2 (bottom left): region 0,32,48,64
flaky=$tmp/bin/obscura-flaky
mkdir -p "$tmp/bin"
cat >"$flaky" <<EOF
#!/usr/bin/env bash
# Task $kill_task's render dies by SIGKILL, as if the node's OOM killer or an admin struck.
if [[ " \$* " == *" --frame 2 "* && " \$* " == *" --region 0,32,48,64 "* ]]; then
  echo "obscura-flaky: SIGKILL" >&2
  kill -KILL \$\$
fi
exec $(printf %q "$real") "\$@"
EOF
chmod +x "$flaky"

out=$tmp/shot
mkdir -p "$out"
shot_args=(-o "$out/default.####.exr" --frames 1-2 --tiles 2x2 --res 96x64 --scene "$scene" --cpus 1)
render_opts=(--spp 8 -p distance=2 --quiet)
work=$out/.farm/default
tiles=("$work"/tiles/default.000{1,2}.t0{0,1,2,3}.exr)  # tasks 0-7

submit() {  # obscura binary -> sets render_job, merge_job; prints submit.sh's output
  local log
  log=$(bash scripts/farm/submit.sh "${shot_args[@]}" --obscura "$1" -- "${render_opts[@]}") || fail "submit.sh failed"
  echo "$log" | sed 's/^/  | /'
  read -r _ render_job merge_job <<<"$(tail -n1 <<<"$log")"
  submit_log=$log
}
wait_jobs() {
  local i ids
  ids=$(IFS=,; echo "$*")
  for ((i = 0; ; i++)); do
    [[ -z "$(squeue -h -j "$ids" -o %i 2>/dev/null)" ]] && return 0
    ((i < 1500)) || fail "jobs $ids still queued after 300 s: $(squeue -h -j "$ids")"
    sleep 0.2
  done
}

# --- A: a task dies ---------------------------------------------------------------------
phase "A: submit 2 frames x 4 tiles, task $kill_task killed"
submit "$flaky"
[[ "$render_job" != - && "$merge_job" != - ]] || fail "the first submit did not submit a render and a merge job"
grep -q -- '--array=0-7 ' <<<"$submit_log" || fail "the first submit's array is not 0-7"
wait_jobs "$render_job" "$merge_job"
states=$(scontrol -o show job "$render_job" | grep -oE 'ArrayTaskId=[0-9]+ .*JobState=[A-Z_]+' |
  sed -E 's/ArrayTaskId=([0-9]+) .*JobState=([A-Z_]+)/\1=\2/' | sort -n | tr '\n' ' ')
echo "slurm_test: render job $render_job tasks: $states"
expected=""
for ((t = 0; t < 8; t++)); do
  if ((t == kill_task)); then expected+="$t=FAILED "; else expected+="$t=COMPLETED "; fi
done
[[ "$states" == "$expected" ]] || fail "task states '$states', expected '$expected'"
merge_state=$(scontrol -o show job "$merge_job" | grep -oE 'JobState=[A-Z_]+')
echo "slurm_test: merge job $merge_job: $merge_state"
[[ "$merge_state" == JobState=CANCELLED ]] || fail "the merge job should be cancelled (afterok failed), is $merge_state"
for ((t = 0; t < 8; t++)); do
  if ((t == kill_task)); then
    [[ ! -e "${tiles[t]}" ]] || fail "${tiles[t]} exists although its task was killed"
  else
    [[ -f "${tiles[t]}" ]] || fail "${tiles[t]} is missing"
  fi
done
ls "$out"/default.*.exr >/dev/null 2>&1 && fail "a frame was merged although a task failed"
grep -q SIGKILL "$work/logs/render-${render_job}_$kill_task.log" || fail "task $kill_task's log does not show the kill"

# --- B: the resubmit redoes only that task ----------------------------------------------
phase "B: resubmit: only task $kill_task, then merge"
others() { for ((t = 0; t < 8; t++)); do ((t == kill_task)) || stat -c '%n inode %i mtime %.9Y' "${tiles[t]}"; done; }
before=$(others)
submit "$real"
[[ "$render_job" != - && "$merge_job" != - ]] || fail "the resubmit did not submit a render and a merge job"
grep -q -- "--array=$kill_task " <<<"$submit_log" || fail "the resubmit's array is not just task $kill_task"
wait_jobs "$render_job" "$merge_job"
states=$(scontrol -o show job "$render_job" | grep -oE 'ArrayTaskId=[0-9]+ .*JobState=[A-Z_]+' |
  sed -E 's/ArrayTaskId=([0-9]+) .*JobState=([A-Z_]+)/\1=\2/' | sort -n | tr '\n' ' ')
echo "slurm_test: render job $render_job tasks: $states"
[[ "$states" == "$kill_task=COMPLETED " ]] || fail "the resubmitted array ran '$states', expected only task $kill_task"
logs=$(cd "$work/logs" && ls render-"$render_job"_*.log)
[[ "$logs" == "render-${render_job}_$kill_task.log" ]] || fail "logs of the resubmitted job: $logs"
merge_state=$(scontrol -o show job "$merge_job" | grep -oE 'JobState=[A-Z_]+')
echo "slurm_test: merge job $merge_job: $merge_state"
[[ "$merge_state" == JobState=COMPLETED ]] || fail "the merge job ended $merge_state"
after=$(others)
[[ "$before" == "$after" ]] || fail "tiles of tasks that were complete changed: $(diff <(echo "$before") <(echo "$after"))"
echo "slurm_test: the 7 complete tiles kept their inode and mtime; task $kill_task's tile is new"
[[ -f "${tiles[kill_task]}" ]] || fail "${tiles[kill_task]} was not rendered"

# --- C: bit-identical to single-process renders ---------------------------------------------
phase "C: frames == single-process renders, bit for bit"
shas=()
pixels_sha() { iinfo --hash "$1" | sed -nE 's/.*SHA-1: ([0-9A-Fa-f]{40})$/\1/p'; }
for f in 1 2; do
  frame=$out/default.000$f.exr
  ref=$tmp/ref.$f.exr
  "$real" render "$scene" -o "$ref" --res 96x64 --frame "$f" "${render_opts[@]}"
  dims=$(iinfo "$frame" | sed -n 's/.*: *\([0-9]* x *[0-9]*\),.*/\1/p')
  a=$(pixels_sha "$frame")
  b=$(pixels_sha "$ref")
  [[ -n "$a" && "$a" == "$b" ]] || fail "frame $f: merged pixels SHA-1 $a != single render $b"
  oiiotool "$frame" "$ref" --diff --fail 0 --failpercent 0 >/dev/null || fail "frame $f: oiiotool --diff finds a difference"
  echo "slurm_test: frame $f ($dims): merged == single render, pixel SHA-1 $a"
  shas[f]=$a
  if ((animated)); then
    got=$(iinfo -v "$frame" | sed -nE 's/^ *obscura:frame: "?([^"]*)"?$/\1/p')
    [[ "$got" == "$f" ]] || fail "frame $f: the merged header's obscura:frame is '$got'"
  fi
done
if ((animated)); then
  [[ "${shas[1]}" != "${shas[2]}" ]] || fail "frames 1 and 2 are the same image although the crate moves"
  echo "slurm_test: frames 1 and 2 differ (the crate moved), and each header says its frame"
fi
# The check is exact: a copy scaled by float(1 + 2^-23) (every nonzero value
# moves by one or two ulps) must fail it.
oiiotool "$tmp/ref.1.exr" --mulc 1.00000012 -d float -o "$tmp/ulp.exr"
[[ "$(pixels_sha "$tmp/ulp.exr")" != "$(pixels_sha "$tmp/ref.1.exr")" ]] || fail "the SHA-1 check misses a one-ulp change"
if oiiotool "$tmp/ulp.exr" "$tmp/ref.1.exr" --diff --fail 0 --failpercent 0 >/dev/null; then
  fail "oiiotool --diff --fail 0 misses a one-ulp change"
fi
echo "slurm_test: a one-ulp change alters the SHA-1 and fails oiiotool --diff --fail 0"

# --- D: nothing left to do -------------------------------------------------------------------
phase "D: submit again: nothing to do"
submit "$real"
[[ "$render_job" == - && "$merge_job" == - ]] || fail "a complete shot was submitted again ($render_job, $merge_job)"

#!/usr/bin/env bash
# Fuzzing (docs/testing.md "Fuzzing"): builds the libFuzzer targets with clang
# (CMake OBSCURA_FUZZ, ASan + UBSan) in their own build directory, writes the
# seed corpus, and runs each target for SECONDS (default 60). Fails on any
# finding: the crashing input is left in $BUILD_DIR/findings/<target>/.
#
#   scripts/fuzz.sh [SECONDS] [TARGET...]   # targets: gltf obj params json camera (default all)
#
# Environment: BUILD_DIR (default build-fuzz), JOBS (default nproc).
set -euo pipefail

seconds="${1:-60}"
shift || true
targets=("$@")
((${#targets[@]})) || targets=(gltf obj params json camera)
if ! [[ "$seconds" =~ ^[0-9]+$ ]] || ((seconds < 1)); then
  echo "usage: $0 [SECONDS] [gltf|obj|params|json|camera]..." >&2
  exit 2
fi
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$root"
build="${BUILD_DIR:-build-fuzz}"
jobs="${JOBS:-$(nproc)}"

# --- 1. Debian packages (only the missing ones): setup.sh's and clang's ---------
source scripts/install_missing.sh
install_missing build-essential cmake ninja-build pkg-config clang libclang-rt-14-dev libembree-dev \
  libopenimageio-dev libopenexr-dev libosd-dev libtbb-dev libtinygltf-dev nlohmann-json3-dev libstb-dev \
  libgtest-dev libcli11-dev libtinyobjloader-dev ccache

# --- 2. Build -------------------------------------------------------------------
compiler_cache_args "$root" >/dev/null  # exports the cache's environment
read -r -a cache <<< "$(compiler_cache_args "$root")"
cmake -S . -B "$build" -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo "${cache[@]}" -DCMAKE_CXX_COMPILER=clang++ \
  -DCMAKE_C_COMPILER=clang -DOBSCURA_FUZZ=ON -DOBSCURA_BUILD_TESTS=OFF -DOBSCURA_BUILD_BENCH=OFF >/dev/null
cmake --build "$build" -j "$jobs" --target obscura_fuzz_corpus $(printf 'obscura_fuzz_%s ' "${targets[@]}")

# --- 3. Seed corpus ---------------------------------------------------------------
# seeds/ is rewritten each run; corpus/<target>/ keeps what fuzzing found
# interesting across runs (libFuzzer adds to the first corpus directory).
rm -rf "$build/seeds"
"$build/fuzz/obscura_fuzz_corpus" "$build/seeds"

# --- 4. Fuzz ------------------------------------------------------------------------
# Each input must finish within 20 s and 2 GiB; leaks are findings too.
# intercept_tls_get_addr=0: LeakSanitizer's dynamic-TLS bug (docs/testing.md, the sanitizer pass).
export ASAN_OPTIONS="abort_on_error=1:intercept_tls_get_addr=0:${ASAN_OPTIONS:-}"
export UBSAN_OPTIONS="print_stacktrace=1:halt_on_error=1:${UBSAN_OPTIONS:-}"
status=0
for t in "${targets[@]}"; do
  corpus="$build/corpus/$t"
  findings="$build/findings/$t"
  mkdir -p "$corpus" "$findings"
  echo "== fuzzing $t for ${seconds}s"
  if ! "$build/fuzz/obscura_fuzz_$t" "$corpus" "$build/seeds/$t" -max_total_time="$seconds" -timeout=20 \
      -rss_limit_mb=2048 -max_len=65536 -print_final_stats=1 -artifact_prefix="$findings/" \
      > "$build/fuzz-$t.log" 2>&1; then
    tail -n 60 "$build/fuzz-$t.log" >&2
    echo "== $t: FINDING, input in $findings/ (log: $build/fuzz-$t.log)" >&2
    status=1
  else
    grep -E "stat::number_of_executed_units|cov:" "$build/fuzz-$t.log" | tail -n 2
    echo "== $t: no finding in ${seconds}s"
  fi
done
exit $status

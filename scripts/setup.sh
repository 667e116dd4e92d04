#!/usr/bin/env bash
# Obscura set-up on Debian 12: installs what is missing, builds, then either
# renders the bundled scene (`demo`) or runs the whole test suite (`test`).
#
#   scripts/setup.sh demo   # install + Release build + render scenes/default.gltf to out/
#   scripts/setup.sh test   # install + Release build + tests, then the tests under ASan/UBSan
#
# Environment: BUILD_DIR (default build), JOBS (default nproc),
# OBSCURA_SKIP_SANITIZE=1 to skip the ASan/UBSan pass of `test`.
set -euo pipefail

mode="${1:-}"
if [[ "$mode" != demo && "$mode" != test ]]; then
  echo "usage: $0 demo|test" >&2
  exit 2
fi
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$root"
build="${BUILD_DIR:-build}"
jobs="${JOBS:-$(nproc)}"

# --- 1. Debian packages (only the missing ones) -------------------------------
source scripts/install_missing.sh
install_missing build-essential cmake ninja-build pkg-config libembree-dev libopenimageio-dev \
  openimageio-tools libopenexr-dev libosd-dev libtbb-dev libtinygltf-dev nlohmann-json3-dev \
  libstb-dev libgtest-dev libcli11-dev libtinyobjloader-dev pybind11-dev python3-dev python3-numpy \
  python3-matplotlib python3-pytest ccache
# The outside clients the tests drive, for `test` only: the compare report
# page loaded in a real browser, headless (tests/test_report_page.cpp,
# Debian's chromium), and the EXR's passes read by Blender's compositor
# (tests/test_blender.cpp, Debian's blender 3.4). CI requires both.
if [[ "$mode" == test ]]; then install_missing chromium blender; fi

# --- 2. Build ------------------------------------------------------------------
# The Python module (docs/python.md "Python") is built for Debian's interpreter,
# whose NumPy, Matplotlib and pytest the packages above installed (a python3
# earlier in PATH, such as pyenv's, would lack them).
python_exe=/usr/bin/python3
python=(-DOBSCURA_PYTHON=ON "-DPython_EXECUTABLE=$python_exe")
compiler_cache_args "$root" >/dev/null  # exports the cache's environment here, not in a subshell
read -r -a cache <<< "$(compiler_cache_args "$root")"
configure() {  # dir, extra cmake args...
  local dir="$1"; shift
  cmake -S . -B "$dir" -G Ninja -DCMAKE_BUILD_TYPE=Release "${cache[@]}" "$@" >/dev/null
}
stage() {  # name: a timed stage of `test` (the split CI's closing lines show)
  local now; now=$(date +%s)
  if [[ -n "${stage_name:-}" ]]; then timings+=("$(printf '%-34s %5d s' "$stage_name" $((now - stage_start)))"); fi
  stage_name="$1" stage_start=$now
}
timings=()

if [[ "$mode" == demo ]]; then
  configure "$build" -DOBSCURA_BUILD_TESTS=OFF -DOBSCURA_BUILD_BENCH=OFF "${python[@]}"
  cmake --build "$build" -j "$jobs" --target obscura obscura_python
  mkdir -p out
  "$build/obscura" render scenes/default.gltf -o out/default_ao.exr --preview out/default_ao.png \
    --res 1280x720 --spp 64 -p distance=2
  echo "== wrote out/default_ao.exr and out/default_ao.png"
  echo "== Python: PYTHONPATH=$build/python $python_exe -c 'import obscura' (or cmake --install $build)"
  exit 0
fi

stage "build (Release)"
configure "$build" -DOBSCURA_BUILD_TESTS=ON -DOBSCURA_BUILD_BENCH=ON "${python[@]}"
cmake --build "$build" -j "$jobs"
echo "== tests (Release)"
stage "tests (Release)"
ctest --test-dir "$build" --output-on-failure -j "$jobs"

if [[ "${OBSCURA_SKIP_SANITIZE:-0}" != 1 ]]; then
  echo "== tests under AddressSanitizer + UndefinedBehaviorSanitizer"
  # Without the Python module: python3 is not ASan-instrumented (CMakeLists.txt).
  stage "build (ASan + UBSan)"
  configure "$build-asan" -DOBSCURA_SANITIZE=ON -DOBSCURA_BUILD_BENCH=OFF -DCMAKE_BUILD_TYPE=RelWithDebInfo -DOBSCURA_PYTHON=OFF
  cmake --build "$build-asan" -j "$jobs"
  stage "tests (ASan + UBSan)"
  # intercept_tls_get_addr=0: GCC 12's LeakSanitizer misreads glibc 2.36's
  # dynamic-TLS vector once enough dlopen'ed libraries have TLS (OpenImageIO's
  # module and its dependencies): its tracer reads a bogus block ("DTLS 19 at
  # 0x326a-0x8000436c") and dies with SIGSEGV at exit, failing a clean run.
  # Static TLS, stacks and the heap are still scanned (docs/testing.md).
  ASAN_OPTIONS=abort_on_error=1:intercept_tls_get_addr=0 UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1 \
    ctest --test-dir "$build-asan" --output-on-failure -j "$jobs"
fi
stage ""
echo "== time by stage"
printf '%s\n' "${timings[@]}"
if command -v ccache >/dev/null && [[ "${OBSCURA_NO_CCACHE:-0}" != 1 ]]; then ccache --show-stats 2>/dev/null | grep -E "Hits|Misses" | head -4 || true; fi

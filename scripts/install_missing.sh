# Sourced by scripts/setup.sh and scripts/fuzz.sh: install_missing PACKAGE...
# installs the Debian packages that are not installed yet (apt-get, through
# sudo unless root), and nothing else.
install_missing() {
  local missing=() p sudo=""
  for p in "$@"; do
    if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed"; then
      missing+=("$p")
    fi
  done
  ((${#missing[@]})) || return 0
  echo "== installing: ${missing[*]}"
  if [[ $(id -u) -ne 0 ]]; then sudo="sudo"; fi
  $sudo apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq --no-install-recommends "${missing[@]}"
}

# compiler_cache_args: the CMake arguments that put ccache (Debian's, when
# installed; install_missing ccache brings it) in front of the compiler, and
# the environment that makes its entries independent of where the clone
# is: paths under the clone are hashed relative to the build directory
# (CCACHE_BASEDIR), and the working directory is left out of the hash
# (CCACHE_NOHASHDIR: only the debug info's compilation directory, which no
# test reads, would name the clone). A fresh clone in another folder - as
# CI's is - then compiles what an earlier build on this machine compiled
# from the same sources out of the cache (docs/testing.md "Build times").
# OBSCURA_NO_CCACHE=1 leaves the compiler alone.
compiler_cache_args() {
  if [[ "${OBSCURA_NO_CCACHE:-0}" == 1 ]] || ! command -v ccache >/dev/null; then
    return 0
  fi
  export CCACHE_BASEDIR="$1" CCACHE_NOHASHDIR=1
  export CCACHE_MAXSIZE="${CCACHE_MAXSIZE:-5G}"
  echo "-DCMAKE_CXX_COMPILER_LAUNCHER=ccache -DCMAKE_C_COMPILER_LAUNCHER=ccache"
}

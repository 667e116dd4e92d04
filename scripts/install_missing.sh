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

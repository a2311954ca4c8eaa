#!/usr/bin/env bash
# Installs the Debian 12 packages rasterslam needs to build, test and run.
# Idempotent: when every package is already installed it only checks and exits (about 1 s).
# Uses sudo when not run as root.  Set RASTERSLAM_SKIP_DEPS=1 to skip entirely.
set -euo pipefail

PKGS=(
  build-essential cmake ninja-build pkg-config git
  libeigen3-dev
  libopencv-dev
  libpcl-dev
  libmrpt-dev mrpt-apps
  libgtest-dev libgmock-dev
  zlib1g-dev
  libjemalloc-dev
  libceres-dev
  libcli11-dev nlohmann-json3-dev
  libyaml-cpp-dev
  clang-format-14 jq time
)

if [ "${RASTERSLAM_SKIP_DEPS:-0}" = "1" ]; then
  echo "install-deps: skipped (RASTERSLAM_SKIP_DEPS=1)"
  exit 0
fi

missing=()
for p in "${PKGS[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed"; then
    missing+=("$p")
  fi
done

if [ ${#missing[@]} -eq 0 ]; then
  echo "install-deps: all ${#PKGS[@]} packages present"
  exit 0
fi

SUDO=""
if [ "$(id -u)" -ne 0 ]; then
  if command -v sudo >/dev/null 2>&1; then SUDO="sudo"; else
    echo "install-deps: need root or sudo to install: ${missing[*]}" >&2; exit 1
  fi
fi

echo "install-deps: installing ${missing[*]}"
export DEBIAN_FRONTEND=noninteractive
$SUDO apt-get update -qq
$SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
echo "install-deps: done"

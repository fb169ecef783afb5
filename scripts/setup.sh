#!/usr/bin/env bash
# Installs what a fresh Debian machine lacks to build, test and run facesynth:
# Xvfb + Mesa's software Vulkan (lavapipe) for the window and screenshot tests,
# numpy for ../shared/bench/synth_gavab.py, and the Rust components for the checks.
# Idempotent: installs only what is missing.
set -euo pipefail
need_apt=()
command -v Xvfb >/dev/null 2>&1 || need_apt+=(xvfb xauth)
ls /usr/share/vulkan/icd.d/lvp_icd*.json >/dev/null 2>&1 || need_apt+=(mesa-vulkan-drivers)
ldconfig -p | grep -q 'libvulkan.so.1' || need_apt+=(libvulkan1)
if [ ${#need_apt[@]} -gt 0 ]; then
  echo "setup: apt-get install ${need_apt[*]}"
  export DEBIAN_FRONTEND=noninteractive
  apt-get update -qq
  apt-get install -y -qq --no-install-recommends "${need_apt[@]}" >/dev/null
fi
if ! python3 -c 'import numpy' >/dev/null 2>&1; then
  echo "setup: pip install numpy"
  python3 -m pip install -q numpy
fi
rustup component list --installed 2>/dev/null | grep -q '^clippy' || rustup component add clippy
rustup component list --installed 2>/dev/null | grep -q '^rustfmt' || rustup component add rustfmt
echo "setup: ok"

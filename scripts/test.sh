#!/usr/bin/env bash
# The project's test command (README, CI): set-up, format check, lints, all tests.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
export XDG_RUNTIME_DIR="${XDG_RUNTIME_DIR:-/tmp/facesynth-xdg}"
mkdir -p "$XDG_RUNTIME_DIR" && chmod 700 "$XDG_RUNTIME_DIR"
# The editor (`gui` feature: eframe + wgpu) is not yet part of the checked build: it has not
# been compiled and verified under Xvfb yet (TODO(#2)). Until then the checks run on the
# library and the headless CLI only.
features=(--no-default-features)
cargo fmt --check
cargo clippy "${features[@]}" --all-targets -- -D warnings
cargo test "${features[@]}" --all-targets

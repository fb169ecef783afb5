#!/usr/bin/env bash
# The project's test command (README, CI): set-up, format check, lints, all tests.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
export XDG_RUNTIME_DIR="${XDG_RUNTIME_DIR:-/tmp/facesynth-xdg}"
mkdir -p "$XDG_RUNTIME_DIR" && chmod 700 "$XDG_RUNTIME_DIR"
# One profile (dev, optimised: see Cargo.toml) and the default features (editor included), so
# clippy and the tests share one dependency build. The window tests run under Xvfb + lavapipe.
cargo fmt --check
cargo clippy --all-targets -- -D warnings
cargo test --all-targets

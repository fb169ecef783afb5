#!/usr/bin/env bash
# Regenerates the editor screenshots reviewers look at into screenshots/ (ignored by git):
# every scripted panel state of `facesynth view`, under Xvfb + lavapipe when no display is set.
set -euo pipefail
cd "$(dirname "$0")/.."
out=screenshots
mkdir -p "$out"
cargo build --quiet
bin=target/debug/facesynth
scan=../shared/data/gavabdb/cara1_frontal1.wrl
export XDG_RUNTIME_DIR="${XDG_RUNTIME_DIR:-/tmp/facesynth-xdg}"
mkdir -p "$XDG_RUNTIME_DIR" && chmod 700 "$XDG_RUNTIME_DIR"
run() {
  local name=$1; shift
  if [ -n "${DISPLAY:-}" ]; then "$bin" view "$@" --screenshot "$out/$name.png"
  else xvfb-run -a -s "-screen 0 1400x900x24" "$bin" view "$@" --screenshot "$out/$name.png"; fi
  echo "screenshots: $out/$name.png"
}
run generic
run cara1_plain "$scan"
run cara1_denoise "$scan" --denoise --show denoise
run cara1_shape_index "$scan" --denoise --detect
run cara1_registration "$scan" --denoise --register
run cara1_happiness "$scan" --denoise --register --expression happiness --show displacement
run cara1_smile_muscles "$scan" --denoise --register --expression broad_smile --muscles --yaw 20
# The smile learned from cara1_sonrisa, coloured by its distance to that scan (fit residual).
run cara1_fit_sonrisa "$scan" --denoise --register --fit "$(dirname "$scan")/cara1_sonrisa.wrl"
run generic_happiness --expression happiness --muscles --show displacement
run generic_cutaway --expression broad_smile --layers cutaway --yaw 40 --pitch 10
for e in sadness surprise anger disgust fear scorn pain; do
  run "generic_$e" --expression "$e" --show displacement
done
# One editor session on cara1 (denoise and compare, fix a landmark, register, heat map, softer
# skin, a mirrored smile, store it as a preset, undo, redo): screenshots/session/*.png.
mkdir -p "$out/session"
if [ -n "${DISPLAY:-}" ]; then "$bin" view --session scripts/session_cara1.ron
else xvfb-run -a -s "-screen 0 1400x900x24" "$bin" view --session scripts/session_cara1.ron; fi
echo "screenshots: $out/session/"
# The review queue on four real scans (a profile among them): screenshots/review/*.png; the
# corrections and the detection cache go to screenshots/review/corrections (the scans are links).
rev=$(mktemp -d)
for f in cara1_frontal1 cara1_derecha cara1_sonrisa cara1_gesto; do
  ln -s "$(pwd)/../shared/data/gavabdb/$f.wrl" "$rev/$f.wrl"
done
mkdir -p "$out/review/corrections"
cat > "$rev/session.ron" <<RON
[
    Screenshot("$out/review/1_worst_first.png"),
    NudgeLandmark(point: "outer_eye_left", offset_mm: (4.0, 0.0, 0.0)),
    ReviewNext,
    Screenshot("$out/review/2_next_after_a_correction.png"),
]
RON
if [ -n "${DISPLAY:-}" ]; then "$bin" review "$rev" --landmarks-dir "$out/review/corrections" --session "$rev/session.ron"
else xvfb-run -a -s "-screen 0 1400x900x24" "$bin" review "$rev" --landmarks-dir "$out/review/corrections" --session "$rev/session.ron"; fi
rm -rf "$rev"
echo "screenshots: $out/review/"

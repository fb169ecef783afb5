#!/usr/bin/env bash
# Feature points on every real scan in ../shared/data (GavabDB VRML and point clouds, POL-DB),
# and their agreement with the independent detector in ../shared/tools (a measurement, not a
# product dependency; needs `pip install numpy scipy pillow dlib-bin face_recognition_models`).
#
#   scripts/real_landmarks.sh OUT [FACESYNTH]
# writes OUT/facesynth/<stem>.json|png, OUT/oracle/<stem>.json|png and prints the agreement.
set -eu
OUT=$1; BIN=${2:-target/release/facesynth}
S=../shared/data
mkdir -p "$OUT/facesynth" "$OUT/oracle"
for f in "$S"/gavabdb/*.wrl "$S"/gavabdb/pointclouds/*.txt "$S"/poldb/*.wrl; do
  b=$(basename "$f"); b=${b%.*}
  # the point cloud of cara1_frontal1 shares its stem with the VRML scan of the same capture
  [ "$b" = cara1_frontal1 ] && [ "${f##*.}" = txt ] && b=cara1_frontal1_pc
  "$BIN" landmarks "$f" --json "$OUT/facesynth/$b.json" --png "$OUT/facesynth/$b.png" >/dev/null \
    || echo "failed: $b"
  if [ ! -e "$OUT/oracle/$b.json" ]; then
    python3 ../shared/tools/landmark_oracle.py "$f" --out "$OUT/oracle/tmp" >/dev/null
    s=$(basename "$f"); s=${s%.*}
    for e in json png noface.png; do
      if [ -e "$OUT/oracle/tmp/$s.$e" ]; then mv "$OUT/oracle/tmp/$s.$e" "$OUT/oracle/$b.$e"; fi
    done
  fi
done
python3 ../shared/tools/landmark_agree.py "$OUT/facesynth" "$OUT/oracle"
grep -l '"suspect": true' "$OUT"/facesynth/*.json | sed 's/^/suspect: /' || true

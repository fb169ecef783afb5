#!/usr/bin/env bash
# Builds fuzz/corpus/<target>/ from the real scans in ../shared/data and small generated
# files. Run from anywhere; the corpus is git-ignored (the real scans are third-party data).
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
repo="$(dirname "$here")"
shared="${SHARED:-$repo/../shared}"
gavab="$shared/data/gavabdb"
c="$here/corpus"
rm -rf "$c"
mkdir -p "$c"/{vrml,obj,ply,xyz,presets_ron,landmarks_json,sidecar_json,mesh_pipeline}

# Real scans. libFuzzer cuts inputs to -max_len, so big scans serve as prefixes.
cp "$gavab"/*.wrl "$c/vrml/" 2>/dev/null || true
for f in "$gavab"/pointclouds/*; do
  cp "$f" "$c/xyz/$(basename "$f")"
done

# Small hand-made files, one per construct the readers handle.
printf '#VRML V1.0 ascii\nSeparator { Coordinate3 { point [0 0 0, 1 0 0, 0 1 0, 1 1 0] }\n IndexedFaceSet { coordIndex [0, 1, 2, -1, 1, 3, 2, -1] } }\n' > "$c/vrml/v1_quad.wrl"
printf '#VRML V2.0 utf8\nDEF S Shape { geometry IndexedFaceSet { coord Coordinate { point [0 0 0, 1 0 0, 0 1 0] }\n coordIndex [0 1 2 -1] ccw FALSE } }\nTransform { translation 1 2 3 scale 2 2 2 children [ USE S ] }\n' > "$c/vrml/v2_def_use.wrl"
printf 'v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nvt 0 0\nvn 0 0 1\nf 1/1/1 2/1/1 3/1/1\nf -3 -2 -1\ng x\nf 2 4 3\n' > "$c/obj/quad.obj"
printf 'ply\nformat ascii 1.0\ncomment c\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\nproperty float quality\nelement face 2\nproperty list uchar int vertex_indices\nend_header\n0 0 0 1\n1 0 0 1\n0 1 0 1\n1 1 0 1\n3 0 1 2\n3 1 3 2\n' > "$c/ply/quad_ascii.ply"
printf '0 0 0\n1 0 0\n2 0 0\n0 1 0\n1 1 0.5\n2 1 0\n0 2 0\n1 2 0\n2 2 0\n' > "$c/xyz/grid.xyz"
printf '{"nose_tip":[0,0,1]}' > "$c/landmarks_json/partial.json"

# Files the tool itself writes: binary PLY, OBJ, landmarks, presets (built from a real scan).
bin="$repo/target/release/facesynth"
[ -x "$bin" ] || bin="$repo/target/debug/facesynth"
if [ -x "$bin" ] && [ -f "$gavab/cara1_frontal1.wrl" ]; then
  tmp="$(mktemp -d)"
  trap 'rm -rf "$tmp"' EXIT
  "$bin" convert "$gavab/cara1_frontal1.wrl" "$tmp/scan.ply" >/dev/null 2>&1 &&
    cp "$tmp/scan.ply" "$c/ply/real_binary.ply" || true
  "$bin" convert "$gavab/cara1_frontal1.wrl" "$tmp/scan.obj" >/dev/null 2>&1 &&
    cp "$tmp/scan.obj" "$c/obj/real.obj" || true
  "$bin" generic --out "$tmp/g.obj" --landmarks "$tmp/lm.json" >/dev/null 2>&1 &&
    cp "$tmp/lm.json" "$c/landmarks_json/generic.json" || true
fi
# A small binary PLY, both byte orders.
python3 - "$c/ply" <<'PY'
import struct, sys
out = sys.argv[1]
verts = [(0, 0, 0), (1, 0, 0), (0, 1, 0), (1, 1, 0)]
faces = [(0, 1, 2), (1, 3, 2)]
for order, fmt in (("<", "binary_little_endian"), (">", "binary_big_endian")):
    head = (f"ply\nformat {fmt} 1.0\nelement vertex 4\nproperty double x\nproperty double y\n"
            f"property double z\nproperty uchar red\nelement face 2\n"
            f"property list uchar int vertex_indices\nend_header\n").encode()
    body = b"".join(struct.pack(order + "dddB", *v, 7) for v in verts)
    body += b"".join(struct.pack(order + "B3i", 3, *f) for f in faces)
    open(f"{out}/small_{fmt}.ply", "wb").write(head + body)
PY

# Presets and muscles: the built-in assets; the first byte picks the parser (even = presets).
for f in "$repo"/assets/expressions*.ron; do { printf '\x00'; cat "$f"; } > "$c/presets_ron/$(basename "$f")"; done
for f in "$repo"/assets/muscles*.ron; do { printf '\x01'; cat "$f"; } > "$c/presets_ron/$(basename "$f")"; done

# Ground-truth sidecars from the benchmark generator (2 subjects, tiny).
tmp2="$(mktemp -d)"
if python3 "$shared/bench/synth_gavab.py" --out "$tmp2" --subjects 1 --seed 3 >/dev/null 2>&1; then
  n=0
  for f in "$tmp2"/*.json; do
    cp "$f" "$c/sidecar_json/"
    n=$((n + 1))
    [ $n -ge 5 ] && break
  done
fi
rm -rf "$tmp2"

# mesh_pipeline: small synthetic faces (3 mm grid, ~3.3k vertices) as OBJ, so the fuzzer
# starts from meshes the landmark detector and the registration get through, plus the OBJ
# seeds above. Run it with -max_len=262144 (the faces are ~190 KB).
tmp3="$(mktemp -d)"
if [ -x "$bin" ] && python3 "$shared/bench/synth_gavab.py" --out "$tmp3" --subjects 1 --seed 2 \
  --grid-mm 3 --jobs 1 >/dev/null 2>&1; then
  for f in "$tmp3"/*.wrl; do
    "$bin" convert "$f" "$c/mesh_pipeline/$(basename "$f" .wrl).obj" >/dev/null 2>&1 || true
  done
fi
rm -rf "$tmp3"
cp "$c/obj/quad.obj" "$c/mesh_pipeline/"
for d in "$c"/*; do echo "$(basename "$d"): $(ls "$d" | wc -l) files"; done

#!/usr/bin/env python3
"""Made-harder real scans: every real scan in ../shared/data with clutter added, detected again.

For each scan: `facesynth convert` writes it as OBJ (the baseline), `facesynth landmarks` finds
its points, then two copies get a clutter surface as extra faces, as
`clutter_below_the_chin_or_over_the_forehead_does_not_move_the_points` in
tests/algorithms/landmarks.rs builds them on cara1_frontal1 only:
  torso: 360 mm wide, from 40 mm below the chin down 200 mm, its front 15 mm in front of the
         nose tip, rounded to the sides;
  hair:  a bumpy dome 200 mm wide from 20 mm above the forehead point up 80 mm, 10 mm in front
         of the forehead.
Both in the scanner frame (x right, y up, z towards the scanner), placed from the baseline's
points. Prints, per scan and clutter, how far the ten anatomical points moved (max, mm) and
whether the detection is suspect; the summary counts copies whose points all stay within 2 mm.

    python3 scripts/clutter_real.py OUT [FACESYNTH]

FS_EXTRA (environment) adds arguments to every `facesynth landmarks` call, e.g.
FS_EXTRA=--no-denoise.
"""
import glob
import json
import math
import os
import subprocess
import sys

EXTRA = os.environ.get("FS_EXTRA", "").split()
ANATOMICAL = [
    "nose_tip", "inner_eye_left", "inner_eye_right", "outer_eye_left", "outer_eye_right",
    "nose_corner_left", "nose_corner_right", "mouth_corner_left", "mouth_corner_right", "chin",
]


def patch(xs, ys, step, z):
    """A grid of quads over [xs] × [ys] (mm) at height z(x, y): (vertices, quads 0-based)."""
    nx = int((xs[1] - xs[0]) / step) + 1
    ny = int((ys[1] - ys[0]) / step) + 1
    v = [(xs[0] + i * step, ys[0] + j * step) for j in range(ny) for i in range(nx)]
    v = [(x, y, z(x, y)) for x, y in v]
    q = [(j * nx + i, j * nx + i + 1, (j + 1) * nx + i + 1, (j + 1) * nx + i)
         for j in range(ny - 1) for i in range(nx - 1)]
    return v, q


def with_patch(obj_in, obj_out, verts, quads):
    text = open(obj_in).read()
    n = sum(1 for line in text.splitlines() if line.startswith("v "))
    with open(obj_out + ".tmp", "w") as f:
        f.write(text)
        for x, y, z in verts:
            f.write(f"v {x:.3f} {y:.3f} {z:.3f}\n")
        for a, b, c, d in quads:
            f.write(f"f {a + n + 1} {b + n + 1} {c + n + 1} {d + n + 1}\n")
    os.replace(obj_out + ".tmp", obj_out)


def detect(binary, obj, out_json):
    r = subprocess.run([binary, "landmarks", obj, "--json", out_json] + EXTRA, capture_output=True,
                       text=True)
    if r.returncode != 0:
        return None, r.stderr.strip().splitlines()[-1] if r.stderr.strip() else "failed"
    return json.load(open(out_json)), None


def baseline(binary, scan, out_obj, out_json):
    """`scan` written as OBJ (`facesynth convert`, the copies' starting point) and its points
    detected: (report, error) as `detect`."""
    subprocess.run([binary, "convert", scan, out_obj], check=True, capture_output=True)
    return detect(binary, out_obj, out_json)


def real_scans(data="../shared/data"):
    """(stem, path) of every real scan in `data`, sorted by path, as `scripts/real_landmarks.sh`
    names them (the point cloud of cara1_frontal1 shares its stem with the VRML scan of the same
    capture, so it is cara1_frontal1_pc)."""
    scans = sorted(glob.glob(f"{data}/gavabdb/*.wrl")
                   + glob.glob(f"{data}/gavabdb/pointclouds/*.txt")
                   + glob.glob(f"{data}/poldb/*.wrl"))
    for scan in scans:
        stem = os.path.splitext(os.path.basename(scan))[0]
        if scan.endswith(".txt") and stem == "cara1_frontal1":
            stem += "_pc"
        yield stem, scan


def main():
    out = sys.argv[1]
    binary = sys.argv[2] if len(sys.argv) > 2 else "target/release/facesynth"
    os.makedirs(out, exist_ok=True)
    kept = total = 0
    for stem, scan in real_scans():
        if "izquierda" in stem or "derecha" in stem:
            continue  # profiles: no torso or hair geometry to stand in for
        base = f"{out}/{stem}.obj"
        ref, err = baseline(binary, scan, base, f"{out}/{stem}.json")
        if ref is None:
            print(f"{stem}: baseline failed: {err}")
            continue
        lm = ref["landmarks"]
        tip, chin, forehead = lm["nose_tip"], lm["chin"], lm["forehead"]
        top = chin[1] - 40.0
        low = forehead[1] + 20.0
        clutter = {
            "torso": patch((tip[0] - 180, tip[0] + 180), (top - 200, top), 2.0,
                           lambda x, y: tip[2] + 15 - ((x - tip[0]) / 60) ** 2 * 10),
            "hair": patch((tip[0] - 100, tip[0] + 100), (low, low + 80), 2.0,
                          lambda x, y: forehead[2] + 10 - ((x - tip[0]) / 50) ** 2 * 8
                          - (y - low) * 0.3 + 3 * math.sin(x * 0.3) * math.cos(y * 0.25)),
        }
        row = [stem[:30].ljust(30), "suspect" if ref["suspect"] else "       "]
        for name, (v, q) in clutter.items():
            total += 1
            obj = f"{out}/{stem}_{name}.obj"
            with_patch(base, obj, v, q)
            got, err = detect(binary, obj, f"{out}/{stem}_{name}.json")
            if got is None:
                row.append(f"{name}: failed ({err})")
                continue
            moved, worst = max(((math.dist(got["landmarks"][p], lm[p]), p) for p in ANATOMICAL),
                               key=lambda t: t[0])
            kept += moved <= 2.0
            flag = " suspect" if got["suspect"] else ""
            row.append(f"{name}: {moved:5.1f} mm ({worst}){flag}")
        print("  ".join(row), flush=True)
    print(f"within 2 mm: {kept} of {total} cluttered copies")


if __name__ == "__main__":
    main()

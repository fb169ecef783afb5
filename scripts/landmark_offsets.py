#!/usr/bin/env python3
"""Signed offsets between two sets of feature points, per point, in a face frame (lateral,
up, depth; mm): mean and spread over all scans. A measurement aid for docs/measurements.md,
not part of the product.

    scripts/landmark_offsets.py A_DIR B_DIR

Each directory holds <stem>.json files: `facesynth landmarks --json` output, the oracle's
(../shared/tools/landmark_oracle.py) or synth_gavab.py ground truth. Prints A − B. The frame
comes from B: x from the right to the left inner eye corner, y up from the mouth corners'
midpoint to the inner corners' midpoint; lateral is away from the midline on each side.
Profiles (izquierda, derecha) and scans where B found no face are left out."""
import glob, json, os, sys
import numpy as np

NAMES = ["nose_tip", "inner_eye_left", "inner_eye_right", "outer_eye_left", "outer_eye_right",
         "mouth_corner_left", "mouth_corner_right"]

def points(path):
    d = json.load(open(path))
    if d.get("found") is False or "landmarks" not in d:
        return None
    lm = d["landmarks"]
    out = {}
    for k, v in lm.items():
        if isinstance(v, dict):  # synth_gavab ground truth: {"xyz_mm": [...], ...}
            v = v["xyz_mm"]
            k = k.replace("_corner", "") if "eye" in k else k
        out[k] = np.array(v, float)
    return out

def frame(b):
    ex = b["inner_eye_left"] - b["inner_eye_right"]
    ex /= np.linalg.norm(ex)
    up = (b["inner_eye_left"] + b["inner_eye_right"]) / 2 - (b["mouth_corner_left"] + b["mouth_corner_right"]) / 2
    up -= ex * up.dot(ex)
    up /= np.linalg.norm(up)
    return ex, up, np.cross(ex, up)

def main(a_dir, b_dir):
    rows = {n: [] for n in NAMES}
    for f in sorted(glob.glob(os.path.join(a_dir, "*.json"))):
        stem = os.path.basename(f)
        if "derecha" in stem or "izquierda" in stem or not os.path.exists(os.path.join(b_dir, stem)):
            continue
        a, b = points(f), points(os.path.join(b_dir, stem))
        if a is None or b is None:
            continue
        ex, up, ez = frame(b)
        for n in NAMES:
            if n in a and n in b:
                side = -1.0 if n.endswith("right") else 1.0
                d = a[n] - b[n]
                rows[n].append((side * d.dot(ex), d.dot(up), d.dot(ez), np.linalg.norm(d)))
    for n, v in rows.items():
        if v:
            v = np.array(v)
            print("%-19s n=%3d  mean lateral/up/depth %s  sd %s  mean distance %.1f"
                  % (n, len(v), v[:, :3].mean(0).round(1), v[:, :3].std(0).round(1), v[:, 3].mean()))

if __name__ == "__main__":
    main(*sys.argv[1:3])

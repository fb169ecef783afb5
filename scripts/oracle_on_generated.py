#!/usr/bin/env python3
"""How often the independent detector alone disagrees: facesynth and the independent detector
(../shared/tools, a measurement, not a product dependency) on generated scans with ground
truth, so that a disagreement count on real scans can be read against it.

For every scan of a `synth_gavab.py` folder, both detect the seven compared points (nose tip,
eye and mouth corners). Per scan kind (frontal1, sonrisa, ...) it prints: how many scans;
on how many facesynth has all seven within 10 mm of the truth; on how many of those the two
still disagree by more than the agreement tolerance (12 mm, as `landmark_agree.py`); and on
how many the independent detector itself is more than 12 mm off.

    python3 scripts/oracle_on_generated.py SYNTH_DIR OUT [FACESYNTH]
"""
import glob
import json
import math
import os
import subprocess
import sys

from clutter_real import detect

COMPARED = [
    "nose_tip", "inner_eye_right", "inner_eye_left", "outer_eye_right", "outer_eye_left",
    "mouth_corner_right", "mouth_corner_left",
]
TOLERANCE_MM = 12.0
CORRECT_MM = 10.0


def truth(gt, name):
    """Ground-truth position of one of facesynth's point names (synth_gavab's names differ)."""
    return gt["landmarks"][name.replace("eye_", "eye_corner_")]["xyz_mm"]


def main():
    synth, out = sys.argv[1], sys.argv[2]
    binary = sys.argv[3] if len(sys.argv) > 3 else "target/release/facesynth"
    oracle_dir, ours_dir = f"{out}/oracle", f"{out}/facesynth"
    os.makedirs(oracle_dir, exist_ok=True)
    os.makedirs(ours_dir, exist_ok=True)
    scans = sorted(glob.glob(f"{synth}/subj*.wrl"))
    todo = [s for s in scans if not os.path.exists(f"{oracle_dir}/{os.path.basename(s)[:-4]}.json")]
    if todo:
        subprocess.run([sys.executable, "../shared/tools/landmark_oracle.py", *todo, "--out",
                        oracle_dir], check=True, capture_output=True)
    rows = {}
    for scan in scans:
        stem = os.path.basename(scan)[:-4]
        kind = stem.split("_", 1)[1]
        gt = json.load(open(f"{synth}/{stem}.json"))
        ours, _ = detect(binary, scan, f"{ours_dir}/{stem}.json")
        oracle = json.load(open(f"{oracle_dir}/{stem}.json"))
        row = rows.setdefault(kind, [0, 0, 0, 0])
        row[0] += 1
        if ours is None or not oracle.get("found"):
            continue
        theirs = {p: oracle["landmarks"][p] for p in COMPARED if p in oracle["landmarks"]}
        ours_ok = all(math.dist(ours["landmarks"][p], truth(gt, p)) <= CORRECT_MM
                      for p in COMPARED)
        apart = max(math.dist(ours["landmarks"][p], q) for p, q in theirs.items())
        if ours_ok:
            row[1] += 1
            row[2] += apart > TOLERANCE_MM
        row[3] += max(math.dist(q, truth(gt, p)) for p, q in theirs.items()) > TOLERANCE_MM
    print("kind      scans  facesynth all within 10 mm  of which disagree > 12 mm  "
          "independent detector > 12 mm off")
    for kind, (n, ok, apart, off) in sorted(rows.items()):
        print(f"{kind:9s} {n:5d}  {ok:26d}  {apart:25d}  {off:32d}")


if __name__ == "__main__":
    main()

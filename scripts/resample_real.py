#!/usr/bin/env python3
"""Real scans sampled differently: every real scan in ../shared/data as another scanner would
sample the same face, detected again.

For each scan: `facesynth convert` writes it as OBJ (the baseline) and `facesynth landmarks`
finds its points; then two copies of the same surface:
  dense:  every triangle split into four at its edge midpoints (the same piecewise-linear
          surface at half the spacing: ~0.8 mm, as a structured-light scanner samples a face);
  coarse: vertex clustering in 3 mm cubes (each occupied cube one vertex, the mean of its
          members; ~2.5–3 mm spacing).
Prints, per scan and copy, how far the ten anatomical points moved (max, mm) and whether the
detection is suspect; then the median of those maxima and, per copy, how many copies keep all
points within 2 and 5 mm. With ORACLE (an `OUT/oracle` folder of `scripts/real_landmarks.sh`),
also the independent detector's agreement on each copy (`landmark_agree.py`).

    python3 scripts/resample_real.py OUT [FACESYNTH] [ORACLE]
"""
import glob
import json
import math
import os
import statistics
import subprocess
import sys

from clutter_real import ANATOMICAL, baseline, detect, real_scans


def read_obj(path):
    """Vertices and triangles (0-based, polygons fanned) of an OBJ file."""
    v, t = [], []
    for line in open(path):
        if line.startswith("v "):
            v.append(tuple(float(x) for x in line.split()[1:4]))
        elif line.startswith("f "):
            f = [int(x.split("/")[0]) - 1 for x in line.split()[1:]]
            t += [(f[0], f[i], f[i + 1]) for i in range(1, len(f) - 1)]
    return v, t


def write_obj(path, v, t):
    with open(path + ".tmp", "w") as f:
        f.writelines(f"v {x:.4f} {y:.4f} {z:.4f}\n" for x, y, z in v)
        f.writelines(f"f {a + 1} {b + 1} {c + 1}\n" for a, b, c in t)
    os.replace(path + ".tmp", path)


def dense(v, t):
    """Each triangle split into four at its edge midpoints."""
    v = list(v)
    mids = {}

    def mid(a, b):
        key = (min(a, b), max(a, b))
        if key not in mids:
            mids[key] = len(v)
            v.append(tuple((p + q) / 2 for p, q in zip(v[a], v[b])))
        return mids[key]

    out = []
    for a, b, c in t:
        ab, bc, ca = mid(a, b), mid(b, c), mid(c, a)
        out += [(a, ab, ca), (ab, b, bc), (ca, bc, c), (ab, bc, ca)]
    return v, out


def coarse(v, t, cell=3.0):
    """Vertex clustering in cubes of side `cell` mm; triangles with three distinct corners kept."""
    index, sums = {}, []
    remap = []
    for p in v:
        key = tuple(math.floor(x / cell) for x in p)
        if key not in index:
            index[key] = len(sums)
            sums.append([0.0, 0.0, 0.0, 0])
        k = index[key]
        s = sums[k]
        s[0] += p[0]
        s[1] += p[1]
        s[2] += p[2]
        s[3] += 1
        remap.append(k)
    nv = [(s[0] / s[3], s[1] / s[3], s[2] / s[3]) for s in sums]
    seen, nt = set(), []
    for a, b, c in t:
        a, b, c = remap[a], remap[b], remap[c]
        if len({a, b, c}) == 3 and tuple(sorted((a, b, c))) not in seen:
            seen.add(tuple(sorted((a, b, c))))
            nt.append((a, b, c))
    return nv, nt


def main():
    out = sys.argv[1]
    binary = sys.argv[2] if len(sys.argv) > 2 else "target/release/facesynth"
    oracle = sys.argv[3] if len(sys.argv) > 3 else None
    copies = {"dense": dense, "coarse": coarse}
    for name in ["plain", *copies]:
        os.makedirs(f"{out}/{name}", exist_ok=True)
    moved = {name: [] for name in copies}
    for stem, scan in real_scans():
        base = f"{out}/{stem}.obj"
        ref, _ = baseline(binary, scan, base, f"{out}/plain/{stem}.json")
        if ref is None:
            print(f"{stem}: baseline failed")
            continue
        v, t = read_obj(base)
        row = [stem[:30].ljust(30), "suspect" if ref["suspect"] else "       "]
        for name, make in copies.items():
            obj = f"{out}/{stem}_{name}.obj"
            write_obj(obj, *make(v, t))
            got, _ = detect(binary, obj, f"{out}/{name}/{stem}.json")
            if got is None:
                row.append(f"{name}: failed")
                continue
            d, worst = max(((math.dist(got["landmarks"][p], ref["landmarks"][p]), p)
                            for p in ANATOMICAL), key=lambda x: x[0])
            moved[name].append(d)
            row.append(f"{name}: {d:5.1f} mm ({worst}){' suspect' if got['suspect'] else ''}")
            os.remove(obj)
        print("  ".join(row), flush=True)
    for name, ds in moved.items():
        if ds:
            print(f"{name}: median of the largest move {statistics.median(ds):.1f} mm; within 2 mm "
                  f"{sum(d <= 2 for d in ds)}, within 5 mm {sum(d <= 5 for d in ds)} of {len(ds)}")
    if oracle:
        for name in ["plain", *copies]:
            agree_py = "../shared/tools/landmark_agree.py"
            r = subprocess.run([sys.executable, agree_py, f"{out}/{name}", oracle],
                               capture_output=True, text=True)
            agree = r.stdout.strip().splitlines()[-1] if r.stdout.strip() else r.stderr.strip()
            suspect = sum(json.load(open(f))["suspect"] for f in glob.glob(f"{out}/{name}/*.json"))
            print(f"{name}: {agree}; suspect {suspect}")


if __name__ == "__main__":
    main()

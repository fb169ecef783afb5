#!/usr/bin/env python3
"""Writes an N x N vertex grid as binary little-endian PLY (quads), for memory and limit tests.

The surface is a dome with a nose-like Gaussian bump, sampled every 0.15 mm (15 cm across at
N = 1000), so readers and the denoiser see an ordinary scan-like mesh. Default: 1M vertices.

    python3 scripts/grid_mesh.py --n 1000 --out /tmp/grid1m.ply
"""
import argparse
import struct


def main():
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--n", type=int, default=1000, help="vertices per side (default 1000)")
    ap.add_argument("--step-mm", type=float, default=0.15, help="grid spacing, mm (default 0.15)")
    ap.add_argument("--out", required=True)
    a = ap.parse_args()
    n, h = a.n, a.step_mm
    half = (n - 1) * h / 2
    head = (
        "ply\nformat binary_little_endian 1.0\n"
        f"element vertex {n * n}\nproperty float x\nproperty float y\nproperty float z\n"
        f"element face {(n - 1) * (n - 1)}\nproperty list uchar int vertex_indices\nend_header\n"
    ).encode()
    import math

    with open(a.out, "wb") as f:
        f.write(head)
        row = struct.Struct("<fff")
        for j in range(n):
            y = half - j * h
            buf = bytearray()
            for i in range(n):
                x = i * h - half
                r2 = x * x + y * y
                z = 60.0 - r2 / 240.0 + 20.0 * math.exp(-r2 / 200.0)
                buf += row.pack(x, y, z)
            f.write(buf)
        quad = struct.Struct("<B4i")
        for j in range(n - 1):
            buf = bytearray()
            for i in range(n - 1):
                v = j * n + i
                # Counter-clockwise seen from +z (rows go down in y).
                buf += quad.pack(4, v, v + n, v + n + 1, v + 1)
            f.write(buf)


if __name__ == "__main__":
    main()

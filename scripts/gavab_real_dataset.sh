#!/bin/sh
# Builds a GavabDB-protocol dataset folder from the real scans in ../shared/data/gavabdb:
# one symlink per (subject, scan) named <subject>_<scan>.<ext>, as `facesynth evaluate` and
# `facesynth augment` expect. VRML scans are preferred over point clouds of the same capture;
# among point clouds the plain `caraN_<scan>.txt` over `caraN_<scan>_filtered_raw.txt`.
# Nothing is copied (the data is third-party; never commit it).
#
#   scripts/gavab_real_dataset.sh [SRC] OUT
set -eu
if [ $# -eq 1 ]; then SRC=../shared/data/gavabdb; OUT=$1; else SRC=$1; OUT=$2; fi
SRC=$(cd "$SRC" && pwd)
mkdir -p "$OUT"
link() { # $1 = source file, $2 = subject_scan, $3 = extension
    [ -e "$OUT/$2.wrl" ] || [ -e "$OUT/$2.txt" ] || ln -s "$1" "$OUT/$2.$3"
}
for f in "$SRC"/*.wrl; do
    [ -e "$f" ] || continue
    b=$(basename "$f" .wrl); link "$f" "$b" wrl
done
for f in "$SRC"/pointclouds/*.txt; do
    [ -e "$f" ] || continue
    b=$(basename "$f" .txt)
    case "$b" in *_filtered_raw) continue ;; esac
    link "$f" "$b" txt
done
for f in "$SRC"/pointclouds/*_filtered_raw.txt; do
    [ -e "$f" ] || continue
    b=$(basename "$f" .txt); b=${b%_filtered_raw}
    link "$f" "$b" txt
done
ls "$OUT"

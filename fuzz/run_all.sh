#!/usr/bin/env bash
# Runs every fuzz target for SECONDS (default 600) one after another, single process each,
# logging to fuzz/logs/<target>.log; a summary line per target goes to fuzz/logs/summary.txt.
# Usage: fuzz/seed.sh && fuzz/run_all.sh [SECONDS] [TARGET...]
set -uo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
cd "$here"
secs="${1:-600}"
shift || true
targets=("$@")
[ ${#targets[@]} -gt 0 ] || targets=(vrml obj ply xyz presets_ron landmarks_json sidecar_json mesh_pipeline)
mkdir -p logs
for t in "${targets[@]}"; do
  mkdir -p "artifacts/$t"
  # mesh_pipeline's seeds are whole (small) faces.
  max_len=65536
  [ "$t" = mesh_pipeline ] && max_len=262144
  # -max_len keeps mutations on the structure (headers, first records) rather than on the
  # bulk of 1 MB scans; -rss_limit_mb catches allocations out of proportion to the input.
  cargo +nightly fuzz run -O "$t" "corpus/$t" -- \
    -max_total_time="$secs" -max_len="$max_len" -rss_limit_mb=2048 -timeout=10 \
    -print_final_stats=1 -artifact_prefix="artifacts/$t/" > "logs/$t.log" 2>&1
  rc=$?
  last="$(grep -E '^#[0-9]+' "logs/$t.log" | tail -1)"
  execs="$(grep -E '^stat::number_of_executed_units' "logs/$t.log" | awk '{print $2}')"
  eps="$(grep -E '^stat::average_exec_per_sec' "logs/$t.log" | awk '{print $2}')"
  crashes="$(ls "artifacts/$t" | wc -l)"
  echo "$t rc=$rc secs=$secs execs=$execs exec_per_s=$eps artifacts=$crashes last: $last" >> logs/summary.txt
done

#!/usr/bin/env bash
# Regenerate everything in results/ from scratch: the sweep tables, the single-cycle
# trajectories, the figures and REPORT.md. Run from anywhere:
#
#     bash results/regenerate.sh [--jobs N]
#
# Needs the package with its plotting extra: pip install -e ".[plot]"
set -euo pipefail
cd "$(dirname "$0")/.."
JOBS=()
if [[ "${1:-}" == "--jobs" ]]; then JOBS=(--jobs "$2"); fi
export FENCESWEEP_REGEN_START="$(date +%s)"

# 1. start from nothing (only what this script makes)
rm -rf results/traj results/REPORT.md
rm -f results/figures/fig[2-8]*.png results/figures/map_*.png results/figures/cycle_*.png \
      results/figures/recommended.png   # its own figures only (benchmarks write there too)
SPECS=(b2k2 psi_b2 fig5a fig5b freefall_H)   # fencesweep.report.TABLES
for spec in "${SPECS[@]}"; do rm -f "results/$spec.parquet"; done

# 2. sweeps (one Parquet table each; sweeps/README.md)
for spec in "${SPECS[@]}"; do
  fencesweep grid "sweeps/$spec.yaml" --out "results/$spec.parquet" --quiet --no-resume "${JOBS[@]}"
  echo "results/$spec.parquet"
done

# 3. the single cycles the figures need (after b2k2: the recommended element is read off it)
fencesweep plot trajectories --results results

# 4. figures and the report
fencesweep plot all --results results
fencesweep plot report --results results

echo "results/ regenerated in $(( $(date +%s) - FENCESWEEP_REGEN_START )) s"

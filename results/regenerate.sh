#!/usr/bin/env bash
# Regenerate everything in results/ from scratch: the sweep tables, the single-cycle
# trajectories, the figures, REPORT.md and the benchmark pages that time the kernel
# (work_precision, scaling_main, stream_cost). Run from anywhere:
#
#     bash results/regenerate.sh [--jobs N] [--no-benchmarks]
#
# Needs the package with its plotting extra: pip install -e ".[plot]"; the benchmarks (step 5,
# minutes, timed: run the script alone on the machine) need the bench extra: pip install -e ".[bench]"
set -euo pipefail
cd "$(dirname "$0")/.."
JOBS=()
BENCHMARKS=1
while [[ $# -gt 0 ]]; do
  case "$1" in
    --jobs) JOBS=(--jobs "$2"); shift 2 ;;
    --no-benchmarks) BENCHMARKS=0; shift ;;
    *) echo "usage: bash results/regenerate.sh [--jobs N] [--no-benchmarks]" >&2; exit 2 ;;
  esac
done
export FENCESWEEP_REGEN_START="$(date +%s)"

# 1. start from nothing (only what this script makes)
rm -rf results/traj results/REPORT.md
rm -f results/figures/fig[2-8]*.png results/figures/map_*.png results/figures/cycle_*.png \
      results/figures/recommended.png results/figures/stream_deflection.png   # its own figures only (benchmarks write there too)
SPECS=(b2k2 psi_b2 fig5a fig5b freefall_H period fig5a_worst_v fig5a_worst_tc)   # fencesweep.report.TABLES
for spec in "${SPECS[@]}"; do rm -f "results/$spec.parquet"; done

# 2. sweeps (one Parquet table each; sweeps/README.md)
for spec in "${SPECS[@]}"; do
  fencesweep grid "sweeps/$spec.yaml" --out "results/$spec.parquet" --quiet --no-resume "${JOBS[@]}"
  echo "results/$spec.parquet"
done

# 2b. design for every package: the envelope map (419904 cycles, minutes), the
#     recommendation, the operating window, the swing, and the sensitivity (needs SALib)
rm -rf results/design results/envelope*.parquet results/window*.parquet results/swing.parquet results/tolerance.parquet results/tolerance_points.parquet results/sensitivity*.parquet
fencesweep grid sweeps/envelope.yaml --quiet --no-resume "${JOBS[@]}"
fencesweep design sweeps/envelope.yaml --quiet "${JOBS[@]}"
fencesweep grid sweeps/window.yaml --quiet --no-resume "${JOBS[@]}"
fencesweep grid sweeps/swing.yaml --quiet --no-resume "${JOBS[@]}"
fencesweep grid sweeps/tolerance.yaml --quiet --no-resume "${JOBS[@]}"
if python -c "import SALib" 2>/dev/null; then
  fencesweep sensitivity sweeps/sensitivity.yaml --quiet "${JOBS[@]}"
else
  echo "skipping fencesweep sensitivity: SALib is not installed (pip install -e \".[sensitivity]\")"
fi

# 2c. risk from a parcel mix (an assumed mix, sweeps/risk.yaml; about two minutes on one core)
rm -f results/risk.parquet
fencesweep risk sweeps/risk.yaml --quiet --no-resume "${JOBS[@]}"

# 3. the single cycles the figures need (after b2k2 and fig5a_worst_v: the recommended element and the
#    worst placements are read off them)
fencesweep plot trajectories --results results

# 4. figures and the report
fencesweep plot all --results results
fencesweep plot-design --results results   # envelope map, loads, window, risk map (and sensitivity when its table exists)
fencesweep plot report --results results

# 5. the benchmark pages that time the current kernel: work-precision against the reference (with
#    solve_ivp), the main job's command on 1 and 2 jobs with its phases, a stream's cost per cycle
#    (an earlier revision against this one: asv, benchmarks/README.md)
if [[ "$BENCHMARKS" == 1 ]]; then
  python benchmarks/work_precision.py
  python benchmarks/scaling.py --spec sweeps/b2k2.yaml --jobs 1 2 --rounds 3 --out results/scaling_main.md
  python benchmarks/stream_cost.py   # a stream's cost per cycle against a cycle -> results/stream_cost.md
fi

echo "results/ regenerated in $(( $(date +%s) - FENCESWEEP_REGEN_START )) s"

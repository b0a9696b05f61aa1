#!/usr/bin/env bash
# meshflow's own sweep on the zebrafish pairs, scored like the 2-D tools (README.md).
#
#   sweep_meshflow.sh WORK [MESHFLOW]
#
# WORK holds surf_PAIR and tracks_PAIR.npy of the README's commands; MESHFLOW is the binary
# (default: meshflow on PATH). Each setting below is solved on the four pairs into
# WORK/sweep/NAME_PAIR, and one line per setting is printed and appended to
# WORK/sweep/results.txt: endpoint ratio / median speed ratio per pair, then their means.
set -euo pipefail
work=$1
meshflow=${2:-meshflow}
pairs="114-116 120-122 140-141 140-142"
mkdir -p "$work/sweep"

solve_setting() {
    local name=$1
    shift
    for pair in $pairs; do
        "$meshflow" solve "$work/surf_$pair" --out "$work/sweep/${name}_$pair" --force --quiet \
            --regularizer strain --time-scale 0 --ground-truth-tracks "$work/tracks_$pair.npy" \
            "$@" >"$work/sweep/${name}_$pair.log" 2>&1
    done
    python3 - "$work/sweep" "$name" "$pairs" "$*" <<'PY' | tee -a "$work/sweep/results.txt"
import json, sys
folder, name, pairs, flags = sys.argv[1], sys.argv[2], sys.argv[3].split(), sys.argv[4]
scores = [json.load(open(f"{folder}/{name}_{p}/summary.json"))["ground_truth_tracks"] for p in pairs]
ratios = [s["endpoint_ratio"] for s in scores]
speeds = [s["median_speed_ratio"] for s in scores]
cells = " ".join(f"{r:.3f}/{s:.2f}" for r, s in zip(ratios, speeds))
print(f"{name:16s} {cells} | mean {sum(ratios) / len(ratios):.4f} speed {sum(speeds) / len(speeds):.3f} | {flags}")
PY
}

solve_setting defaults
solve_setting large_motion --large-motion
for spread in 0.05 0.1 0.25 1 2; do solve_setting "spread_$spread" --spread "$spread"; done
solve_setting spread_0.25_large_motion --spread 0.25 --large-motion
solve_setting robust_data --robust-data auto
solve_setting robust_smoothness --robust-smoothness auto
solve_setting anisotropic --anisotropic auto
for rho in 0 3 6 10; do solve_setting "clg_$rho" --local-integration "$rho"; done
for rho in 6 10; do
    solve_setting "clg_${rho}_spread_0.25" --local-integration "$rho" --spread 0.25
    solve_setting "clg_${rho}_spread_0.1" --local-integration "$rho" --spread 0.1
done
solve_setting clg_15_spread_0.05 --local-integration 15 --spread 0.05
solve_setting clg_6_large_motion --local-integration 6 --large-motion
solve_setting clg_6_spread_0.25_large_motion --local-integration 6 --spread 0.25 --large-motion
solve_setting clg_6_spread_0.25_anisotropic --local-integration 6 --spread 0.25 --anisotropic auto

#!/usr/bin/env bash
# The measurements of docs/crowd.md, "Where the roughness comes from: the goals, the corners and the walker"
# (2026-12-05, 2-core Intel Xeon VM, about 10 minutes in all). Run from the repository root.
set -euo pipefail
D=docs/results/diffusion_roughness_2026-12-05
export OMP_NUM_THREADS=1
R="python scripts/diffusion_roughness.py --seconds 60"
# 1. the crowded scenes of the earlier ablation (lobby 12, corridor 10, home 5), 60 s, seed 0
$R --out $D/crowded.jsonl --variants "default;no_neigh=1;no_neigh=1,agent_weight=0;pace_ramp=0.3;pace_ramp=0.5;pace_ramp=1.0"
$R --out $D/crowded.jsonl --variants "orca_walker=1,orca_time_horizon=5,orca_time_horizon_obst=5;orca_walker=1;\
orca_walker=1,orca_time_horizon=1.0,orca_time_horizon_obst=0.3;orca_walker=1,orca_time_horizon=2.5,orca_time_horizon_obst=1.0;\
orca_walker=1,orca_time_horizon=5,orca_time_horizon_obst=0.5"
$R --out $D/crowded.jsonl --variants "walker_max_accel=1.0;walker_max_accel=2.0;walker_tau=1.0"
$R --out $D/crowded.jsonl --variants "walker_A_wall=0.3;walker_A_wall=0.1;walker_A=0.5;walker_A=0.5,walker_A_wall=0.3"
$R --out $D/crowded.jsonl --crowd sfm --variants default
$R --out $D/crowded.jsonl --crowd orca --variants default
# 2. one person alone in a scene, 120 s
for s in square_crossing corridor doorway home; do
  python scripts/diffusion_roughness.py --seconds 120 --scenes $s:1 --out $D/alone.jsonl --variants "default;guidance_scale=0"
  for c in sfm orca; do
    python scripts/diffusion_roughness.py --seconds 120 --scenes $s:1 --out $D/alone.jsonl --crowd $c --variants default
  done
done

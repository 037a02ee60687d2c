#!/usr/bin/env bash
# Benchmark the shipped CrowdNav policy and its fine-tunes (2 conditions x 2 training seeds) (training/robot_vs_crowd/) on
# training/robot_vs_crowd/benchmark.yaml, one after the other; needs the learned crowds in runs/joint_study
# (scripts/device_joint_study.sh). usage: bash training/robot_vs_crowd/run_benchmark.sh OUT_DIR [WORKERS] [SPEC]
# (SPEC: training/robot_vs_crowd/benchmark.yaml, or benchmark_round2.yaml for round 2)
set -euo pipefail
out=${1:-runs/rvc_bench}; workers=${2:-2}; spec=${3:-training/robot_vs_crowd/benchmark.yaml}
for name in shipped vs_learned_seed0 vs_orca_seed0 vs_learned_seed1 vs_orca_seed1; do
  dir=training/robot_vs_crowd/$name/policy
  [ "$name" = shipped ] && dir=policies/transformer_ppo_crowdnav
  NAVZOO_TRANSFORMER_PPO_CROWDNAV_DIR=$dir navzoo benchmark --spec "$spec" \
    --workers "$workers" --out "$out/$name" --no-progress 2>&1 | grep -v '^b3' | tail -1
done

#!/usr/bin/env bash
# One DAgger round of the paper-scene policy's imitation stage on the device machine: ORCA
# demonstrations (beta 1, the first 3 of bc_device.sh's 5 seed blocks) and learner-driven episodes labelled by ORCA
# (LEARNER drives with probability 1 - BETA), then the actor-critic refitted to all of them on
# the GPU and a validation benchmark (seed 1). BETA (0.5) and SEED_BASE (100, learner episodes get seeds
# SEED_BASE and 2 SEED_BASE) set the round. usage: training/robot/dagger_device.sh LEARNER DEMO_DIR BC_DIR
set -uo pipefail
learner=$1; demos=$2; bc=$3; mkdir -p "$demos" "$OUT"
export OMP_NUM_THREADS=1 MKL_NUM_THREADS=1
pids=()
for k in 0 1 2; do
  for spec in station:8 grocery:10 home:14; do
    scene=${spec%%:*}; n=${spec##*:}
    python3 -m navzoo.agents.robot_bc collect --out "$demos" --scenes "$scene" --episodes "$n" \
      --seed $((1000 * (k + 1))) 2>&1 | grep -v '^b3' >> "$OUT/collect.log" &
    pids+=($!)
  done
done
for k in 0 1; do
  for spec in station:4 grocery:6 home:8; do
    scene=${spec%%:*}; n=${spec##*:}
    timeout ${COLLECT_TIMEOUT:-330} python3 -m navzoo.agents.robot_bc collect --out "$demos" --scenes "$scene" \
      --episodes "$n" --seed $((${SEED_BASE:-100} * (k + 1))) --learner "$learner" --beta ${BETA:-0.5} 2>&1 | grep -v '^b3' >> "$OUT/collect.log" &
    pids+=($!)
  done
done
wait "${pids[@]}"
python3 -m navzoo.agents.robot_bc pretrain --demos "$demos" --out "$bc" --init-from policies/transformer_ppo_crowdnav \
  --epochs ${BC_EPOCHS:-12} --device cuda 2>&1 | grep -v '^b3' > "$OUT/pretrain.log"
cp "$bc/policy/config.json" "$bc/policy/policy.pt" "$OUT/"
NAVZOO_TRANSFORMER_PPO_DIR=$bc/policy timeout ${VAL_TIMEOUT:-150} python3 -m navzoo.cli benchmark --scenes station,home,grocery \
  --methods transformer-ppo --crowd sfm --density 0.05,0.15,0.3 --max-humans 40 --episodes 4 --seed 1 \
  --workers 16 --out /tmp/val_bc --no-progress 2>&1 | grep -v '^b3' | tail -1
python3 -m navzoo.cli report /tmp/val_bc 2>&1 | grep '^| transformer' | tee "$OUT/val.log"

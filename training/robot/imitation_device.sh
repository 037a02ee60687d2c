#!/usr/bin/env bash
# Imitation stage of the paper-scene policy on the device machine: ORCA demonstrations in the three
# training scenes from parallel processes, then the actor-critic fitted to them on the GPU (from the
# CrowdNav weights), then a validation benchmark (seed 1) of the result.
# usage: training/robot/imitation_device.sh DEMO_DIR BC_DIR [LEARNER]
# - without LEARNER (behaviour cloning): 5 blocks of expert episodes (seeds 1000..5000), 15 epochs;
# - with LEARNER (a DAgger round): 3 expert blocks (seeds 1000..3000) and 2 blocks in which LEARNER
#   drives with probability 1 - BETA (default 0.5) and ORCA labels every step (seeds SEED_BASE and
#   2 SEED_BASE, default 100), 12 epochs.
set -uo pipefail
demos=$1; bc=$2; learner=${3:-}; mkdir -p "$demos" "$OUT"
export OMP_NUM_THREADS=1 MKL_NUM_THREADS=1
blocks=5; epochs=15
if [ -n "$learner" ]; then blocks=3; epochs=12; fi
pids=()
for k in $(seq 0 $((blocks - 1))); do
  for spec in station:8 grocery:10 home:14; do
    scene=${spec%%:*}; n=${spec##*:}
    python3 -m navzoo.agents.robot_bc collect --out "$demos" --scenes "$scene" --episodes "$n" \
      --seed $((1000 * (k + 1))) 2>&1 | grep -v '^b3' >> "$OUT/collect.log" &
    pids+=($!)
  done
done
if [ -n "$learner" ]; then
  for k in 0 1; do
    for spec in station:4 grocery:6 home:8; do
      scene=${spec%%:*}; n=${spec##*:}
      timeout ${COLLECT_TIMEOUT:-330} python3 -m navzoo.agents.robot_bc collect --out "$demos" --scenes "$scene" \
        --episodes "$n" --seed $((${SEED_BASE:-100} * (k + 1))) --learner "$learner" --beta ${BETA:-0.5} \
        2>&1 | grep -v '^b3' >> "$OUT/collect.log" &
      pids+=($!)
    done
  done
fi
wait "${pids[@]}"
python3 -m navzoo.agents.robot_bc pretrain --demos "$demos" --out "$bc" --init-from policies/transformer_ppo_crowdnav \
  --epochs ${BC_EPOCHS:-$epochs} --device cuda 2>&1 | grep -v '^b3' > "$OUT/pretrain.log"
cp "$bc/policy/config.json" "$bc/policy/policy.pt" "$OUT/"
NAVZOO_TRANSFORMER_PPO_DIR=$bc/policy timeout ${VAL_TIMEOUT:-170} python3 -m navzoo.cli benchmark \
  --scenes station,home,grocery --methods transformer-ppo --crowd sfm --density 0.05,0.15,0.3 --max-humans 40 \
  --episodes 4 --seed 1 --workers 16 --out /tmp/val_bc --no-progress 2>&1 | grep -v '^b3' | tail -1
python3 -m navzoo.cli report /tmp/val_bc 2>&1 | grep '^| transformer' | tee "$OUT/val.log"

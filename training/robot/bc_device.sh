#!/usr/bin/env bash
# Imitation stage of the paper-scene policy on the device machine: ORCA demonstrations in the three
# training scenes from 15 parallel processes, then the actor-critic fitted to them on the GPU, then a
# validation benchmark (seed 1) of the result. usage: training/robot/bc_device.sh DEMO_DIR BC_DIR
set -uo pipefail
demos=$1; bc=$2; mkdir -p "$demos" "$OUT"
pids=()
for k in 0 1 2 3 4; do
  for spec in station:8 grocery:10 home:14; do
    scene=${spec%%:*}; n=${spec##*:}
    python3 -m navzoo.agents.robot_bc collect --out "$demos" --scenes "$scene" --episodes "$n" \
      --seed $((1000 * (k + 1))) 2>&1 | grep -v '^b3' >> "$OUT/collect.log" &
    pids+=($!)
  done
done
wait "${pids[@]}"
python3 -m navzoo.agents.robot_bc pretrain --demos "$demos" --out "$bc" --init-from policies/transformer_ppo_crowdnav \
  --epochs ${BC_EPOCHS:-15} --device cuda 2>&1 | grep -v '^b3' > "$OUT/pretrain.log"
cp "$bc/policy/config.json" "$bc/policy/policy.pt" "$OUT/"
NAVZOO_TRANSFORMER_PPO_DIR=$bc/policy timeout ${VAL_TIMEOUT:-170} python3 -m navzoo.cli benchmark --scenes station,home,grocery \
  --methods transformer-ppo --crowd sfm --density 0.05,0.15,0.3 --max-humans 40 --episodes 4 --seed 1 \
  --workers 16 --out /tmp/val_bc --no-progress 2>&1 | grep -v '^b3' | tail -1
python3 -m navzoo.cli report /tmp/val_bc 2>&1 | grep '^| transformer' | tee "$OUT/val.log"

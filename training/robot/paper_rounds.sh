#!/usr/bin/env bash
# Train the paper-scene policy (station + home + grocery) in rounds on the device machine; after each
# round export a float16 snapshot and score it on validation episodes (benchmark seed 1 on the three
# training scenes at three densities; the reported benchmark uses seed 0 on every scene).
# usage (device machine, wheels installed, $OUT set):
#   training/robot/paper_rounds.sh RUN_DIR ROUNDS SECONDS
# TRAIN_EXTRA adds training options (e.g. "--init-from policies/transformer_ppo_crowdnav --lr 1.5e-4").
set -uo pipefail
run=$1; rounds=$2; secs=$3; snaps=$OUT/snaps; mkdir -p "$snaps"
score() {  # score SNAPSHOT_DIR LABEL
  NAVZOO_TRANSFORMER_PPO_DIR=$1 timeout ${VAL_TIMEOUT:-150} python3 -m navzoo.cli benchmark --scenes station,home,grocery \
    --methods transformer-ppo --crowd sfm --density 0.05,0.15,0.3 --max-humans 40 --episodes 4 --seed 1 \
    --workers 16 --out /tmp/val_$2 --no-progress 2>&1 | grep -v '^b3' | tail -1 >/dev/null
  echo "$2 $(python3 -m navzoo.cli report /tmp/val_$2 2>&1 | grep '^| transformer' | head -1)" | tee -a "$OUT/val.log"
}
for i in $(seq 1 "$rounds"); do
  python3 -m navzoo.agents.robot_train --out "$run" --forward-only --robot-subgoal 3 --robot-progress geodesic \
    --wall-proximity 0.2 --n-envs 16 --num-cpus 15 --batch-size 512 --device cuda --threads 1 \
    --total-steps 20000000 --time-limit-s "$secs" --save-every 100000 --keep 1 ${TRAIN_EXTRA:-} \
    2>&1 | grep -v '^b3' >> "$OUT/train.log"
  tail -1 "$OUT/train.log" | cut -c1-200
  n=$(python3 -c "import json;print(json.load(open('$run/policy/config.json'))['training']['num_timesteps'])")
  python3 -c "from navzoo.agents.robot_train import convert_policy as c; c('$run/policy', '$snaps/$n', 'float16')"
  score "$snaps/$n" "$n"
done
cp "$run/metrics.jsonl" "$OUT/metrics.jsonl"; cp "$run"/checkpoints/*.pt "$run"/checkpoints/*.json "$OUT/"

#!/usr/bin/env bash
# Continue a CrowdNav circle-crossing training run in rounds, export a float16 snapshot after each
# round and score it on validation episodes (benchmark seed 1; the reported test uses seed 0).
# usage (device machine, wheels installed, $OUT set):
#   training/robot/continue_select.sh RUN_DIR ROUNDS SECONDS [SNAPSHOT_TO_SCORE_FIRST]
# TRAIN_EXTRA adds training options, e.g. TRAIN_EXTRA="--lr 5e-5 --target-kl 0.03 --init-from DIR".
set -uo pipefail
run=$1; rounds=$2; secs=$3; snaps=$OUT/snaps; mkdir -p "$snaps"
score() {  # score SNAPSHOT_DIR LABEL
  NAVZOO_TRANSFORMER_PPO_CROWDNAV_DIR=$1 python3 -m navzoo.cli benchmark --protocol crowdnav-circle \
    --methods transformer-ppo-crowdnav-diffdrive --episodes 100 --seed 1 --workers 16 --out /tmp/val_$2 \
    --no-progress --json 2>&1 | grep -v '^b3' | tail -1 >/dev/null
  echo "$2 $(python3 -m navzoo.cli report /tmp/val_$2 2>&1 | grep '^| transformer' | head -1)" | tee -a "$OUT/val.log"
}
snapshot() {
  n=$(python3 -c "import json;print(json.load(open('$run/policy/config.json'))['training']['num_timesteps'])")
  python3 -c "from navzoo.agents.robot_train import convert_policy as c; c('$run/policy', '$snaps/$n', 'float16')"
  score "$snaps/$n" "$n"
}
if [ -n "${4:-}" ]; then score "$4" start; fi
for i in $(seq 1 "$rounds"); do
  python3 -m navzoo.agents.robot_train --out "$run" --scenes navzoo/CircleCrossing-v0 --kinematics diff_drive \
    --forward-only --n-envs 48 --num-cpus 15 --batch-size 512 --device cuda --threads 1 --total-steps 20000000 \
    --time-limit-s "$secs" --save-every 200000 --keep 1 ${TRAIN_EXTRA:-} 2>&1 | grep -v '^b3' >> "$OUT/train.log"
  tail -1 "$OUT/train.log" | cut -c1-200
  snapshot
done
cp "$run/metrics.jsonl" "$OUT/metrics.jsonl"; cp "$run"/checkpoints/*.pt "$run"/checkpoints/*.json "$OUT/"

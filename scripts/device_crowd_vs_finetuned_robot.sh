#!/usr/bin/env bash
# Co-adaptation, round 2 of the behaviour-change study (docs/scaling.md): kinematic pedestrians learn (RLlib PPO)
# among the robot that was fine-tuned against the round-1 learned crowd (training/robot_vs_crowd/vs_learned_seed0,
# frozen), in the world of round 1 (CircleCrossing-v0, 4 pedestrians who walk on to new goals, see the robot and
# pay for contacts; the robot diff-drive as in its training). Then: does that robot still do well among a crowd
# that adapted to it?
#
#   device run, carry [".whl", ".raysite"]:  OUT=$OUT bash scripts/device_crowd_vs_finetuned_robot.sh
# Env: SEED (0), RUNNERS (14), ITERS (38), TRAIN_S (450), BATCH (4000), RUNS (/tmp/round2).
# Writes $OUT/round2_seed<SEED>.tgz (the run folder: config, metrics, final checkpoint) and the log.
set -u
OUT=${OUT:?set OUT}
source scripts/device_ray_env.sh
export NAVZOO_TRANSFORMER_PPO_CROWDNAV_DIR=$PWD/training/robot_vs_crowd/vs_learned_seed0/policy
PY=${PY:-python3}
SEED=${SEED:-0}; RUNNERS=${RUNNERS:-14}; ITERS=${ITERS:-38}; TRAIN_S=${TRAIN_S:-450}; BATCH=${BATCH:-4000}
RUNS=${RUNS:-/tmp/round2}; run=$RUNS/vs_finetuned_robot_seed$SEED
mkdir -p "$RUNS"
timeout -s INT "$TRAIN_S" $PY -m navzoo.rl.train --env navzoo/CircleCrossing-v0 --n-humans 4 \
  --set human_at_goal=new_goal --set humans_see_robots=true --set 'robot={kinematics: diff_drive}' \
  --humans learn --robots frozen --robot-policy transformer-ppo-crowdnav-diffdrive --n-robots 1 \
  --env-runners "$RUNNERS" --iterations "$ITERS" --batch-size "$BATCH" --minibatch-size 1000 --epochs 4 \
  --seed "$SEED" --checkpoint-every 5 --keep 1 --out "$run" > "$OUT/round2_seed$SEED.log" 2>&1
echo "$(grep -c '"iteration"' "$run/metrics.jsonl") iterations, last:"; tail -n 1 "$run/metrics.jsonl" | head -c 700; echo
tar czf "$OUT/round2_seed$SEED.tgz" -C "$RUNS" "$(basename "$run")"

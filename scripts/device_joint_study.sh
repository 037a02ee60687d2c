#!/usr/bin/env bash
# Pedestrians trained with robots present vs without (docs/scaling.md, "Behaviour-change study").
#
# Two RLlib runs side by side, one per condition, on navzoo/CircleCrossing-v0 with 4 learning
# kinematic pedestrians who walk on to new goals and pay for contacts (human_contact_penalty):
#   with_robots: 1 frozen DWA robot per episode;   no_robots: no robot.
# Each run trains for TRAIN_S seconds (SIGINT then saves a checkpoint), then both pedestrian policies
# are evaluated frozen around a DWA robot on the same EPISODES seeded episodes.
#
#   device run, carry [".whl", ".raysite"]:  SEED=0 bash scripts/device_joint_study.sh
#   here (2 cores, a smoke run):  RUNNERS=1 TRAIN_S=60 EPISODES=2 OUT=/tmp/js bash scripts/device_joint_study.sh
#
# Env: SEED (0), RUNNERS per run (7), ITERS (38 iterations of BATCH env steps), TRAIN_S (a time limit:
# 450 s), BATCH (4000), EPISODES (100; 0 = no evaluation here, evaluate with navzoo.rl.evaluate
# where the runs were copied), EVAL_SEED (10000).
# Writes $OUT/study_seed<SEED>.tgz (both run folders: config, metrics, final checkpoint), and
# $OUT/eval_<condition>_seed<SEED>.json.
set -u
OUT=${OUT:?set OUT}
source scripts/device_ray_env.sh
PY=${PY:-python3}
SEED=${SEED:-0}; RUNNERS=${RUNNERS:-7}; ITERS=${ITERS:-38}; TRAIN_S=${TRAIN_S:-450}; BATCH=${BATCH:-4000}
EPISODES=${EPISODES:-100}; EVAL_SEED=${EVAL_SEED:-10000}
RUNS=${RUNS:-/tmp/joint_study}
ENVF="--env navzoo/CircleCrossing-v0 --n-humans 4 --set human_at_goal=new_goal --set humans_see_robots=true"
TRAIN="--humans learn --robots frozen --robot-policy dwa --env-runners $RUNNERS --iterations $ITERS
  --batch-size $BATCH --minibatch-size 1000 --epochs 4 --seed $SEED --checkpoint-every 5 --keep 1"
mkdir -p "$(dirname "$RUNS")"
declare -A NR=([with_robots]=1 [no_robots]=0)
for c in with_robots no_robots; do
  timeout -s INT "$TRAIN_S" $PY -m navzoo.rl.train $ENVF $TRAIN --n-robots "${NR[$c]}" \
    --out "$RUNS/${c}_seed$SEED" > "$RUNS.${c}_seed$SEED.log" 2>&1 &
done
wait
for c in with_robots no_robots; do
  echo "$c: $(grep -c '"iteration"' "$RUNS/${c}_seed$SEED/metrics.jsonl") iterations, last:"
  tail -n 2 "$RUNS/${c}_seed$SEED/metrics.jsonl" | head -c 600; echo
done
for c in with_robots no_robots; do
  [ "$EPISODES" -gt 0 ] || continue
  $PY -m navzoo.rl.evaluate $ENVF --n-robots 1 --robot-policy dwa --humans frozen \
    --human-policy "rllib:$RUNS/${c}_seed$SEED" --episodes "$EPISODES" --seed "$EVAL_SEED" \
    > "$OUT/eval_${c}_seed$SEED.json" 2> "$RUNS.eval_$c.log" &
done
wait
[ "$EPISODES" -gt 0 ] && for c in with_robots no_robots; do python3 -c "import json,sys; print('$c', json.load(open(sys.argv[1]))['mean'])" "$OUT/eval_${c}_seed$SEED.json"; done
tar czf "$OUT/study_seed$SEED.tgz" -C "$(dirname "$RUNS")" "$(basename "$RUNS")"
ls -la "$OUT"

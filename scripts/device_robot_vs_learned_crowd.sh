#!/usr/bin/env bash
# The robot side of the behaviour-change study (docs/scaling.md): the CrowdNav transformer policy fine-tuned
# against pedestrians that learned among robots (a frozen RLlib crowd) vs against the ORCA crowd, side by side,
# the same settings otherwise (navzoo/CircleCrossing-v0, 4 pedestrians who walk on to new goals and see the
# robot, diff-drive robot, forward-only, the shipped policy's lr / target KL / minibatch).
#
#   device run, carry [".whl", ".raysite", "runs/joint_study/joint_study/with_robots_seed0"]:
#     OUT=$OUT bash scripts/device_robot_vs_learned_crowd.sh
#   here (2 cores, a smoke run): ENVS=2 CPUS=0 BATCH=64 TRAIN_S=30 DEVICE=cpu OUT=/tmp/rvc bash scripts/device_robot_vs_learned_crowd.sh
#
# Env: TRAIN_S (520 s per run, both at once), ENVS (16 copies per run), CPUS (7 worker processes per run),
# BATCH (512), DEVICE (cuda), SEED (0), CROWD (the learned crowd's run folder), RUNS (/tmp/robot_vs_crowd).
# Writes $OUT/robot_vs_crowd.tgz (each run's policy/ and metrics.jsonl), $OUT/<run>_step_*.pt/.json (its last
# checkpoint) and $OUT/<run>.log.
set -u
OUT=${OUT:?set OUT}
source scripts/device_ray_env.sh
PY=${PY:-python3}
TRAIN_S=${TRAIN_S:-520}; ENVS=${ENVS:-16}; CPUS=${CPUS:-7}; BATCH=${BATCH:-512}; DEVICE=${DEVICE:-cuda}
CROWD=${CROWD:-runs/joint_study/joint_study/with_robots_seed0}; RUNS=${RUNS:-/tmp/robot_vs_crowd}
COMMON="--scenes navzoo/CircleCrossing-v0 --kinematics diff_drive --forward-only
  --init-from policies/transformer_ppo_crowdnav --set human_at_goal=new_goal --set humans_see_robots=true
  --set n_humans=4 --n-envs $ENVS --num-cpus $CPUS --lr 5e-5 --target-kl 0.03 --batch-size $BATCH --threads 1
  --device $DEVICE --total-steps 20000000 --time-limit-s $TRAIN_S --save-every 50000 --keep 1 --seed ${SEED:-0}"
mkdir -p "$RUNS"
$PY -m navzoo.agents.robot_train $COMMON --crowd-policy "rllib:$CROWD" --out "$RUNS/vs_learned" \
  2>&1 | grep -v '^b3' > "$OUT/vs_learned.log" &
$PY -m navzoo.agents.robot_train $COMMON --set crowd_model=orca_rvo2 --out "$RUNS/vs_orca" \
  2>&1 | grep -v '^b3' > "$OUT/vs_orca.log" &
wait
for r in vs_learned vs_orca; do echo "$r: $(tail -n 1 "$OUT/$r.log" | head -c 400)"; done
tar czf "$OUT/robot_vs_crowd.tgz" -C "$RUNS" vs_learned/policy vs_learned/metrics.jsonl vs_orca/policy vs_orca/metrics.jsonl
for r in vs_learned vs_orca; do  # the last checkpoint (resume: put both files in $RUNS/$r/checkpoints/)
  for f in "$RUNS/$r"/checkpoints/step_*; do cp "$f" "$OUT/${r}_$(basename "$f")"; done
done

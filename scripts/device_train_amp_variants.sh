#!/usr/bin/env bash
# Scene training of the AMP pedestrians (python -m navzoo.rl.amp_joint train, from the shipped policy), several
# variants at once in one device call: each variant gets its own learner (on the GPU) and WORKERS processes, all
# variants share the machine's cores. For a dose-response of one option (e.g. --anchor-coef) measured under the
# same conditions, instead of one variant per call.
#
#   device run, carry [".whl"], after `bash scripts/device_slim_tree.sh out training/amp policies/amp_pedestrian
#   policies/trajectory_diffusion`:
#     VARIANTS="a01:--anchor-coef 0.1;a1:--anchor-coef 1.0" SCENES=<16 scenes> COMMON_ARGS="--seed 37 ..." \
#       bash scripts/device_train_amp_variants.sh
#
# VARIANTS: NAME:EXTRA_ARGS items separated by ';'. COMMON_ARGS go to every variant. WORKERS (default 16) processes
# per variant, each with N_ENVS (1) copies x N_HUMANS (6) pedestrians of one scene of SCENES in turn; ROLLOUT (32)
# steps per rollout, MINIBATCH (1536); LIMIT_S (380) seconds of training, TRAIN_S (430) the hard stop;
# SNAPSHOT_EVERY (40) iterations between exported policies. Returns $OUT/NAME.tgz per variant (its newest KEEP_SNAPSHOTS
# (2) snapshots, never the start, which is the shipped policy; its last policy as policy/, metrics.jsonl, summary.json;
# in 15 MB parts NAME.tgz.part-* if larger) and $OUT/NAME.log. On the H200 host two variants x 16 workers ran 174
# iterations of 3,072 samples each in 380 s (2026-12-05).
# DEVICE (cuda) and PY (python3) can be changed for a local try. No checkpoint comes back (the policies are what
# the evaluation needs).
set -u
python3 -m pip install -q --no-index --no-deps --no-compile --target /tmp/site .whl/*.whl 2>&1 | grep -v "already exists" | tail -2
export PYTHONPATH=/tmp/site:$PWD
nproc; nvidia-smi --query-gpu=name,memory.total --format=csv,noheader
python3 -c "import navzoo, torch, pybullet; print('navzoo ok, cuda', torch.cuda.is_available(), torch.__version__)"
IFS=';' read -ra items <<< "${VARIANTS:?set VARIANTS}"
names=()
for item in "${items[@]}"; do
  name=${item%%:*}; extra=${item#*:}
  [ -n "$name" ] && [ "$name" != "$item" ] || { echo "VARIANTS item '$item' is not NAME:ARGS"; exit 1; }
  names+=("$name")
  rm -rf "/tmp/v_$name"
  # shellcheck disable=SC2086
  timeout "${TRAIN_S:-430}" "${PY:-python3}" -m navzoo.rl.amp_joint train --out "/tmp/v_$name" --workers "${WORKERS:-16}" \
    --n-envs "${N_ENVS:-1}" --n-humans "${N_HUMANS:-6}" --n-robots 0 --scenes "${SCENES:?set SCENES}" --device "${DEVICE:-cuda}" \
    --rollout-steps "${ROLLOUT:-32}" --minibatch-size "${MINIBATCH:-1536}" --time-limit-s "${LIMIT_S:-380}" \
    --steps 500000000 --ckpt-every 20 --keep-checkpoints 1 --snapshot-every "${SNAPSHOT_EVERY:-40}" \
    ${COMMON_ARGS:-} $extra > "$OUT/$name.log" 2>&1 &
done
wait
for name in "${names[@]}"; do
  d=/tmp/v_$name
  echo "$name: $(tail -1 "$OUT/$name.log" | cut -c1-300)"
  first=$(ls "$d/snapshots" 2>/dev/null | head -1)
  [ -n "$first" ] && rm -rf "$d/snapshots/$first"  # the start: the shipped policy
  # only the newest KEEP_SNAPSHOTS snapshots come back (2.7 MB each)
  ls "$d/snapshots" 2>/dev/null | head -n -"${KEEP_SNAPSHOTS:-2}" | while read -r old; do rm -rf "$d/snapshots/$old"; done
  (cd "$d" && tar czf "/tmp/$name.tgz" snapshots policy metrics.jsonl summary.json 2>/dev/null)
  # the device tool returns files of at most 16 MiB: larger archives come back in parts (cat NAME.tgz.part-* > NAME.tgz)
  if [ "$(stat -c %s "/tmp/$name.tgz")" -gt 15000000 ]; then split -b 15m "/tmp/$name.tgz" "$OUT/$name.tgz.part-"
  else cp "/tmp/$name.tgz" "$OUT/"; fi
done
ls -la "$OUT"
true

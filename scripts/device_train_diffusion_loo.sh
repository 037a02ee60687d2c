#!/usr/bin/env bash
# Leave-one-scene-out diffusion models: five folds trained at once on the accelerator machine's GPU,
# within one device call; the forecasts are scored afterwards on any machine with
# `navzoo eval forecast --split loo --loo-models DIR` (CPU is enough).
#
#   once: mkdir -p .data && cp -r ../shared/data/trajectories/eth_ucy .data/ && echo /.data/ >> .git/info/exclude
#   device run, carry [".whl", ".data"]:  LIMIT_S=420 bash scripts/device_train_diffusion_loo.sh
#   back here: mkdir -p training/diffusion_loo_resampled && cat $FILES_AT/loo.tgz.part-* | tar xz -C training/diffusion_loo_resampled
#
# Fold S trains on the train/ files of the four other scenes and picks its weights by the validation loss
# on their val/ files (navzoo train diffusion --split loo --test-scene S), so nothing of scene S is seen.
# ETH/UCY only, no map input (--map-cells 0), the shipped model's architecture otherwise; batch 512 on the
# GPU, LIMIT_S seconds each, all five folds in parallel (one process each). Returns the exported EMA
# models (models/<scene>/), each fold's metrics.jsonl and training log, in one archive.
set -u
python3 -m pip install -q --no-index --no-deps --no-compile --target /tmp/site .whl/*.whl 2>&1 | grep -v "already exists" | tail -2
export PYTHONPATH=/tmp/site:$PWD
nproc; nvidia-smi --query-gpu=name,memory.total --format=csv,noheader
[ -d .data/eth_ucy ] || { mkdir -p .data && tar xzf .eth_ucy.tgz -C .data; }
SCENES=${SCENES:-biwi_eth crowds_zara01 crowds_zara03 students001 uni_examples}
B=/tmp/loo_bundle && rm -rf $B && mkdir -p $B/models $B/folds
for S in $SCENES; do
  OMP_NUM_THREADS=3 python3 -m navzoo.agents.diffusion.train --out /tmp/loo_run/$S --data .data/eth_ucy --split loo \
    --test-scene $S --device cuda --batch-size "${BATCH:-512}" --steps "${STEPS:-60000}" --time-limit-s "${LIMIT_S:-420}" \
    --eval-every 500 --ckpt-every 2000 --map-cells 0 --seed "${SEED:-0}" --export $B/models/$S ${TRAIN_ARGS:-} --json \
    > $B/folds/train_$S.log 2>&1 &
done
wait
for S in $SCENES; do
  echo "$S: $(tail -1 $B/folds/train_$S.log | cut -c1-200)"
  mkdir -p $B/folds/$S && cp /tmp/loo_run/$S/metrics.jsonl /tmp/loo_run/$S/checkpoint/meta.json $B/folds/$S/ 2>/dev/null
  cp /tmp/loo_run/$S/checkpoint/best.json $B/folds/$S/ 2>/dev/null
done
# $OUT holds at most 8 files: everything goes back in one archive (split at 15 MiB).
tar czf - -C $B . | split -b 15m - "$OUT/loo.tgz.part-"
ls -la "$OUT"

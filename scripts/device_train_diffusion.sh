#!/usr/bin/env bash
# Train (or resume) the trajectory diffusion model on the accelerator machine, within one device call.
#
#   once: mkdir -p .data && cp -r ../shared/data/trajectories/eth_ucy .data/ && echo /.data/ >> .git/info/exclude
#   device run, carry [".whl", ".data"]:  LIMIT_S=420 bash scripts/device_train_diffusion.sh
#   (or, when the checkout is near the device's 64 MiB limit, carry a 1.2 MB archive instead of .data:
#    tar czf .eth_ucy.tgz -C .data eth_ucy && echo /.eth_ucy.tgz >> .git/info/exclude; carry [".whl", ".eth_ucy.tgz"])
#
# The map-aware model: SIM_SECONDS=60 CKPT=training/diffusion_map TRAIN_ARGS="--map-cells 32" first builds
# the simulated-crowd windows (python -m navzoo.forecast.sim_data, one process per core, every library
# scene but the 8 evaluation scenes, social force and ORCA, SIM_SECONDS each) and trains on them too.
#
# Resumes from training/diffusion (the checkpoint split in 15 MiB parts) when it holds one, trains on
# the GPU for LIMIT_S seconds (batch 512, the ETH/UCY val split), exports the EMA model, evaluates it
# with `navzoo eval forecast` against constant velocity and social force, and returns the logs and
# bundle.tgz.part-* in $OUT (cat them | tar xz: checkpoint/, metrics.jsonl, trajectory_diffusion/,
# forecast_val.json).
set -u
rm -rf /tmp/bundle /tmp/bundle_export
python3 -m pip install -q --no-index --no-deps --no-compile --target /tmp/site .whl/*.whl 2>&1 | grep -v "already exists" | tail -2
export PYTHONPATH=/tmp/site:$PWD
nproc; nvidia-smi --query-gpu=name,memory.total --format=csv,noheader
[ -d .data/eth_ucy ] || { mkdir -p .data && tar xzf .eth_ucy.tgz -C .data; }
CKPT=${CKPT:-training/diffusion}
RUN=/tmp/diffusion_$(basename "$CKPT")
mkdir -p $RUN/checkpoint
if ls $CKPT/state.pt.part-* > /dev/null 2>&1 && [ ! -f $RUN/checkpoint/state.pt ]; then
  cat $CKPT/state.pt.part-* > $RUN/checkpoint/state.pt
  cp $CKPT/meta.json $RUN/checkpoint/
  cp $CKPT/best.pt $CKPT/best.json $RUN/checkpoint/ 2>/dev/null
  cp $CKPT/metrics.jsonl $RUN/ 2>/dev/null
fi
[ -f $RUN/checkpoint/meta.json ] && echo "resuming from step $(python3 -c "import json;print(json.load(open('$RUN/checkpoint/meta.json'))['step'])")"
SIM_ARGS=""
if [ -n "${SIM_SECONDS:-}" ]; then
  SIM=/tmp/sim_windows_${SIM_SECONDS}.npz
  [ -f $SIM ] || timeout "${SIM_LIMIT_S:-240}" python3 -m navzoo.forecast.sim_data --out $SIM --crowds sfm,orca \
    --seconds "$SIM_SECONDS" --seed 0 --map-cells 32 --workers "$(nproc)" > "$OUT/sim_data.log" 2>&1
  echo "sim windows rc=$? $(tail -1 "$OUT/sim_data.log" | cut -c1-300)"
  SIM_ARGS="--sim-data $SIM"
fi
python3 -m navzoo.agents.diffusion.train --out $RUN --data .data/eth_ucy --device cuda --batch-size "${BATCH:-512}" \
  --steps "${STEPS:-60000}" --time-limit-s "${LIMIT_S:-420}" --eval-every 1000 --ckpt-every 2000 \
  --export /tmp/bundle_export $SIM_ARGS ${TRAIN_ARGS:-} --json > "$OUT/train.log" 2>&1
echo "train rc=$?"
tail -4 "$OUT/train.log"
# $OUT holds at most 8 files: everything goes back in one archive (split at 15 MiB), made at the end.
B=/tmp/bundle && mkdir -p $B/checkpoint
cp $RUN/metrics.jsonl $B/ && cp $RUN/checkpoint/meta.json $RUN/checkpoint/state.pt $B/checkpoint/
cp $RUN/checkpoint/best.pt $RUN/checkpoint/best.json $B/checkpoint/ 2>/dev/null
NAVZOO_DIFFUSION_MODEL=/tmp/bundle_export timeout "${EVAL_S:-150}" python3 -c "
from navzoo.forecast.evaluate import main, register_forecaster, forecaster_names
from navzoo.agents.diffusion.forecaster import DiffusionForecaster
register_forecaster('diffusion', lambda ctx: DiffusionForecaster(seed=ctx.seed, device='cuda'), overwrite=True)
raise SystemExit(main(['--data', '.data/eth_ucy', '--split', 'val', '--samples', '20', '--models',
                       '${MODELS:-constant_velocity,sfm,diffusion}', '--out', '$B/forecast_val.json']))
" > "$OUT/forecast.log" 2>&1
echo "eval rc=$?"
tail -12 "$OUT/forecast.log"
cp -r /tmp/bundle_export $B/trajectory_diffusion
tar czf - -C $B . | split -b 15m - "$OUT/bundle.tgz.part-"
ls -la "$OUT"

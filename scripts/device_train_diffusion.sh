#!/usr/bin/env bash
# Train (or resume) the trajectory diffusion model on the accelerator machine, within one device call.
#
#   once: mkdir -p .data && cp -r ../shared/data/trajectories/eth_ucy .data/ && echo /.data/ >> .git/info/exclude
#   device run, carry [".whl", ".data"]:  LIMIT_S=420 bash scripts/device_train_diffusion.sh
#
# Resumes from training/diffusion (the checkpoint split in 15 MiB parts) when it holds one, trains on
# the GPU for LIMIT_S seconds (batch 512, the ETH/UCY val split), exports the EMA model to
# $OUT/trajectory_diffusion, evaluates it with `navzoo eval forecast` against constant velocity and
# social force, and returns the checkpoint parts, metrics.jsonl and the logs in $OUT.
set -u
python3 -m pip install -q --no-index --no-deps --no-compile --target /tmp/site .whl/*.whl 2>&1 | grep -v "already exists" | tail -2
export PYTHONPATH=/tmp/site:$PWD
nproc; nvidia-smi --query-gpu=name,memory.total --format=csv,noheader
RUN=/tmp/diffusion
mkdir -p $RUN/checkpoint
if ls training/diffusion/state.pt.part-* > /dev/null 2>&1; then
  cat training/diffusion/state.pt.part-* > $RUN/checkpoint/state.pt
  cp training/diffusion/meta.json $RUN/checkpoint/
  cp training/diffusion/best.pt training/diffusion/best.json $RUN/checkpoint/ 2>/dev/null
  cp training/diffusion/metrics.jsonl $RUN/ 2>/dev/null
  echo "resuming from step $(python3 -c "import json;print(json.load(open('$RUN/checkpoint/meta.json'))['step'])")"
fi
python3 -m navzoo.agents.diffusion.train --out $RUN --data .data/eth_ucy --device cuda --batch-size "${BATCH:-512}" \
  --steps "${STEPS:-60000}" --time-limit-s "${LIMIT_S:-420}" --eval-every 1000 --ckpt-every 2000 \
  --export "$OUT/trajectory_diffusion" ${TRAIN_ARGS:-} --json > "$OUT/train.log" 2>&1
echo "train rc=$?"
tail -4 "$OUT/train.log"
cp $RUN/metrics.jsonl "$OUT/"
cp $RUN/checkpoint/meta.json "$OUT/"
cp $RUN/checkpoint/best.pt $RUN/checkpoint/best.json "$OUT/" 2>/dev/null
split -b 15m $RUN/checkpoint/state.pt "$OUT/state.pt.part-"
NAVZOO_DIFFUSION_MODEL="$OUT/trajectory_diffusion" timeout "${EVAL_S:-150}" python3 -c "
from navzoo.forecast.evaluate import main, register_forecaster, forecaster_names
from navzoo.agents.diffusion.forecaster import DiffusionForecaster
register_forecaster('diffusion', lambda ctx: DiffusionForecaster(seed=ctx.seed, device='cuda'), overwrite=True)
raise SystemExit(main(['--data', '.data/eth_ucy', '--split', 'val', '--samples', '20', '--models',
                       '${MODELS:-constant_velocity,sfm,diffusion}', '--out', '$OUT/forecast_val.json']))
" > "$OUT/forecast.log" 2>&1
echo "eval rc=$?"
tail -12 "$OUT/forecast.log"
ls -la "$OUT"

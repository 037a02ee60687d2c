#!/usr/bin/env bash
# RLlib throughput against the number of env runner processes, on the accelerator machine
# (16 CPU cores). Ray is not installed there and its wheel (79 MB) is over the device's transfer
# limit, so it travels as an extracted, xz-compressed site folder (see docs/scaling.md, "On the
# device machine"):
#
#   bash scripts/device_rllib_stage.sh            # here: builds .raysite/ (ray + its missing needs)
#   device run, carry [".whl", ".raysite"]:  bash scripts/device_rllib_throughput.sh
#
# Env: RUNNERS (default "1 2 4 8 16"), ITERS (default 4; the first is warm-up), BATCH (env steps per
# iteration, default 3200), EXTRA (more trainer flags). Writes $OUT/rllib_<n>.jsonl (the trainer's
# metrics lines), $OUT/rllib_train.log (all trainer output), $OUT/rllib_throughput.log and
# $OUT/rllib_summary.json.
set -u
if [ ! -d /tmp/site/ray ]; then
  python3 -m pip install -q --no-index --no-deps --no-compile --target /tmp/site .whl/*.whl .raysite/deps/*.whl \
    2>&1 | grep -v "already exists" | tail -2
  tar xJf .raysite/ray_site.tar.xz -C /tmp/site || exit 1
fi
export PYTHONPATH=/tmp/site:$PWD PYTHONUNBUFFERED=1 RAY_DISABLE_USAGE_STATS=1
nproc; lscpu | grep "Model name"
python3 -c "import ray, ray.rllib, torch; print('ray', ray.__version__, 'torch', torch.__version__)" || exit 1
ITERS=${ITERS:-4}
BATCH=${BATCH:-3200}
for n in ${RUNNERS:-1 2 4 8 16}; do
  start=$(date +%s)
  python3 -m navzoo.rl.train --env-runners "$n" --iterations "$ITERS" --batch-size "$BATCH" \
    --minibatch-size 800 --epochs 2 --checkpoint-every 1000 --out "/tmp/rllib_scale_$n" --fresh ${EXTRA:-} \
    >> "$OUT/rllib_train.log" 2>&1
  echo "runners=$n rc=$? wall=$(( $(date +%s) - start ))s" | tee -a "$OUT/rllib_throughput.log"
  cp "/tmp/rllib_scale_$n/metrics.jsonl" "$OUT/rllib_$n.jsonl" 2>/dev/null
  ray stop --force > /dev/null 2>&1 || python3 -m ray.scripts.scripts stop --force > /dev/null 2>&1
done
python3 - "$OUT" <<'EOF' | tee "$OUT/rllib_summary.json"
import json, pathlib, statistics, sys
out = pathlib.Path(sys.argv[1]); rows = {}
for f in sorted(out.glob("rllib_*.jsonl")):
    its = [json.loads(l) for l in f.read_text().splitlines() if l.startswith("{")]
    its = [r for r in its if "env_steps_per_s" in r]
    if len(its) < 2:
        continue
    meas = its[1:]  # iteration 1 is warm-up
    rows[f.stem.split("_")[1]] = {
        "iterations_measured": len(meas),
        "env_steps_per_s_median": statistics.median(r["env_steps_per_s"] for r in meas),
        "env_steps_per_s_overall": sum(r["env_steps_sampled"] for r in meas) / sum(r["iteration_s"] for r in meas),
        "iteration_s": [round(r["iteration_s"], 2) for r in meas],
        "env_step_ms": [(r.get("navzoo") or {}).get("env_step_ms") for r in meas],
    }
print(json.dumps(rows, indent=1))
EOF

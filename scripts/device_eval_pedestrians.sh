#!/usr/bin/env bash
# Run `navzoo eval pedestrians` on the accelerator machine (16 CPU cores: one process per scene).
#
#   device run, carry [".whl"]:  bash scripts/device_eval_pedestrians.sh
#
# Writes $OUT/ped_eval.json (the full evaluation, throughput on this machine included) and the log.
set -u
python3 -m pip install -q --no-index --no-deps --no-compile --target /tmp/site .whl/*.whl 2>&1 | grep -v "already exists" | tail -2
export PYTHONPATH=/tmp/site:$PWD
nproc; nvidia-smi --query-gpu=name --format=csv,noheader; lscpu | grep "Model name"
python3 -m navzoo.cli eval pedestrians --workers "${WORKERS:-8}" --json --out "$OUT/ped_eval.json" ${EXTRA:-} \
  > "$OUT/ped_eval.log" 2>&1
echo "eval rc=$?"
tail -c 1500 "$OUT/ped_eval.log"

#!/usr/bin/env bash
# Run scripts/amp_target_ablation.py (the following protocol) on the accelerator machine's 16 cores.
#
#   device run, carry [".whl"] (and the result file to resume, if a call was cut short):
#     NAME=sight bash scripts/device_following_ablation.sh --crowd diffusion --configs "sight:0.1:0.1:4:2.0:0" --seeds 0,1,2,3 --seconds 200
#
# Writes $OUT/$NAME.jsonl (one row per finished scene run, so a call cut short keeps what it finished: copy the
# file back to RESUME=path and run again to go on) and $OUT/$NAME.log.
set -u
python3 -m pip install -q --no-index --no-deps --no-compile --target /tmp/site .whl/*.whl 2>&1 | grep -v "already exists" | tail -2
export PYTHONPATH=/tmp/site:$PWD
nproc; lscpu | grep "Model name"
NAME=${NAME:-ablation}
if [ -n "${RESUME:-}" ]; then cp "$RESUME" "$OUT/$NAME.jsonl"; fi
python3 scripts/amp_target_ablation.py "$@" --workers "${WORKERS:-16}" --out "$OUT/$NAME.jsonl" > "$OUT/$NAME.log" 2>&1
echo "ablation rc=$?"
tail -c 2500 "$OUT/$NAME.log"

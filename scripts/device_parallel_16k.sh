#!/usr/bin/env bash
# Continue the parallel-training study at the paper's size (16,000 simulator steps per run) on the device
# machine (docs/training.md, "The paper's size"). Finished rows are in training/robot/parallel_device_16k.jsonl
# and are skipped (--resume); a run cut off by the time limit continues from its checkpointed folder.
#
#   device run, carry [".whl", "runs/parallel16k"]:  LIMIT_S=560 bash scripts/device_parallel_16k.sh
#
# Afterwards, here: cp $FILES/parallel_device_16k.jsonl training/robot/ and, when a run was cut off,
# rm -rf runs/parallel16k && mkdir -p runs && tar xzf $FILES/parallel16k.tgz -C runs   (carry it next time).
# ROBOTS / BATCHES choose the configurations (default: all ten, largest first). SEED=N (default 0) trains
# another seed: its rows go to training/robot/parallel_device_16k_seedN.jsonl, its runs to runs/parallel16k_seedN
# (carry that instead; the archive is $OUT/parallel16k_seedN.tgz).
set -u
[ -d /tmp/site/pybullet ] || python3 -m pip install -q --no-index --no-deps --no-compile --target /tmp/site \
  .whl/*.whl 2>&1 | grep -v "already exists" | tail -2
export PYTHONPATH=/tmp/site:$PWD PYTHONUNBUFFERED=1 OMP_NUM_THREADS=1
seed=${SEED:-0}; sfx=""; [ "$seed" = 0 ] || sfx="_seed$seed"
runs=runs/parallel16k$sfx
rows=$OUT/parallel_device_16k$sfx.jsonl
# The rows of an earlier call on the same (still warm) machine are kept in runs/, which is not carried, so a
# second call skips what the first finished even before they are copied back here.
kept=runs/parallel_device_16k$sfx.jsonl
if [ -f "$kept" ]; then cp "$kept" "$rows"
elif [ -f "training/robot/parallel_device_16k$sfx.jsonl" ]; then cp "training/robot/parallel_device_16k$sfx.jsonl" "$rows"; fi
# SIGINT = Ctrl-C: the running configuration saves a checkpoint, the study stops (exit 130)
timeout -s INT "${LIMIT_S:-560}" python3 -m navzoo.cli scaling parallel --robots "${ROBOTS:-16,8,4,2,1}" \
  --batch-sizes "${BATCHES:-512,64}" --sim-steps 16000 --scene navzoo/CircleCrossing-v0 --device cuda --threads 1 \
  --seed "$seed" --out "$rows" --resume --runs-dir "$runs" 2>&1 | grep -v '^b3' | grep -v '^{"timesteps"' | cut -c1-400
mkdir -p runs && [ -f "$rows" ] && cp "$rows" "$kept"
echo "rows: $(wc -l < "$rows")"
# keep only the unfinished runs' folders (a finished run's row is written; its 11 MB checkpoint is not needed)
RUNS=$runs python3 - <<'PY'
import os, re, shutil
from pathlib import Path
for d in Path(os.environ["RUNS"]).glob("*_r*_b*"):
    total = 16000 * int(re.search(r"_r(\d+)_b", d.name).group(1))
    done = [int(p.stem.split("_")[1]) for p in (d / "checkpoints").glob("step_*.pt")]
    if done and max(done) >= total:
        shutil.rmtree(d)
PY
[ -d "$runs" ] && [ -n "$(ls "$runs")" ] && tar czf "$OUT/parallel16k$sfx.tgz" -C runs "parallel16k$sfx" \
  && du -h "$OUT/parallel16k$sfx.tgz"

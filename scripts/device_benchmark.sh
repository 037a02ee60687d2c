#!/usr/bin/env bash
# Continue the full benchmark (docs/benchmarks.md, "Full benchmark") on the accelerator machine.
# The run is CPU-bound: one worker per core. Resumes from the committed benchmarks/full_sfm.
#
#   device run, carry [".whl"]:  WORKERS=62 LIMIT_S=520 bash scripts/device_benchmark.sh
#
# Stops itself (SIGTERM: the runner records the session) after LIMIT_S seconds and writes to $OUT:
# episodes.jsonl, run.json (whole run so far), traj.tgz (this session's saved trajectories), bench.log.
set -u
python3 -m pip install -q --no-index --no-deps --no-compile --target /tmp/site .whl/*.whl 2>&1 | grep -v "already exists" | tail -2
export PYTHONPATH=/tmp/site:$PWD
nproc; lscpu | grep "Model name"
RUN=runs/benchmark_full
mkdir -p "$RUN"
# A warm machine keeps runs/ between calls: go on from there when it holds more than the commit.
if [ "$(wc -l < "$RUN/episodes.jsonl" 2>/dev/null || echo 0)" -le "$(gunzip -c benchmarks/full_sfm/episodes.jsonl.gz | wc -l)" ]; then
  gunzip -c benchmarks/full_sfm/episodes.jsonl.gz > "$RUN/episodes.jsonl"
  cp benchmarks/full_sfm/run.json "$RUN/"
fi
echo "episodes before: $(wc -l < "$RUN/episodes.jsonl")"
timeout -s TERM "${LIMIT_S:-520}" python3 -m navzoo.cli benchmark --scenes "${SCENES:-all}" --no-progress \
  --methods orca,dwa,sfm,pure-pursuit,stop,random --crowd sfm --density 0.05,0.15,0.3 --max-humans 40 \
  --episodes 20 --seed 0 --save-trajectories 1 --workers "${WORKERS:-15}" --out "$RUN" > "$OUT/bench.log" 2>&1
echo "benchmark rc=$?"
echo "episodes after: $(wc -l < "$RUN/episodes.jsonl")"
# $OUT files come back up to 16 MiB each, 64 MiB together: the episodes gzipped, the trajectories
# (about 12 KB per saved episode) only with TRAJ=1, split.
gzip -c "$RUN/episodes.jsonl" > "$OUT/episodes.jsonl.gz"
cp "$RUN/run.json" "$OUT/"
[ "${TRAJ:-0}" = 1 ] && tar czf - -C "$RUN" trajectories | split -b 15M - "$OUT/traj.tgz.part-"
# With REPORT=1, also the report (its trajectory plots need the trajectories, which stay here).
[ "${REPORT:-0}" = 1 ] && timeout 90 python3 -m navzoo.cli report "$RUN" > "$OUT/report.log" 2>&1 \
  && tar czf "$OUT/report.tgz" -C "$RUN" report
tail -c 1500 "$OUT/bench.log" | tr '\r' '\n' | tail -8

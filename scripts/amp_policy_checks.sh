#!/usr/bin/env bash
# Quick checks of exported AMP policies on this machine: clip tracking (78 clips) and the path-task
# check (16 bodies, 20 s, stages 1 and 3), one JSON line per policy on stdout.
#
#   bash scripts/amp_policy_checks.sh NAME:POLICY_DIR[:FLAG] ...
#   bash scripts/amp_policy_checks.sh 4260:policies/amp_pedestrian 4260-symmetric:policies/amp_pedestrian:--symmetric
#
# FLAG is passed to both commands (e.g. --symmetric, or --steering-trim=0). About 1 min per policy on a
# 2-core VM.
set -euo pipefail
PY=${PY:-python}
for spec in "$@"; do
  IFS=: read -r name dir flag <<< "$spec"
  t=$($PY -m navzoo.agents.amp.tracking "$dir" ${flag:-} --json)
  e1=$($PY -m navzoo.agents.amp.evaluate "$dir" ${flag:-} --stage 1 --seconds 20 --json)
  e3=$($PY -m navzoo.agents.amp.evaluate "$dir" ${flag:-} --stage 3 --seconds 20 --json)
  echo "{\"policy\": \"$name\", \"tracking\": $t, \"path_stage1\": $e1, \"path_stage3\": $e3}"
done

#!/usr/bin/env bash
# Throughput of AMP pedestrians learning with learning robots vs with frozen robots (same network, inference only),
# one after the other on this machine: 2 Lobby copies x 4 pedestrians x 1 robot, 240 s each.
# usage: bash training/amp_joint_robots/throughput_vm.sh OUT_DIR
set -euo pipefail
out=${1:-runs/amp_joint_robots_tp}
C="--env navzoo/Lobby-v0 --n-envs 2 --n-humans 4 --n-robots 1 --steps 10000000 --time-limit-s 240 --minibatch-size 128"
python -m navzoo.rl.amp_joint train $C --out "$out/learn" --robots learn --robot-init policies/transformer_ppo_crowdnav \
    --robot-forward-only 2>&1 | grep -v '^b3' | tail -1 > "$out/learn.summary.json"
python -m navzoo.rl.amp_joint train $C --out "$out/frozen" --robot-policy transformer-ppo-crowdnav-diffdrive \
    2>&1 | grep -v '^b3' | tail -1 > "$out/frozen.summary.json"

#!/usr/bin/env bash
# Imitation stage of the paper-scene policy on the device machine: ORCA demonstrations in the three
# training scenes from parallel processes, then the actor-critic fitted to them on the GPU (from the
# CrowdNav weights), then a validation benchmark (seed 1) of the result.
# usage: training/robot/imitation_device.sh DEMO_DIR BC_DIR [LEARNER]
# - without LEARNER (behaviour cloning): 5 blocks of expert episodes (seeds 1000..5000), 15 epochs;
# - with LEARNER (a DAgger round): 3 expert blocks (seeds 1000..3000) and 2 blocks in which LEARNER
#   drives with probability 1 - BETA (default 0.5) and ORCA labels every step (seeds SEED_BASE and
#   2 SEED_BASE, default 100), 12 epochs.
# Options (environment):
#   EXPERT_BLOCKS / LEARNER_BLOCKS  number of blocks of each kind (defaults above); a block is one
#                                   process per scene;
#   SPECS / LSPECS                  "scene:episodes ..." of an expert / learner block
#                                   (default "station:8 grocery:10 home:14" / "station:4 grocery:6 home:8");
#   EXPERT_SEED                     seed step of the expert blocks (default 1000): later rounds on the same
#                                   machine add new episodes instead of rewriting the same shards;
#   SCAN_RAYS                       record a range scan with this many rays (NavConfig.scan_rays; default 0);
#   INIT                            the policy the fit starts from (default policies/transformer_ppo_crowdnav;
#                                   e.g. the LEARNER, to refit a DAgger round from the previous round's weights);
#   BC_EPOCHS, COLLECT_TIMEOUT (s), VAL=0 (skip the validation benchmark), VAL_TIMEOUT (s).
# Every shard in DEMO_DIR is used by the fit, those of earlier rounds on the same machine included.
set -uo pipefail
demos=$1; bc=$2; learner=${3:-}; mkdir -p "$demos" "$OUT"
export OMP_NUM_THREADS=1 MKL_NUM_THREADS=1
eblocks=5; lblocks=0; epochs=15
if [ -n "$learner" ]; then eblocks=3; lblocks=2; epochs=12; fi
eblocks=${EXPERT_BLOCKS:-$eblocks}; lblocks=${LEARNER_BLOCKS:-$lblocks}; eseed=${EXPERT_SEED:-1000}
specs=${SPECS:-"station:8 grocery:10 home:14"}; lspecs=${LSPECS:-"station:4 grocery:6 home:8"}
if [ "$lblocks" -gt 0 ] && [ -z "$learner" ]; then echo "LEARNER_BLOCKS > 0 needs a LEARNER" >&2; exit 2; fi
pids=()
for k in $(seq 1 "$eblocks"); do
  for spec in $specs; do
    timeout ${COLLECT_TIMEOUT:-330} python3 -m navzoo.agents.robot_bc collect --out "$demos" --scenes "${spec%%:*}" \
      --episodes "${spec##*:}" --seed $((eseed * k)) --scan-rays ${SCAN_RAYS:-0} 2>&1 | grep -v '^b3' >> "$OUT/collect.log" &
    pids+=($!)
  done
done
for k in $(seq 1 "$lblocks"); do
  for spec in $lspecs; do
    timeout ${COLLECT_TIMEOUT:-330} python3 -m navzoo.agents.robot_bc collect --out "$demos" --scenes "${spec%%:*}" \
      --episodes "${spec##*:}" --seed $((${SEED_BASE:-100} * k)) --learner "$learner" --beta ${BETA:-0.5} --scan-rays ${SCAN_RAYS:-0} \
      2>&1 | grep -v '^b3' >> "$OUT/collect.log" &
    pids+=($!)
  done
done
[ ${#pids[@]} -gt 0 ] && wait "${pids[@]}"
python3 -m navzoo.agents.robot_bc pretrain --demos "$demos" --out "$bc" --init-from "${INIT:-policies/transformer_ppo_crowdnav}" \
  --epochs ${BC_EPOCHS:-$epochs} --device cuda 2>&1 | grep -v '^b3' > "$OUT/pretrain.log"
cp "$bc/policy/config.json" "$bc/policy/policy.pt" "$OUT/"
python3 -c "import glob,numpy as np;print('demo steps in $demos:', sum(len(np.load(f)['action']) for f in glob.glob('$demos/*.npz')))" \
  | tee -a "$OUT/pretrain.log"
[ "${VAL:-1}" = 0 ] && exit 0
NAVZOO_TRANSFORMER_PPO_DIR=$bc/policy timeout ${VAL_TIMEOUT:-170} python3 -m navzoo.cli benchmark \
  --scenes station,home,grocery --methods transformer-ppo --crowd sfm --density 0.05,0.15,0.3 --max-humans 40 \
  --episodes 4 --seed 1 --workers 16 --out /tmp/val_bc --no-progress 2>&1 | grep -v '^b3' | tail -1
python3 -m navzoo.cli report /tmp/val_bc 2>&1 | grep '^| transformer' | tee "$OUT/val.log"

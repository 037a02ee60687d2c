#!/usr/bin/env bash
# The measurements of docs/crowd.md, "A hybrid walker" (2026-12-05, 2-core Intel Xeon VM). Run from the repository root.
set -euo pipefail
D=docs/results/diffusion_walker_hybrid_2026-12-05
export OMP_NUM_THREADS=1
# 1. the realism part and the diffusion + kinematic reliability row with the hybrid walker, seeds 0 and 1
#    (the social-force and ORCA walkers' files of the same command: docs/results/diffusion_walker_2026-12-05/vm_*),
#    about 12 minutes each, both at once on two cores
for s in 0 1; do
  navzoo eval crowd --crowds diffusion --rows diffusion+kinematic --no-cost --seed $s --set diffusion_walker=hybrid \
    --out $D/vm_hybrid_s$s.json > $D/vm_hybrid_s$s.log 2>&1 &
done
wait
# 2. the realism part without the doorway, seed 0, each walker (about 5 minutes each)
for w in orca hybrid sfm; do
  navzoo eval crowd --crowds diffusion --rows "" --no-cost --seed 0 \
    --scenes station,home,grocery,circle_crossing,square_crossing,corridor,lobby --set diffusion_walker=$w \
    --out $D/vm_nodoor_${w}_s0.json > $D/vm_nodoor_${w}_s0.log 2>&1
done
# 3. per scene: goals, speeds, accelerations (also while walking) and the share of person-time standing, each walker,
#    200 s, seed 0; first the real ETH/UCY tracks measured the same way
python scripts/diffusion_roughness.py --real --variants "" --out $D/standing.jsonl
for sc in lobby:15 corridor:12 home:5 doorway:13; do
  python scripts/diffusion_roughness.py --seconds 200 --scenes $sc --out $D/standing.jsonl \
    --variants "default;orca_walker=1;hybrid_walker=1"
done
# 4. the doorway with door turns (human_door_turns), ORCA and social-force walkers, seed 0 (about 30 s each)
for w in orca sfm; do
  navzoo eval crowd --crowds diffusion --rows "" --no-cost --seed 0 --scenes doorway --people 13 \
    --set diffusion_walker=$w --set human_door_turns=true --out $D/vm_door_turns_${w}_s0.json
done
# 5. the realism part of every crowd (default walker) and of the diffusion crowd with the ORCA and hybrid walkers,
#    seeds 0 and 1, with the standing share and the accelerations while walking (about 14 minutes per seed)
for s in 0 1; do
  navzoo eval crowd --rows "" --no-cost --seed $s --workers 2 --out $D/vm_realism_all_crowds_s$s.json
  for w in orca hybrid; do
    navzoo eval crowd --crowds diffusion --rows "" --no-cost --seed $s --workers 2 --set diffusion_walker=$w \
      --out $D/vm_realism_${w}_walker_s$s.json
  done
done

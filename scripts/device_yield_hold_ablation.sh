#!/usr/bin/env bash
# Following success of AMP pedestrians with and without holding yields (amp_humans.YIELD_HOLD_S): the social
# force + AMP row of `navzoo eval crowd` (the protocol and seed of `navzoo eval pedestrians`' following part),
# three runs side by side on the 16-core device machine: seed 0 and seed 1 with YIELD_HOLD_S = HOLD (6 s), and
# seed 1 with YIELD_HOLD_S = 0 (patched copies of the package in /tmp/hold and /tmp/nohold).
#
#   device run, carry [".whl", ".eth_ucy.tgz"]:  OUT=$OUT bash scripts/device_yield_hold_ablation.sh
set -u
OUT=${OUT:?set OUT}
[ -d /tmp/site/pybullet ] || python3 -m pip install -q --no-index --no-deps --no-compile --target /tmp/site .whl/*.whl
mkdir -p /tmp/d && tar xzf .eth_ucy.tgz -C /tmp/d
for v in hold nohold; do rm -rf /tmp/$v && mkdir -p /tmp/$v && cp -r navzoo policies /tmp/$v/; done
sed -i "s/^YIELD_HOLD_S = .*/YIELD_HOLD_S = ${HOLD:-6.0}/" /tmp/hold/navzoo/envs/amp_humans.py
sed -i 's/^YIELD_HOLD_S = .*/YIELD_HOLD_S = 0.0/' /tmp/nohold/navzoo/envs/amp_humans.py
export PYTHONUNBUFFERED=1 OMP_NUM_THREADS=1
E="-m navzoo.cli eval crowd --rows sfm+amp --crowds sfm --no-cost --workers 8 --data /tmp/d/eth_ucy"
(cd /tmp/hold && PYTHONPATH=/tmp/site:/tmp/hold python3 $E --seed 0 --out "$OUT/hold_seed0.json" \
  > "$OUT/hold_seed0.log" 2>&1) &
(cd /tmp/hold && PYTHONPATH=/tmp/site:/tmp/hold python3 $E --seed 1 --out "$OUT/hold_seed1.json" \
  > "$OUT/hold_seed1.log" 2>&1) &
(cd /tmp/nohold && PYTHONPATH=/tmp/site:/tmp/nohold python3 $E --seed 1 --out "$OUT/nohold_seed1.json" \
  > "$OUT/nohold_seed1.log" 2>&1) &
wait
for f in hold_seed0 hold_seed1 nohold_seed1; do
  python3 -c "import json,sys; r=json.load(open('$OUT/$f.json'))['reliability']['sfm+amp']; print('$f', {k: round(v, 4) if isinstance(v, float) else v for k, v in r.items() if k != 'scenes'})"
done

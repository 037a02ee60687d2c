#!/usr/bin/env bash
# Single following runs (scripts/amp_target_ablation.py) from a list, P at a time: the runs of the fallen-obstacles
# comparison (docs/crowd_log.md, "Falls come in cascades").
#
#   device run, carry [".whl"]:   bash scripts/device_fallen_obstacles.sh
#   a machine with navzoo:        PYTHON=.venv/bin/python P=2 OUT=out JOBS=docs/results/fallen_obstacles/jobs_heldout_amd.txt \
#                                     bash scripts/device_fallen_obstacles.sh
#
# JOBS (default docs/results/fallen_obstacles/jobs_protocol.txt) has one run per line: CONFIG SCENE[:PEOPLE] SEED, where
# CONFIG is kdtf... (diffusion targets) or skdtf... (social-force targets; e.g. skdtfr), today's defaults with
# human_fallen_obstacles on, under that name. FLAGS (default human_door_turns+human_fallen_obstacles) replaces the FALLEN
# field for every run, e.g. FLAGS=human_door_turns+amp_replan_seconds=1.0 with the names kdtp1 / skdtp1 (kd... and skd...
# names are accepted).
# Each run writes $OUT/parts/CONFIG_SCENE_SEED.jsonl (a call cut short keeps the runs it finished); at the end the
# parts are joined into $OUT/CONFIG_fallen.jsonl. SECS (default 200) sets the run length; DSET (e.g. fallen_in_map=1)
# passes --diffusion-set to the runs with diffusion targets. SET (e.g. DIFFUSION_DOOR_REACH=1.5) adds constants of
# navzoo.envs.amp_humans to every run's settings. POLICY (an exported AMP policy folder in the tree) walks every run
# with that policy instead of the shipped one. DEADLINE_S stops the list after that many seconds (the runs finished
# by then are kept). On the device machine (or with PACK=1) the parts are packed into $OUT/parts.tgz at the end, since
# the device tool returns at most 8 files.
set -u
if [ -d .whl ] && [ -z "${PYTHON:-}" ]; then  # the device machine: bring the wheels
  PACK=${PACK:-1}
  python3 -m pip install -q --no-index --no-deps --no-compile --target /tmp/site .whl/*.whl 2>&1 | tail -1
  export PYTHONPATH=/tmp/site:$PWD
fi
export POLICY=${POLICY:-} OMP_NUM_THREADS=1 PYTHON=${PYTHON:-python3} SECS=${SECS:-200} DSET=${DSET:-}
export FLAGS=${FLAGS:-human_door_turns+human_fallen_obstacles}
lscpu | grep "Model name"
export S="SFM_SIDE_BIAS=0.4+SFM_SIDE_NARROW_REACH=1.5${SET:++$SET}"
one() {
  case $1 in
    kd*) cfg="$1:0.1:0.1:4:2.0:$FLAGS::${POLICY:-}::::::::$S"; crowd=diffusion ;;
    skd*) cfg="$1:0.1:0.1:4:2.0:$FLAGS::${POLICY:-}::1:::::1:$S"; crowd=sfm ;;
    *) echo "unknown configuration $1 (kd... or skd...)" >&2; return 1 ;;
  esac
  dset=()
  if [ "$crowd" = diffusion ] && [ -n "${DSET:-}" ]; then dset=(--diffusion-set "$DSET"); fi
  timeout 1500 "$PYTHON" scripts/amp_target_ablation.py --crowd $crowd --scenes "$2" --configs "$cfg" --seeds "$3" "${dset[@]}" \
    --seconds "$SECS" --workers 1 --out "$OUT/parts/$1_$2_$3.jsonl" > "$OUT/parts/$1_$2_$3.log" 2>&1
}
export -f one
mkdir -p "$OUT/parts"
timeout "${DEADLINE_S:-100000}" xargs -P "${P:-16}" -L 1 bash -c 'one "$@"' _ < "${JOBS:-docs/results/fallen_obstacles/jobs_protocol.txt}"
[ $? = 124 ] && pkill -f -- "--out $OUT/parts/" && sleep 2  # this list's runs still going at the deadline (no rows)
for c in $(cut -d" " -f1 "${JOBS:-docs/results/fallen_obstacles/jobs_protocol.txt}" | sort -u); do
  cat "$OUT"/parts/${c}_*.jsonl > "$OUT/${c}_fallen.jsonl"
done
wc -l "$OUT"/*_fallen.jsonl
if [ "${PACK:-0}" = 1 ]; then
  tar czf "$OUT/parts.tgz" -C "$OUT" parts && rm -rf "$OUT/parts"
fi

#!/usr/bin/env bash
# Train (or resume) the AMP pedestrian controller on the accelerator machine, within one device call.
#
#   device run, carry [".whl"]:  TRAIN_S=500 LIMIT_S=455 bash scripts/device_train_amp.sh
#
# Resumes from the checkpoint committed in training/amp (RESUME_DIR), trains for LIMIT_S seconds on
# 15 worker processes x 16 humanoids with the networks on the GPU, and writes the new checkpoint to
# $OUT split in 15 MiB parts (the device tool returns files of at most 16 MiB), with metrics.jsonl.gz and
# the log. Copy those files back into training/amp to continue in a later session.
# RESET_DISC=1: resume with a fresh discriminator (needed once when the discriminator inputs changed meaning,
# e.g. from checkpoint 3315 to the finite-difference / grounded inputs); TRAIN_ARGS: more train.py flags.
# TRACK=1: afterwards, track the reference clips (the paper's protocol, navzoo.agents.amp.tracking) with the returned
# checkpoint's policy, for at most TRACK_S seconds (default 120); the summary is printed and appended to train.log
# (the call's eighth file: there is no room for a ninth). A progress signal for runs without obstacle rays, which
# cannot run the following protocol. The device's CPU walks slightly other rollouts than the VM's: compare
# checkpoints tracked on one kind of CPU (scripts/amp_checkpoint_tracking.py on the VM). TRACK_FULL=1 (with TRACK=1):
# also track the whole clips without the stop at failure (fall rate and errors over every second; another TRACK_S).
#
# Checkpoint selection (SNAPSHOT_EVERY=N, a multiple of 10): the run also exports its policy every N iterations
# and at the start, keeps all its checkpoints, and afterwards runs the short following protocol
# (scripts/amp_select_snapshots.py stage 1: 60 s per scene, seed 2, steering trim TRIM, default 0.025 rad) on
# every snapshot for at most SELECT_S seconds (default 200). The checkpoint returned is then the one of the
# best snapshot of the short protocol, not the last; small.tgz holds latest.json, selection.json, short.jsonl,
# the selection log and best_policy/ (the best snapshot's exported policy). Run the full protocol on it (and the
# baseline) in a second call.
#   device run:  SNAPSHOT_EVERY=40 STAGE=3 OBSTACLES=1 TRAIN_S=380 LIMIT_S=340 TRAIN_ARGS="..." bash scripts/device_train_amp.sh
#
# TRAINER=scenes: train in navzoo scenes instead of the patch env (python -m navzoo.rl.amp_joint train, from the
# shipped policy inside the training checkpoint in training/amp): WORKERS processes, each with N_ENVS copies x N_HUMANS pedestrians
# of one scene of SCENES (comma-separated library scenes, one per worker in turn), no robots; STAGE, OBSTACLES,
# RESET_DISC and RESUME_DIR do not apply. TRAIN_ARGS go to amp_joint train (e.g. --actor-lr, --disc-lr; a fresh
# discriminator is --reset-disc there, e.g. with --amp-velocity-span 4).
# The run from scratch (training/amp_scratch/README.md) on the 64-core host (kind nvidia-h100-x4), with only that
# training folder in the tree (the device copy holds at most 64 MiB):
#   RESUME_DIR=training/amp_scratch WORKERS=60 MINIBATCH=1920 STAGE=2 TRAIN_S=545 LIMIT_S=470 \
#     TRAIN_ARGS="--amp-velocity-span 4 --disc-lr 2e-5 --disc-grad-penalty 50 --disc-weight-decay 5e-4 --seed S" bash scripts/device_train_amp.sh
# On the 16-core host (kind nvidia-h200 / nvidia-h100) the same run goes on with 15 workers: add --any-num-envs 1 to
# TRAIN_ARGS for the first call after a change of WORKERS (the episodes restart; everything else resumes). The
# device copy holds at most 64 MiB, .whl included: `bash scripts/device_slim_tree.sh out training/amp_scratch
# policies/amp_pedestrian` before the call, `bash scripts/device_slim_tree.sh back` after it.
# BC_PAIRS=F (e.g. /tmp/bc_pairs.npz, outside the tree: a warm machine keeps /tmp between calls): make the cloning
# pairs for the actor's cloning term there first if F is missing (python -m navzoo.agents.amp.bc --pairs-only, on
# every core, about 50 s on 16; --amp-velocity-span BC_SPAN, default 4), then pass "--bc-coef W --bc-data F" in
# TRAIN_ARGS. The pairs (about 60 MB) do not fit the device copy next to the wheels and a training folder.
# BC_MIN_AHEAD=S: keep only the pairs after which the oracle's body stayed up S seconds more (bc --min-ahead); name
# such pairs by their margin (e.g. BC_PAIRS=/tmp/bc_pairs_ahead05.npz), since a file already there is used as it is.
# WIDEN_TO=141 (with OBSTACLES=1): widen the resumed checkpoint to the 16 obstacle rays first (navzoo.agents.amp.widen:
# zero weights on the new inputs, the episodes restart). For a run trained without rays, e.g. training/amp_bc before
# stage 3; its cloning pairs get clear rays (bc.with_clear_rays). Once only: the returned checkpoint has the rays.
# INIT_DIR=DIR starts the scene training from a checkpoint returned by an earlier call (its name, meta.json and
# state.pt.part-* files) instead of the shipped one; training/amp is then not needed and can stay behind.
set -u
python3 -m pip install -q --no-index --no-deps --no-compile --target /tmp/site .whl/*.whl 2>&1 | grep -v "already exists" | tail -2
export PYTHONPATH=/tmp/site:$PWD
nproc; nvidia-smi --query-gpu=name,memory.total --format=csv,noheader
python3 -c "import navzoo, torch, pybullet; print('navzoo ok, cuda', torch.cuda.is_available(), torch.__version__)"
rm -rf /tmp/amp /tmp/amp_init  # a warm machine keeps /tmp: never mix an earlier call's run into this one
if [ -n "${BC_PAIRS:-}" ]; then
  if [ -f "$BC_PAIRS" ]; then echo "cloning pairs: $BC_PAIRS (kept from an earlier call)"
  else python3 -m navzoo.agents.amp.bc --pairs-only --data-out "$BC_PAIRS" --workers "$(nproc)" \
      --amp-velocity-span "${BC_SPAN:-4}" --min-ahead "${BC_MIN_AHEAD:-0}" 2>&1 | tail -2
  fi
  [ -f "$BC_PAIRS" ] || { echo "no cloning pairs at $BC_PAIRS: stopping before training" | tee "$OUT/train.log"; exit 1; }
fi
RESUME_DIR=${RESUME_DIR:-training/amp}
TRAINER=${TRAINER:-path}
if [ -n "${WIDEN_TO:-}" ] && { [ "$TRAINER" != path ] || [ ! -f "$RESUME_DIR/name" ]; }; then
  echo "WIDEN_TO needs TRAINER=path and a checkpoint in $RESUME_DIR to widen: stopping before training" | tee "$OUT/train.log"; exit 1
fi
mkdir -p /tmp/amp/checkpoints
if [ "$TRAINER" = path ] && [ -f "$RESUME_DIR/name" ]; then
  name=$(cat "$RESUME_DIR/name")
  mkdir -p /tmp/amp/checkpoints/$name
  cat "$RESUME_DIR"/state.pt.part-* > /tmp/amp/checkpoints/$name/state.pt
  cp "$RESUME_DIR/meta.json" /tmp/amp/checkpoints/$name/ && cp "$RESUME_DIR/latest.json" /tmp/amp/checkpoints/
  [ -f "$RESUME_DIR/metrics.jsonl.gz" ] && gunzip -c "$RESUME_DIR/metrics.jsonl.gz" > /tmp/amp/metrics.jsonl
  echo "resuming from $name"
  if [ -n "${WIDEN_TO:-}" ]; then  # add inputs (the 16 obstacle rays: WIDEN_TO=141) to a checkpoint trained without
    python3 -m navzoo.agents.amp.widen /tmp/amp/checkpoints/$name /tmp/amp/widened --obs-dim "$WIDEN_TO" \
      && rm -rf /tmp/amp/checkpoints && mv /tmp/amp/widened /tmp/amp/checkpoints && echo "widened $name to $WIDEN_TO inputs" \
      || { echo "widening $name to $WIDEN_TO inputs failed: stopping before training" | tee "$OUT/train.log"; exit 1; }
  fi
fi
SNAP=${SNAPSHOT_EVERY:-0}
SNAP_ARGS=""
[ "$SNAP" -gt 0 ] && SNAP_ARGS="--snapshot-every $SNAP --keep-checkpoints 1000"
if [ "$TRAINER" = scenes ]; then
  INIT_ARGS=""
  if [ -n "${INIT_DIR:-}" ]; then  # start from another run's checkpoint (name, meta.json, state.pt.part-*)
    init=/tmp/amp_init/$(cat "$INIT_DIR/name")
    mkdir -p "$init" && cat "$INIT_DIR"/state.pt.part-* > "$init/state.pt" && cp "$INIT_DIR/meta.json" "$init/"
    INIT_ARGS="--init $init"; echo "starting from $init"
  fi
  timeout "${TRAIN_S:-500}" python3 -m navzoo.rl.amp_joint train --out /tmp/amp --workers "${WORKERS:-16}" \
    --n-envs "${N_ENVS:-2}" --n-humans "${N_HUMANS:-6}" --n-robots 0 --scenes "${SCENES:?set SCENES}" --device cuda \
    --minibatch-size "${MINIBATCH:-1536}" --time-limit-s "${LIMIT_S:-455}" --steps 500000000 --ckpt-every 10 \
    $INIT_ARGS $SNAP_ARGS ${TRAIN_ARGS:-} > "$OUT/train.log" 2>&1
elif [ "$TRAINER" = path ]; then
  timeout "${TRAIN_S:-500}" python3 -m navzoo.agents.amp.train --out /tmp/amp --workers "${WORKERS:-15}" --envs-per-worker 16 \
    --device cuda --hidden 1024,512 --minibatch-size "${MINIBATCH:-1920}" --time-limit-s "${LIMIT_S:-455}" \
    --total-steps 500000000 --ckpt-every 10 --ckpt-replay-rows 8000 --stage "${STAGE:-1}" --obstacles "${OBSTACLES:-0}" \
    --reset-disc "${RESET_DISC:-0}" $SNAP_ARGS ${TRAIN_ARGS:-} --json > "$OUT/train.log" 2>&1
else
  echo "TRAINER must be path or scenes, got $TRAINER" > "$OUT/train.log"; false
fi
echo "train rc=$?"
tail -5 "$OUT/train.log"
gzip -c /tmp/amp/metrics.jsonl > "$OUT/metrics.jsonl.gz" 2>/dev/null
name=$(python3 -c "import json;print(json.load(open('/tmp/amp/checkpoints/latest.json'))['checkpoint'])")
if [ "$SNAP" -gt 0 ]; then
  timeout "${SELECT_S:-200}" python3 scripts/amp_select_snapshots.py --snapshots /tmp/amp/snapshots --trim "${TRIM:-0.025}" \
    --full-seeds '' --workers "${SELECT_WORKERS:-16}" --out /tmp/amp/selection ${SELECT_ARGS:-} > /tmp/amp/select.log 2>&1
  echo "select rc=$?"; tail -20 /tmp/amp/select.log
  # the best snapshot of the short protocol (rows so far, if the time ran out) -> its checkpoint
  best=$(python3 -c "
import json, sys
sys.path.insert(0, 'scripts')
from amp_select_snapshots import success_by_config
s = success_by_config(__import__('pathlib').Path('/tmp/amp/selection/short.jsonl'))
print(max(s, key=lambda n: s[n]['success']) if s else '')")
  if [ -n "$best" ] && [ -d "/tmp/amp/checkpoints/ckpt_$(printf %08d "${best#it}")" ]; then
    name="ckpt_$(printf %08d "${best#it}")"
    echo "{\"checkpoint\": \"$name\"}" > /tmp/amp/checkpoints/latest.json
    echo "returning $name, the best snapshot of the short protocol"
  else
    echo "returning the last checkpoint $name: the best snapshot (${best:-none}) has no checkpoint"
  fi
  # the best snapshot's exported policy too (about 3 MB), ready for the full protocol in a second call
  extra=""
  if [ -n "$best" ] && [ -d "/tmp/amp/snapshots/policy_$(printf %08d "${best#it}")" ]; then
    cp -r "/tmp/amp/snapshots/policy_$(printf %08d "${best#it}")" /tmp/amp/best_policy && extra=best_policy
  fi
  (cd /tmp/amp && cp checkpoints/latest.json . && tar czf "$OUT/small.tgz" latest.json select.log selection $extra)
else
  cp /tmp/amp/checkpoints/latest.json "$OUT/"
fi
echo "$name" > "$OUT/name"
if [ "${TRACK:-0}" = 1 ]; then
  python3 -c "from navzoo.agents.amp.train import export_from_checkpoint as e; e('/tmp/amp/checkpoints/$name', '/tmp/amp/track_policy')" \
    && timeout "${TRACK_S:-120}" python3 -m navzoo.agents.amp.tracking /tmp/amp/track_policy --json > /tmp/amp/tracking.json
  echo "tracking rc=$? of $name: $(python3 -c "
import json
d = json.load(open('/tmp/amp/tracking.json'))
print(json.dumps({k: d[k] for k in ('clip_success_rate', 'mean_pos_error_m', 'max_pos_error_m', 'mean_rot_error_rad')}))" 2>&1)" \
    | tee -a "$OUT/train.log"
  if [ "${TRACK_FULL:-0}" = 1 ]; then  # whole clips, no stop at failure: falls and errors over every second
    timeout "${TRACK_S:-120}" python3 -m navzoo.agents.amp.tracking /tmp/amp/track_policy --no-stop-on-failure --json \
      > /tmp/amp/tracking_full.json
    echo "whole-clip tracking rc=$? of $name: $(python3 -c "
import json
d = json.load(open('/tmp/amp/tracking_full.json'))
print(json.dumps({k: d[k] for k in ('fall_rate', 'mean_pos_error_m', 'mean_rot_error_rad', 'seconds_simulated')}))" 2>&1)" \
      | tee -a "$OUT/train.log"
  fi
fi
cp /tmp/amp/checkpoints/$name/meta.json "$OUT/"
split -b 15m /tmp/amp/checkpoints/$name/state.pt "$OUT/state.pt.part-"
ls -la "$OUT"
n=$(find "$OUT" -type f | wc -l)
[ "$n" -gt 8 ] && echo "WARNING: $n files under \$OUT but the device tool returns at most 8: write other outputs of this call elsewhere"
true

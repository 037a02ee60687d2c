#!/usr/bin/env bash
# Slim the working tree for a device call, and put it back afterwards.
#
# The device tool copies the tracked tree plus the carried paths, at most 64 MiB in all; the tracked tree is
# about 150 MB (training checkpoints, docs, benchmark results, policies). A call that trains the AMP controller
# needs the code, the packaged motions, one training folder and (for evaluation) the shipped AMP policy.
#
#   bash scripts/device_slim_tree.sh out training/amp_scratch policies/amp_pedestrian   # before the call
#   bash scripts/device_slim_tree.sh back                                               # after it, always
#
# `out` moves every folder of training/ and policies/, docs/ and benchmarks/ to STASH (default
# ../.device_stash, outside the repository), except the paths named, and the exported policies (policies/) of a
# named training folder. `back` moves them back (and moves nothing if any path was made again meanwhile). Both refuse to
# overwrite anything, and `git status` shows the moved files as deleted until `back`: never commit between the two.
set -euo pipefail
cd "$(dirname "$0")/.."
STASH=${STASH:-../.device_stash}
mode=${1:-}
shift || true
case "$mode" in
  out)
    [ -e "$STASH" ] && { echo "$STASH exists: run 'back' first (or remove it if it is empty)" >&2; exit 1; }
    for keep in "$@"; do
      [ -e "$keep" ] || { echo "$keep: no such path to keep" >&2; exit 1; }
    done
    mkdir -p "$STASH"
    moved=0
    for path in training/* policies/* docs benchmarks; do
      [ -d "$path" ] || continue
      for keep in "$@"; do
        [ "${keep%/}" = "$path" ] && continue 2
      done
      mkdir -p "$STASH/$(dirname "$path")"
      mv "$path" "$STASH/$path"
      moved=$((moved + 1))
    done
    # a kept training folder's exported policies (a few MB each) are not needed to train: they stay behind too
    for keep in "$@"; do
      case "${keep%/}" in
        training/*) if [ -d "${keep%/}/policies" ]; then
            mkdir -p "$STASH/${keep%/}" && mv "${keep%/}/policies" "$STASH/${keep%/}/policies"; moved=$((moved + 1)); fi ;;
      esac
    done
    echo "moved $moved paths to $STASH; tracked files left: $(git ls-files | while read -r f; do [ -e "$f" ] && echo "$f"; done | xargs du -cb 2>/dev/null | tail -1 | cut -f1) bytes"
    ;;
  back)
    [ -d "$STASH" ] || { echo "$STASH: nothing to put back" >&2; exit 1; }
    # check every path first, so that a conflict moves nothing (a half put-back tree is harder to mend)
    clash=""
    for sub in $(cd "$STASH" && find training -mindepth 2 -maxdepth 2 -name policies 2>/dev/null); do
      [ -d "$(dirname "$sub")" ] && [ -e "$sub" ] && clash="$clash $sub"
    done
    for path in $(cd "$STASH" && find training policies -mindepth 1 -maxdepth 1 2>/dev/null) docs benchmarks; do
      case "$path" in training/*) [ -d "$path" ] && [ -d "$STASH/$path/policies" ] && continue ;; esac  # a kept folder
      [ -e "$STASH/$path" ] && [ -e "$path" ] && clash="$clash $path"
    done
    if [ -n "$clash" ]; then
      echo "in the tree and in $STASH:$clash; nothing moved. Something wrote there while the tree was slim (results" >&2
      echo "copied into docs/?): move it aside, remove the path from the tree, run 'back', then move it in again" >&2
      exit 1
    fi
    for sub in $(cd "$STASH" && find training -mindepth 2 -maxdepth 2 -name policies 2>/dev/null); do
      [ -d "$(dirname "$sub")" ] || continue  # its whole training folder was moved: the loop below puts it back
      [ -e "$sub" ] && { echo "$sub exists in the tree and in $STASH: left both as they are" >&2; exit 1; }
      mv "$STASH/$sub" "$sub"
      rmdir "$STASH/$(dirname "$sub")"
    done
    for path in $(cd "$STASH" && find training policies -mindepth 1 -maxdepth 1 2>/dev/null) docs benchmarks; do
      [ -e "$STASH/$path" ] || continue
      [ -e "$path" ] && { echo "$path exists in the tree and in $STASH: left both as they are" >&2; exit 1; }
      mkdir -p "$(dirname "$path")"
      mv "$STASH/$path" "$path"
    done
    find "$STASH" -depth -type d -empty -delete
    [ -e "$STASH" ] && { echo "$STASH still holds files: check them" >&2; exit 1; }
    echo "put back"
    ;;
  *)
    echo "usage: $0 out [PATH_TO_KEEP ...] | back" >&2; exit 2 ;;
esac

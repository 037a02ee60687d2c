#!/usr/bin/env bash
# Build .raysite/ (git-ignored) for scripts/device_rllib_throughput.sh: Ray 2.60 for CPython 3.12,
# unpacked without its Java jars and dashboard source maps and xz-compressed (79 MB wheel -> ~31 MB),
# plus the wheels of Ray's and RLlib's needs that the device image lacks. Needs pip and the network.
set -eu
cd "$(dirname "$0")/.."
PLAT="--only-binary=:all: --python-version 3.12 --implementation cp --platform manylinux_2_28_x86_64 \
  --platform manylinux_2_24_x86_64 --platform manylinux_2_17_x86_64 --platform manylinux2014_x86_64"
tmp=$(mktemp -d)
mkdir -p .raysite/deps
python3 -m pip download -q --no-deps $PLAT -d "$tmp" ray==2.60.0
python3 -m pip download -q --no-deps $PLAT -d .raysite/deps dm_tree lz4 "ormsgpack>=1.7.0" jsonschema \
  jsonschema-specifications referencing rpds-py pydantic pydantic-core annotated-types typing-inspection
mkdir "$tmp/x" && (cd "$tmp/x" && unzip -q ../ray-2.60.0-*.whl && rm -rf ray/jars \
  && rm -f ray/dashboard/client/build/static/js/*.map && tar cJf - .) > .raysite/ray_site.tar.xz
rm -rf "$tmp"
grep -qx "/.raysite/" .git/info/exclude || echo "/.raysite/" >> .git/info/exclude
du -sh .raysite

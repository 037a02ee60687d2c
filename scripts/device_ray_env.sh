# Sourced by the device scripts that need Ray RLlib (carry [".whl", ".raysite"]): on the device machine, install
# the wheels and unpack the Ray site into /tmp/site once; then the environment every run of them uses.
if command -v nvidia-smi > /dev/null && [ ! -d /tmp/site/ray ]; then  # the device machine
  python3 -m pip install -q --no-index --no-deps --no-compile --target /tmp/site .whl/*.whl .raysite/deps/*.whl \
    2>&1 | grep -v "already exists" | tail -2
  tar xJf .raysite/ray_site.tar.xz -C /tmp/site || exit 1
fi
[ -d /tmp/site/ray ] && export PYTHONPATH=/tmp/site:$PWD
export PYTHONUNBUFFERED=1 RAY_DISABLE_USAGE_STATS=1 OMP_NUM_THREADS=1  # one torch thread per process

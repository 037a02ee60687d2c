"""Small PyBullet helpers shared by the world builder, the agents and the env.

Every navzoo object talks to one explicit physics client (never PyBullet's implicit default one),
and PyBullet's URDF importer prints harmless warnings from C code straight to the process's stdout;
:func:`quiet` silences them at the file-descriptor level so that ``--json`` output stays parseable.
"""

from __future__ import annotations

import contextlib
import importlib.util
import os
import sys
from collections.abc import Iterator


@contextlib.contextmanager
def quiet() -> Iterator[None]:
    """Redirect the C-level stdout and stderr to /dev/null for the duration of the block."""
    try:
        sys.stdout.flush()
        sys.stderr.flush()
        saved = (os.dup(1), os.dup(2))
    except (OSError, ValueError):  # no real file descriptors (e.g. some notebook kernels)
        yield
        return
    devnull = os.open(os.devnull, os.O_WRONLY)
    try:
        os.dup2(devnull, 1)
        os.dup2(devnull, 2)
        yield
    finally:
        os.dup2(saved[0], 1)
        os.dup2(saved[1], 2)
        os.close(devnull)
        os.close(saved[0])
        os.close(saved[1])


# Import torch before pybullet: with a CUDA build of torch and a source-built pybullet (the wheel of
# the accelerator machine), importing pybullet first makes `import torch` segfault (measured there).
if importlib.util.find_spec("torch") is not None:
    import torch  # noqa: F401

# pybullet prints its build time to stdout when first imported; keep stdout clean for --json output.
with quiet():
    import pybullet as p
    import pybullet_data


def connect(gui: bool = False) -> int:
    """Open a new PyBullet client (DIRECT, or GUI when asked) and return its id.

    Raises:
        RuntimeError: ``gui=True`` but no display is available.
    """
    if gui:
        if not os.environ.get("DISPLAY") and sys.platform.startswith("linux"):
            raise RuntimeError(
                "render_mode='human' opens the PyBullet GUI, which needs a display, but $DISPLAY is not set; "
                "use render_mode='rgb_array' on a headless machine (or run under Xvfb)"
            )
        with quiet():
            cid = p.connect(p.GUI)
    else:
        with quiet():
            cid = p.connect(p.DIRECT)
    if cid < 0:
        raise RuntimeError("could not open a PyBullet physics client")
    p.setAdditionalSearchPath(pybullet_data.getDataPath(), physicsClientId=cid)
    return cid


def disconnect(cid: int) -> None:
    """Close a client, ignoring one that is already gone."""
    with contextlib.suppress(p.error):
        p.disconnect(physicsClientId=cid)

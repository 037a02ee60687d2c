from __future__ import annotations

import os

os.environ.setdefault("SDL_VIDEODRIVER", "dummy")

from __future__ import annotations

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from navzoo.world.library import get_scene  # noqa: E402
from navzoo.world.plot import contact_sheet, plot_scene  # noqa: E402


def test_plot_scene_returns_axes():
    ax = plot_scene(get_scene("home"))
    assert ax.get_title() == "home"
    fig, ax2 = plt.subplots()
    assert plot_scene(get_scene("circle_crossing"), ax=ax2, show_regions=False) is ax2
    plt.close("all")


def test_contact_sheet(tmp_path):
    out = contact_sheet(["doorway", "corridor"], tmp_path / "sheet.png", cols=2)
    assert out.exists() and out.stat().st_size > 10_000
    img = plt.imread(out)
    assert img.ndim == 3 and np.ptp(img) > 0

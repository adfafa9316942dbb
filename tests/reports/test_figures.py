"""The report's figures that compare methods: Fig. 4 (the paper's classroom bars beside ours only) and the error maps
(a colour scale per method, so that the best methods' maps are not black beside the worst's)."""

from __future__ import annotations

import numpy as np
import pandas as pd

from reconstruction.methods.registry import DEFAULT_METHOD, PAPER_CONFIG
from reports.plots import error_figure, fig4_figure, overview_figure, png_bytes
from reports.tables import PAPER_MAE_M

PAPER = f"{PAPER_CONFIG[0]}-{'rect' if PAPER_CONFIG[1] else 'plain'}"


def _rows(scene: str, viewpoint: str, paper_mae: float, family: str = "") -> list[dict]:
    """One frame's rows: the paper's set-up (average, gradient, color), dis-rect:gradient, the default method and
    the sweep; MAEs in metres, the paper set-up's ``average`` = ``paper_mae``, its refined variants 0.1 m less."""
    out = []
    for v in ("average", "gradient", "color"):
        out.append({"scene": scene, "viewpoint": viewpoint, "method": f"{PAPER}:{v}", "flow": PAPER_CONFIG[0],
                    "rectify": PAPER_CONFIG[1], "variant": v,
                    "mae_m": paper_mae if v == "average" else paper_mae - 0.1})
    out.append({"scene": scene, "viewpoint": viewpoint, "method": "dis-rect:gradient", "flow": "dis",
                "rectify": True, "variant": "gradient", "mae_m": 0.3})
    for label, mae in ((DEFAULT_METHOD, 0.15), ("sweep", 0.4)):
        out.append({"scene": scene, "viewpoint": viewpoint, "method": label, "flow": "", "rectify": "",
                    "variant": "", "mae_m": mae})
    return [{**r, "family": family} for r in out]


def _panels(fig):
    """The bar-chart axes (the ones with x tick labels), left to right."""
    return [ax for ax in fig.axes if ax.get_xticklabels()]


def _bars(ax):
    """``[(x tick label, height, hatched)]`` of every bar (each bar belongs to the nearest tick)."""
    ticks = [t.get_text() for t in ax.get_xticklabels()]
    out = []
    for p in ax.patches:
        x = p.get_x() + p.get_width() / 2
        out.append((ticks[int(round(x))], p.get_height(), bool(p.get_hatch())))
    return out


def test_fig4_puts_the_papers_bars_beside_ours_on_the_classroom_only():
    # classroom frames (by family, and one by scene name) at 0.5 / 0.7 m, and a lab frame at 5 m
    results = pd.DataFrame(_rows("room-a", "vp000", 0.5, family="classroom") + _rows("classroom", "vp001", 0.7)
                           + _rows("lab", "vp000", 5.0, family="lab"))
    fig = fig4_figure(results)
    first, every = _panels(fig)
    bars = _bars(first)
    quoted = [(label, h) for label, h, hatched in bars if hatched]
    assert [h for _, h in quoted] == list(PAPER_MAE_M.values())
    assert all("their classroom" in label for label, _ in quoted)
    ours = {round(h, 6) for label, h, hatched in bars if not hatched and "our classroom" in label}
    # the paper set-up's classroom means (0.6 m average, 0.5 m refined) and the default method (0.15 m); never the
    # lab frame (5 m) and never a bar without the "our classroom" label
    assert ours == {0.6, 0.5, 0.15}
    assert all(hatched or "our classroom" in label for label, _, hatched in bars)
    assert any(DEFAULT_METHOD in label for label, _, _ in bars)
    # every frame: no quoted bar, the lab frame included, the default method present
    rest = _bars(every)
    assert not any(hatched for _, _, hatched in rest)
    assert any(abs(h - (0.5 + 0.7 + 5.0) / 3) < 1e-9 for _, h, _ in rest)
    assert any(DEFAULT_METHOD in label and abs(h - 0.15) < 1e-9 for label, h, _ in rest)


def test_fig4_without_classroom_frames_draws_no_paper_bars():
    fig = fig4_figure(pd.DataFrame(_rows("lab", "vp000", 5.0, family="lab")))
    panels = _panels(fig)
    assert len(panels) == 1
    assert not any(hatched for _, _, hatched in _bars(panels[0]))
    assert "not drawn" in panels[0].get_title()


def test_error_maps_give_each_method_its_own_scale():
    """A good method (errors 0-2 cm) beside a bad one (errors 0-20 m): the good one's panel spans its own errors,
    so its structure is visible, instead of 0-20 m where all of it would be black."""
    rng = np.random.default_rng(0)
    gt = np.full((40, 80), 5.0)
    good = gt + rng.uniform(0.0, 0.02, gt.shape)
    bad = gt + rng.uniform(0.0, 20.0, gt.shape)
    fig = error_figure(gt, {"good": good, "bad": bad}, "t")
    clim = {ax.get_title().split(": ")[1].split(" ")[0]: ax.images[0].get_clim()
            for ax in fig.axes if ax.get_title().startswith("|pred - gt|")}
    assert clim["good"][0] == 0 and 0.018 < clim["good"][1] < 0.0201  # its 99th percentile, metres
    assert 18.0 < clim["bad"][1] < 20.01
    bars = [ax for ax in fig.axes if ax.get_label() == "<colorbar>"]
    assert len(bars) == 3  # ground truth and one per method


def test_overview_figure_shows_image_prediction_and_error_on_its_own_scale():
    """The README's picture: input, prediction on the true distances' scale, error on its own scale; an invalid
    pixel is no surface in the prediction panel and counted in the MAE with error = gt."""
    rng = np.random.default_rng(1)
    gt = np.full((40, 80), 4.0)
    gt[:5] = np.inf  # no surface
    pred = gt + rng.uniform(0.0, 0.1, gt.shape)
    pred[20, 10] = np.nan
    image = rng.integers(0, 255, (40, 80, 3), dtype=np.uint8)
    fig = overview_figure(image, gt, pred, "m")
    titles = [ax.get_title() for ax in fig.axes if ax.get_label() != "<colorbar>"]
    assert titles[0].startswith("input") and titles[1] == "predicted distance: m"
    mae = float(titles[2].split("MAE ")[1].split(" ")[0])
    finite = np.isfinite(gt)
    err = np.abs(pred[finite] - gt[finite])
    expected = (np.nansum(err) + 4.0) / finite.sum()  # the invalid pixel scores error = gt = 4 m
    assert abs(mae - expected) < 1e-3
    err_panel = [ax for ax in fig.axes if ax.get_title().startswith("absolute error")][0]
    assert 0.09 < err_panel.images[0].get_clim()[1] <= 0.1  # the 99th percentile of its errors, metres
    assert png_bytes(fig)[:8] == b"\x89PNG\r\n\x1a\n"

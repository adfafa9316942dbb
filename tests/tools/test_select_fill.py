"""The selection of the default's sweep resolution and refill: the tables and the rule on hand-made results, and
the candidates."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from harness.data.errors import UserError
from reconstruction.methods.presets import fused_mirror
from tools.research.select_fill import (
    MAX_LEVELS,
    REFERENCE,
    candidate_methods,
    choose,
    family_table,
    fill_method,
    frame_table,
    region_table,
)

REF = "fused-mirror-160-0-8-inverse"
# method -> MAE per (condition, family); 1000 pixels per frame, two frames per cell
MAE = {
    REF: {("ideal", "a"): 0.20, ("ideal", "b"): 0.30, ("captured", "a"): 0.25},
    "x": {("ideal", "a"): 0.15, ("ideal", "b"): 0.30, ("captured", "a"): 0.20},  # eligible: no cell above 1.0 x
    "y": {("ideal", "a"): 0.10, ("ideal", "b"): 0.31, ("captured", "a"): 0.10},  # lowest pooled, ideal b 1.03 x
    "z": {("ideal", "a"): 0.19, ("ideal", "b"): 0.303, ("captured", "a"): 0.25},  # ideal b 1.01 x: within the bound
}


def results() -> pd.DataFrame:
    rows = []
    for method, cells in MAE.items():
        for (cond, fam), mae in cells.items():
            for vp in ("vp000", "vp001"):
                rows.append({"scene": f"{fam}-s1", "viewpoint": vp, "method": method, "mae_m": mae,
                             "valid_px": 1000, "condition": "" if cond == "ideal" else cond, "family": fam})
    return pd.DataFrame(rows)


def test_family_table_pools_and_the_rule_keeps_every_family_within_the_bound():
    table = family_table(results(), [REF, "x", "y", "z"])
    assert list(table.index)[0] == ("ideal", "a") and list(table.index)[-1] == ("all", "all")
    assert table.loc[("all", "all"), "x"] == pytest.approx((0.15 + 0.30 + 0.20) / 3)
    levels = {"x": 200, "y": 200}
    choice, worst, worst_frame = choose(table, ["x", "y"], levels)
    assert all(np.isnan(v) for v in worst_frame.values())  # no frames given: no frame bound
    assert worst["x"] == pytest.approx(1.0) and worst["y"] == pytest.approx(0.31 / 0.30)
    assert choice == "x"  # y is lower pooled but loses 3 % on ideal b
    assert choose(table, ["z", "y"], {"z": 200, "y": 200})[0] == "z"  # z loses 1 %: eligible
    # more labels than the memory allows: not eligible, however accurate
    assert choose(table, ["x", "y"], {"x": MAX_LEVELS + 40, "y": 200})[0] == REF
    # a candidate worse everywhere leaves the reference
    table[["x", "y"]] = table[["x", "y"]] * 2
    assert choose(table, ["x", "y"], levels)[0] == REF


def test_the_rule_keeps_every_frame_within_the_frame_bound():
    """A candidate better pooled and on every family but losing more than ``FRAME_BOUND`` on one frame is not
    eligible; within the bound it is."""
    rows = []
    maes = {REF: (0.10, 0.10, 0.10, 0.10), "x": (0.05, 0.05, 0.05, 0.12), "y": (0.09, 0.09, 0.09, 0.105)}
    for method, per_frame in maes.items():
        for k, mae in enumerate(per_frame):
            rows.append({"scene": f"a-s{k // 2}", "viewpoint": f"vp00{k % 2}", "method": method, "mae_m": mae,
                         "valid_px": 1000, "condition": "", "family": "a"})
    df = pd.DataFrame(rows)
    methods = [REF, "x", "y"]
    frames = frame_table(df, methods)
    assert frames.shape == (4, 3) and frames.loc[("a-s1", "vp001"), "x"] == pytest.approx(0.12)
    families = family_table(df, methods)
    choice, worst, worst_frame = choose(families, ["x", "y"], {"x": 200, "y": 200}, frames)
    assert worst_frame["x"] == pytest.approx(1.2) and worst_frame["y"] == pytest.approx(1.05)
    assert worst["x"] < 1 and choice == "y"  # x: 1.2 x on one frame
    assert choose(families, ["x"], {"x": 200}, frames)[0] == REF
    assert choose(families, ["x"], {"x": 200})[0] == "x"  # without frames only the families count
    frames.loc[("a-s0", "vp000"), "y"] = np.nan  # a frame y gives no MAE on: unbounded, not skipped
    assert choose(families, ["y"], {"y": 200}, frames)[:3:2] == (REF, {"y": np.inf})


def test_region_table_pools_each_region_by_its_pixels():
    regions = pd.DataFrame([{"method": REF, "region": "all", "mae_m": 0.2, "valid_px": 100},
                            {"method": REF, "region": "all", "mae_m": 0.4, "valid_px": 300},
                            {"method": REF, "region": "occluded", "mae_m": 1.0, "valid_px": 10}])
    table = region_table(regions, [REF])
    assert table.loc[REF, "all"] == pytest.approx(0.35) and table.loc[REF, "occluded"] == pytest.approx(1.0)


def test_candidates_the_reference_first_and_the_default_once():
    methods = candidate_methods()
    labels = [m.label for m in methods]
    assert labels[0] == REF and labels[-1] == "fused-mirror" and len(set(labels)) == len(labels)
    ref = methods[0]
    assert (ref.sweep.cost.levels, ref.sweep.corrected_cost.levels, ref.sweep.post.min_confidence) == (160, 160, 0.0)
    # everything but the four values is the default's
    default = fused_mirror()
    m = fill_method(*REFERENCE)
    assert m.flow == default.flow and m.prior == default.prior and m.sweep.sgm == default.sweep.sgm
    with pytest.raises(UserError, match="unknown candidate"):
        candidate_methods(["160-0.3-8-cubic"])

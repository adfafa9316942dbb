"""The selection of the default's sweep resolution and refill: the tables and the rule on hand-made results, and
the candidates."""

from __future__ import annotations

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
    choice, worst = choose(table, ["x", "y"], levels)
    assert worst["x"] == pytest.approx(1.0) and worst["y"] == pytest.approx(0.31 / 0.30)
    assert choice == "x"  # y is lower pooled but loses 3 % on ideal b
    assert choose(table, ["z", "y"], {"z": 200, "y": 200})[0] == "z"  # z loses 1 %: eligible
    # more labels than the memory allows: not eligible, however accurate
    assert choose(table, ["x", "y"], {"x": MAX_LEVELS + 40, "y": 200})[0] == REF
    # a candidate worse everywhere leaves the reference
    table[["x", "y"]] = table[["x", "y"]] * 2
    assert choose(table, ["x", "y"], levels)[0] == REF


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

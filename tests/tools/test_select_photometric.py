"""The selection of the default's photometric self-calibration: the method x condition x family table, the bounds
and the rule, on hand-made results; the candidates and the uncalibrated reference."""

from __future__ import annotations

import pandas as pd
import pytest

from harness.data.errors import UserError
from reconstruction.methods.presets import fused_mirror
from reconstruction.methods.registry import uncalibrated
from reconstruction.photometry import NO_CALIBRATION
from reconstruction.rig_calibration import NO_RIG_CALIBRATION
from tools.research.select_photometric import (
    CANDIDATES,
    UNCALIBRATED_DEFAULT,
    candidate_methods,
    choose,
    condition_table,
)

# method -> (ideal MAE, captured MAE) per family (two frames per family and condition, 1000 pixels each)
MAE = {
    "sweep": {"a": (0.30, 0.33), "b": (0.20, 0.22)},
    "fused": {"a": (0.25, 0.27), "b": (0.30, 0.30)},
    UNCALIBRATED_DEFAULT: {"a": (0.20, 2.00), "b": (0.20, 1.00)},
    "fused-mirror-i1": {"a": (0.20, 0.23), "b": (0.21, 0.25)},  # ideal b 1.05 x the better baseline (0.20): ok
    "fused-mirror-i0.5": {"a": (0.19, 0.25), "b": (0.19, 0.20)},  # captured a 1.32 x its ideal: not eligible
    "fused-mirror-i0.25": {"a": (0.22, 0.23), "b": (0.20, 0.21)},  # ideal a 1.1 x the reference: not eligible
}


def results() -> pd.DataFrame:
    rows = []
    for method, fams in MAE.items():
        for fam, (ideal, captured) in fams.items():
            for cond, mae in (("ideal", ideal), ("captured", captured)):
                for vp in ("vp000", "vp001"):
                    rows.append({"scene": f"{fam}-s1" + ("" if cond == "ideal" else ".captured"), "viewpoint": vp,
                                 "method": method, "flow": "", "rectify": "", "variant": "", "mae_m": mae,
                                 "mae_sw_m": mae, "valid_px": 1000, "valid_sr": 12.0, "seconds": 1.0,
                                 "family": fam, "tags": "", "suite_id": "", "split": "", "condition": cond})
    return pd.DataFrame(rows)


def test_table_bounds_and_choice():
    table = condition_table(results())
    assert table.loc["fused", "ideal:b"] == pytest.approx(0.30) and table.loc["sweep", "captured"] == pytest.approx(
        0.275)
    assert table.loc["fused-mirror-i1", "seconds"] == pytest.approx(8.0)
    label, eligible, r = choose(table)
    assert label == "fused-mirror-i1" and eligible
    assert r.loc["fused-mirror-i0.5", "captured_family"] == pytest.approx(0.25 / 0.19 / 1.3)
    assert r.loc["fused-mirror-i0.25", "ideal"] == pytest.approx(0.21 / 0.20 / 1.03)
    assert r.loc["fused-mirror-i1", "ideal_family"] == pytest.approx(0.21 / 0.20 / 1.05)


def test_no_eligible_candidate_gives_the_lowest_worst_ratio():
    df = results()
    df.loc[(df["method"] == "fused-mirror-i1") & (df["condition"] == "captured"), "mae_m"] = 0.5
    label, eligible, r = choose(condition_table(df))
    assert not eligible and label == r[r.index.isin(list(CANDIDATES))].max(axis=1).idxmin()


def test_missing_reference_or_condition_is_refused():
    df = results()
    with pytest.raises(UserError, match=UNCALIBRATED_DEFAULT):
        choose(condition_table(df[df["method"] != UNCALIBRATED_DEFAULT]))
    with pytest.raises(UserError, match="captured"):
        choose(condition_table(df[df["condition"] == "ideal"]))


def test_candidates_and_the_reference():
    methods = {m.label: m for m in candidate_methods()}
    assert list(methods)[:3] == ["sweep", "fused", UNCALIBRATED_DEFAULT] and set(CANDIDATES) <= set(methods)
    raw = methods[UNCALIBRATED_DEFAULT]
    assert raw.flow.photometric == NO_CALIBRATION and raw.sweep.photometric == NO_CALIBRATION
    assert raw.sweep.cost.intensity_weight == 1.0 and raw.quality_flow.photometric == NO_CALIBRATION
    assert raw.flow.rig == NO_RIG_CALIBRATION and raw.quality_flow.rig == NO_RIG_CALIBRATION
    assert raw.sweep.cost.blur_px == 0.0 and raw.sweep.corrected_cost is None
    # a candidate's intensity weight and blur are the cost of images the self-calibration changed
    assert methods["fused-mirror-i0.25"].sweep.corrected_cost.intensity_weight == 0.25
    assert methods["fused-mirror-i0.25"].sweep.cost == raw.sweep.cost
    assert methods["fused-mirror-told-poses"].flow.rig == NO_RIG_CALIBRATION
    assert fused_mirror().sweep.corrected_cost.intensity_weight == 0.25
    chosen = methods["fused-mirror-rig-b0.7"]  # the default is exactly the candidate the selection chose
    assert {**chosen.config(), "label": "fused-mirror"} == fused_mirror().config()
    assert uncalibrated(fused_mirror()).label == "fused-mirror-raw"
    with pytest.raises(UserError, match="candidates"):
        candidate_methods(["fused-mirror-i7"])

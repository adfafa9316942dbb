"""The self-calibration issue's bounds on hand-made results (tools.research.check_calibration): the ideal ratios
against the uncalibrated reference per room family and per frame, each twin condition against the ideal frames."""

from __future__ import annotations

import pandas as pd
import pytest

from harness.data.errors import UserError
from tools.research.check_calibration import check, pooled

# method -> condition -> family -> MAE (two frames per family, 1000 scored pixels each)
MAE = {
    "fused-mirror-raw": {"ideal": {"a": 0.20, "b": 0.10}, "captured": {"a": 2.0, "b": 1.0}},
    "fused-mirror": {"ideal": {"a": 0.20, "b": 0.102}, "captured": {"a": 0.22, "b": 0.11},
                     "tone": {"a": 0.30, "b": 0.11}},
}


def results(changes: dict | None = None) -> pd.DataFrame:
    changes = changes or {}
    rows = []
    for method, conds in MAE.items():
        for cond, fams in conds.items():
            for fam, mae in fams.items():
                for vp in ("vp000", "vp001"):
                    value = changes.get((method, cond, fam, vp), mae)
                    rows.append({"scene": f"{fam}-s1" + ("" if cond == "ideal" else f".{cond}"), "viewpoint": vp,
                                 "method": method, "mae_m": value, "valid_px": 1000, "family": fam,
                                 "condition": "" if cond == "ideal" else cond})
    return pd.DataFrame(rows)


def test_pooled_weights_frames_by_their_scored_pixels():
    rows = pd.DataFrame({"mae_m": [1.0, 4.0], "valid_px": [3000, 1000]})
    assert pooled(rows) == pytest.approx(1.75, abs=1e-12)


def test_bounds_pass_and_fail_where_they_should():
    text, ok = check(results(), "fused-mirror", "fused-mirror-raw")
    # ideal b: 0.102 / 0.100 = 1.02 <= 1.03; captured 0.33 / 0.302; tone pooled 0.41 / 0.302 (family a 1.5 x): fails
    assert "[PASS] ideal: fused-mirror / fused-mirror-raw pooled per room family at most 1.03: worst b 1.020" in text
    assert "[PASS] captured: fused-mirror pooled MAE over its ideal at most 1.15: 1.093" in text
    assert "[FAIL] tone: fused-mirror pooled MAE over its ideal at most 1.15: 1.358" in text
    assert "[FAIL] tone: worst room family at most 1.3: a 1.500" in text and not ok
    assert "| fused-mirror | tone | 0.205 | - | 0.300 | 0.110 |" in text


def test_the_table_gives_the_pooled_mae_as_a_multiple_of_the_pooled_floor():
    table = results()
    table["floor_m"] = 0.05
    table.loc[table["family"] == "b", "floor_m"] = 0.01  # tone: (0.30 + 0.11) / 2 over (0.05 + 0.01) / 2
    text, _ = check(table, "fused-mirror", "fused-mirror-raw")
    assert "| fused-mirror | tone | 0.205 | 6.83 | 0.300 | 0.110 |" in text
    assert pooled(table.iloc[:2], "floor_m") == pytest.approx(0.05, abs=1e-12)


def test_one_bad_ideal_frame_fails_the_per_frame_bound():
    text, _ = check(results({("fused-mirror", "ideal", "a", "vp001"): 0.23}), "fused-mirror", "fused-mirror-raw")
    assert "[FAIL] ideal: fused-mirror / fused-mirror-raw per frame at most 1.1: worst a-s1/vp001 1.150" in text


def test_a_method_without_rows_is_one_line():
    with pytest.raises(UserError, match="no rows of method 'fused-x'"):
        check(results(), "fused-x", "fused-mirror-raw")

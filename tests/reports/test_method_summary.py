"""reports.tables.method_summary: one row per method, means over its frames, best MAE first."""

from __future__ import annotations

import math

import pandas as pd

from reports.tables import SUMMARY_METRICS, method_summary


def _row(method: str, viewpoint: str, mae: float, **kw) -> dict:
    return {"scene": "s", "viewpoint": viewpoint, "method": method, "mae_m": mae, "median_m": mae / 2,
            "delta110": 0.9, "seconds": 1.0, **kw}


def test_means_over_frames_sorted_best_first():
    t = pd.DataFrame([_row("b", "vp0", 0.2), _row("b", "vp1", 0.4, seconds=3.0), _row("a", "vp0", 0.5),
                      _row("c", "vp0", 0.1, delta110=0.5)])
    s = method_summary(t)
    assert list(s.columns) == ["method", "frames", *SUMMARY_METRICS]
    assert list(s.method) == ["c", "b", "a"] and list(s.frames) == [1, 2, 1]
    b = s.set_index("method").loc["b"]
    assert math.isclose(b.mae_m, 0.3, abs_tol=1e-12) and math.isclose(b.median_m, 0.15, abs_tol=1e-12)
    assert math.isclose(b.seconds, 2.0, abs_tol=1e-12) and math.isclose(b.delta110, 0.9, abs_tol=1e-12)


def test_a_missing_value_is_never_dropped_and_goes_last():
    t = pd.DataFrame([_row("x", "vp0", 0.1), _row("x", "vp1", float("nan")), _row("y", "vp0", 9.0),
                      _row("a", "vp0", float("nan"))])
    s = method_summary(t)
    assert list(s.method) == ["y", "a", "x"]  # NaN MAE last, ties by label
    assert math.isnan(s.set_index("method").loc["x"].mae_m)


def test_an_older_results_table_without_delta110_reads_nan():
    t = pd.DataFrame([_row("m", "vp0", 0.1)]).drop(columns="delta110")
    s = method_summary(t)
    assert math.isnan(s.delta110[0]) and s.mae_m[0] == 0.1


def test_times_floor_is_the_mean_over_frames_of_the_per_frame_ratios():
    """Like the MAE column (the mean of the per-frame MAEs), ``mae_x_floor`` is the mean of the per-frame ratios:
    frames of MAE 0.2 / floor 0.1 and 0.4 / 0.05 give (2 + 8) / 2 = 5, not 0.3 / 0.075 = 4."""
    t = pd.DataFrame([_row("m", "vp0", 0.2, floor_m=0.1, mae_x_floor=2.0),
                      _row("m", "vp1", 0.4, floor_m=0.05, mae_x_floor=8.0)])
    s = method_summary(t).set_index("method")
    assert math.isclose(s.loc["m", "mae_x_floor"], 5.0, abs_tol=1e-12)
    assert math.isclose(s.loc["m", "mae_m"], 0.3, abs_tol=1e-12)
    older = method_summary(pd.DataFrame([_row("m", "vp0", 0.1)]))  # results without the floor: NaN, never made up
    assert math.isnan(older.mae_x_floor[0])

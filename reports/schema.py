"""The results schema: one module owns the columns that ``evaluate``/``score`` write and the reports read.

``results.csv`` / ``results.json``: one row per (scene, viewpoint, method); ``regions.csv``: the same metrics per
region of the frame (``reports.regions``).  ``flow``, ``rectify`` and ``variant`` describe flow-pipeline methods
and are empty for other methods.  A frame without ground truth (a real capture) gets rows with empty metrics,
``valid_px`` 0 and the ground-truth-free quality figures (:data:`QUALITY_COLUMNS`), and no region or breakdown rows.
``breakdown.csv``: the same key plus a breakdown kind and bin (long format).

Every scored row (and region row) also carries the frame's floor (:data:`FLOOR_COLUMNS`, ``reports.floor``): the MAE
an ideal matcher with 0.25 px angular error per pair would make over the same pixels, and the row's MAE as a multiple
of it.  The floor is a reference, not a method: it is a column of every method's row rather than a row of its own,
so that every table, leaderboard and regression check that ranks the rows keeps ranking only methods.

Pure: the column lists, their types and the DataFrame constructors.  The files themselves are read and written
by ``harness.data.results`` with these definitions.
"""

from __future__ import annotations

import pandas as pd

from reports.metrics import SUMMARY_KEYS

__all__ = ["KEY_COLUMNS", "FLOW_COLUMNS", "SUITE_COLUMNS", "CALIBRATION_COLUMNS",
           "CORE_METRIC_COLUMNS", "METRIC_COLUMNS", "RESULT_COLUMNS",
           "RESULT_REQUIRED", "REGION_COLUMNS", "REGION_REQUIRED", "BREAKDOWN_COLUMNS", "INT_COLUMNS", "TEXT_COLUMNS",
           "BOOL_COLUMNS", "QUALITY_COLUMNS", "FLOOR_COLUMNS", "unscored_rows", "results_table", "regions_table",
           "breakdown_table"]

#: identify a row
KEY_COLUMNS = ["scene", "viewpoint", "method"]
#: describe the method (flow pipeline only: empty for other methods) and the frame
FLOW_COLUMNS = ["flow", "rectify", "variant"]
#: the first metrics, always present, in the order every results set has had them (``seconds`` is the
#: method's wall time on the frame)
CORE_METRIC_COLUMNS = ["mae_m", "rmse_m", "median_m", "absrel", "delta1", "outlier_rate", "valid_px", "seconds"]
#: the floor of the row's pixels (``reports.floor``; docs/metrics.md, "The floor"): ``floor_m``, the MAE in metres of an
#: ideal matcher whose angular error is ``reports.floor.FLOOR_PX`` = 0.25 px per pair (Gaussian, pairs combined by
#: inverse variance), computed from the truth and the rig over exactly the pixels of the row's ``mae_m`` (the frame's
#: scored pixels, or the region's), and ``mae_x_floor`` = ``mae_m / floor_m`` (unitless; 1 = the ideal matcher).
#: Empty for frames without ground truth; older results sets lack them
FLOOR_COLUMNS = ["floor_m", "mae_x_floor"]
#: every metric of reports.metrics.summary, then ``ause`` (empty where the method gives no confidence), then the
#: :data:`FLOOR_COLUMNS`
METRIC_COLUMNS = [*CORE_METRIC_COLUMNS, *(k for k in SUMMARY_KEYS if k not in CORE_METRIC_COLUMNS), "ause",
                  *FLOOR_COLUMNS]
#: what the frame is (its scene family, difficulty tags joined by ``;``, the condition of its cameras: ``ideal`` or
#: the name of a derived condition such as ``captured``) and, for a suite's split, the suite id and split (empty
#: otherwise); older results sets lack them
SUITE_COLUMNS = ["family", "tags", "suite_id", "split", "condition"]
#: the ground-truth-free quality figures of a prediction (``reconstruction.quality.assess``: medians of its per-pixel
#: maps over the validly predicted pixels, and the calibration check's score), written for frames without ground
#: truth (real captures) and empty for scored frames; older results sets lack them
QUALITY_COLUMNS = ["photometric_residual_median", "distance_residual_m_median", "pair_agreement_median",
                   "uncertainty_median", "calibration_score"]
#: what the method's self-calibration applied on the frame, e.g. ``U gain; U field; R rotation`` (``none``: it ran and
#: found nothing to correct; empty: the method does not self-calibrate); older results sets lack it
CALIBRATION_COLUMNS = ["calibrated"]
RESULT_COLUMNS = ["scene", "viewpoint", "width", "height", "method", *FLOW_COLUMNS, *METRIC_COLUMNS, *SUITE_COLUMNS,
                  *QUALITY_COLUMNS, *CALIBRATION_COLUMNS]
#: the columns a results.csv must have (older results sets lack the later metrics)
RESULT_REQUIRED = ["scene", "viewpoint", "width", "height", "method", *FLOW_COLUMNS, *CORE_METRIC_COLUMNS]
REGION_COLUMNS = [*KEY_COLUMNS, *FLOW_COLUMNS, "region", *(c for c in METRIC_COLUMNS if c != "seconds")]
BREAKDOWN_COLUMNS = [*KEY_COLUMNS, *FLOW_COLUMNS, "kind", "bin_lo", "bin_hi", "mae_m", "median_m", "n_px"]
#: the columns a regions.csv must have (older results sets lack the later metrics)
REGION_REQUIRED = [*KEY_COLUMNS, *FLOW_COLUMNS, "region", *(c for c in CORE_METRIC_COLUMNS if c != "seconds")]
#: whole numbers (never empty)
INT_COLUMNS = {"width", "height", "valid_px", "n_px"}
#: names (strings, never empty; ``flow`` and ``variant`` only in flow-pipeline rows)
TEXT_COLUMNS = {"scene", "viewpoint", "method", "flow", "variant", "kind", "region"}
#: true/false in flow-pipeline rows, empty in the others
BOOL_COLUMNS = {"rectify"}
# every other column is a float (NaN allowed: e.g. a frame with no scored pixel, ``ause`` without confidence)


def unscored_rows(table: pd.DataFrame) -> pd.Series:
    """Per row of a results table, True where nothing was scored: a frame without ground truth (a real capture),
    whose row has ``valid_px`` 0 and empty metrics (``mae_m`` NaN) and carries :data:`QUALITY_COLUMNS` instead.  A
    scored frame always has ``valid_px > 0`` (``evaluate`` refuses a frame with no finite true distance).  A table
    without either column (a partial one) counts as scored."""
    if "valid_px" not in table.columns or "mae_m" not in table.columns:
        return pd.Series(False, index=table.index)
    return (pd.to_numeric(table["valid_px"], errors="coerce") == 0) & table["mae_m"].isna()


def results_table(rows: list[dict]) -> pd.DataFrame:
    """Rows (dicts with at least :data:`RESULT_COLUMNS`) -> the results table, columns in schema order."""
    return pd.DataFrame(rows, columns=RESULT_COLUMNS)


def regions_table(rows: list[dict]) -> pd.DataFrame:
    """Rows (dicts with at least :data:`REGION_COLUMNS`) -> ``regions.csv``'s table, columns in schema order."""
    return pd.DataFrame(rows, columns=REGION_COLUMNS)


def breakdown_table(rows: list[dict]) -> pd.DataFrame:
    """Rows (dicts with at least :data:`BREAKDOWN_COLUMNS`) -> the breakdown table, columns in schema order."""
    return pd.DataFrame(rows, columns=BREAKDOWN_COLUMNS)

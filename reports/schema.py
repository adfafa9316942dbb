"""The results schema: one module owns the columns that ``evaluate``/``score`` write and the reports read.

``results.csv`` / ``results.json``: one row per (scene, viewpoint, method); ``regions.csv``: the same metrics per
region of the frame (``reports.regions``).  ``flow``, ``rectify`` and ``variant`` describe flow-pipeline methods
and are empty for other methods.  ``breakdown.csv``: the same key plus a breakdown kind and bin (long format).

Pure: the column lists, their types and the DataFrame constructors.  The files themselves are read and written
by ``harness.data.results`` with these definitions.
"""

from __future__ import annotations

import pandas as pd

from reports.metrics import SUMMARY_KEYS

__all__ = ["KEY_COLUMNS", "FLOW_COLUMNS", "SUITE_COLUMNS", "CORE_METRIC_COLUMNS", "METRIC_COLUMNS", "RESULT_COLUMNS",
           "RESULT_REQUIRED", "REGION_COLUMNS", "REGION_REQUIRED", "BREAKDOWN_COLUMNS", "INT_COLUMNS", "TEXT_COLUMNS",
           "BOOL_COLUMNS", "results_table", "regions_table", "breakdown_table"]

#: identify a row
KEY_COLUMNS = ["scene", "viewpoint", "method"]
#: describe the method (flow pipeline only: empty for other methods) and the frame
FLOW_COLUMNS = ["flow", "rectify", "variant"]
#: the first metrics, always present, in the order every results set has had them (``seconds`` is the
#: method's wall time on the frame)
CORE_METRIC_COLUMNS = ["mae_m", "rmse_m", "median_m", "absrel", "delta1", "outlier_rate", "valid_px", "seconds"]
#: every metric of reports.metrics.summary, then ``ause`` (empty where the method gives no confidence)
METRIC_COLUMNS = [*CORE_METRIC_COLUMNS, *(k for k in SUMMARY_KEYS if k not in CORE_METRIC_COLUMNS), "ause"]
#: what the frame is (its scene family, difficulty tags joined by ``;``) and, for a suite's split, the suite id and
#: split (empty otherwise); older results sets lack them
SUITE_COLUMNS = ["family", "tags", "suite_id", "split"]
RESULT_COLUMNS = ["scene", "viewpoint", "width", "height", "method", *FLOW_COLUMNS, *METRIC_COLUMNS, *SUITE_COLUMNS]
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


def results_table(rows: list[dict]) -> pd.DataFrame:
    """Rows (dicts with at least :data:`RESULT_COLUMNS`) -> the results table, columns in schema order."""
    return pd.DataFrame(rows, columns=RESULT_COLUMNS)


def regions_table(rows: list[dict]) -> pd.DataFrame:
    """Rows (dicts with at least :data:`REGION_COLUMNS`) -> ``regions.csv``'s table, columns in schema order."""
    return pd.DataFrame(rows, columns=REGION_COLUMNS)


def breakdown_table(rows: list[dict]) -> pd.DataFrame:
    """Rows (dicts with at least :data:`BREAKDOWN_COLUMNS`) -> the breakdown table, columns in schema order."""
    return pd.DataFrame(rows, columns=BREAKDOWN_COLUMNS)

"""The results schema: one module owns the columns that ``evaluate``/``score`` write and the reports read.

``results.csv`` / ``results.json``: one row per (scene, viewpoint, method); ``regions.csv``: the same metrics per
region of the frame (``reports.regions``).  ``flow``, ``rectify`` and
``variant`` describe flow-pipeline methods and are empty for other methods.  ``breakdown.csv``: the same key
plus a breakdown kind and bin (long format).
"""

from __future__ import annotations

from pathlib import Path

import pandas as pd

from harness.data import jsonio
from harness.data.atomic import atomic_write_text
from reports.metrics import SUMMARY_KEYS

__all__ = ["KEY_COLUMNS", "FLOW_COLUMNS", "SUITE_COLUMNS",
           "CORE_METRIC_COLUMNS", "METRIC_COLUMNS", "RESULT_COLUMNS", "RESULT_REQUIRED",
           "REGION_COLUMNS", "BREAKDOWN_COLUMNS", "INT_COLUMNS", "results_table", "regions_table", "breakdown_table",
           "write_results"]

#: identify a row
KEY_COLUMNS = ["scene", "viewpoint", "method"]
#: describe the method (flow pipeline only: empty for other methods) and the frame
FLOW_COLUMNS = ["flow", "rectify", "variant"]
#: the first metrics (DESIGN.md's order; ``seconds`` is the method's wall time on the frame): always present
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
INT_COLUMNS = {"width", "height", "valid_px", "n_px"}


def results_table(rows: list[dict]) -> pd.DataFrame:
    """Rows (dicts with at least :data:`RESULT_COLUMNS`) -> the results table, columns in schema order."""
    return pd.DataFrame(rows, columns=RESULT_COLUMNS)


def regions_table(rows: list[dict]) -> pd.DataFrame:
    """Rows (dicts with at least :data:`REGION_COLUMNS`) -> ``regions.csv``'s table, columns in schema order."""
    return pd.DataFrame(rows, columns=REGION_COLUMNS)


def breakdown_table(rows: list[dict]) -> pd.DataFrame:
    """Rows (dicts with at least :data:`BREAKDOWN_COLUMNS`) -> the breakdown table, columns in schema order."""
    return pd.DataFrame(rows, columns=BREAKDOWN_COLUMNS)


def write_results(out: Path, table: pd.DataFrame, breakdown: pd.DataFrame | None = None,
                  regions: pd.DataFrame | None = None) -> list[Path]:
    """Write ``results.csv``, ``results.json`` and (if given) ``breakdown.csv`` and ``regions.csv`` into ``out``,
    each atomically.

    Returns:
        The paths written.
    """
    out = Path(out)
    table = table[RESULT_COLUMNS]
    written = [out / "results.csv", out / "results.json"]
    atomic_write_text(written[0], table.to_csv(index=False))
    atomic_write_text(written[1], jsonio.dumps(table.to_dict(orient="records")))
    if breakdown is not None:
        written.append(out / "breakdown.csv")
        atomic_write_text(written[-1], breakdown[BREAKDOWN_COLUMNS].to_csv(index=False))
    if regions is not None:
        written.append(out / "regions.csv")
        atomic_write_text(written[-1], regions[REGION_COLUMNS].to_csv(index=False))
    return written

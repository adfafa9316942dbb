"""The robustness study's tables and plots, pure: per-frame rows in, pooled tables, doubling levels, text and PNG out.

The rows (``robustness.csv``, written by ``harness.commands.parts.robustness``) have the columns ``kind, level, unit,
method, frame, mae_m, median_m, valid_px`` (and ``mae_sw_m``, ``valid_sr`` when the results have them); the unperturbed
frames are the rows of kind :data:`NONE_KIND` (level 0), measured once and shared by every kind.

Each kind's curve starts at its *origin* -- the level that stands for "unperturbed" (0 for most kinds; a kind
whose severity grows as its level falls, JPEG quality, puts it at its other end, e.g. 100) -- with the
unperturbed MAE, then runs through the measured levels in order of severity.  :func:`doubling_level` walks it.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
import pandas as pd
from matplotlib.figure import Figure

from reports.plots import png_bytes
from reports.tables import pixel_weighted

__all__ = ["NONE_KIND", "pooled_mae", "doubling_level", "kind_table", "level_plot", "robustness_markdown",
           "format_level"]

NONE_KIND = "none"
"""``kind`` of the rows of the unperturbed frames (level 0)."""


def format_level(level) -> str:
    """A level as short text: ``0.25``, ``1``, ``95`` (``%g`` when that is exact, else ``repr``)."""
    text = format(level, "g")
    return text if float(text) == float(level) else repr(float(level))


def pooled_mae(rows: pd.DataFrame) -> pd.DataFrame:
    """Per (kind, level, method): the MAE over all scored pixels of all frames (each frame's ``mae_m`` weighted by
    its ``valid_px``, :func:`reports.tables.pixel_weighted`) and the number of frames.

    Returns:
        DataFrame with columns ``kind, level, method, mae_m, frames``, in the rows' order of appearance.
    """
    out = []
    for (kind, level, method), sub in rows.groupby(["kind", "level", "method"], sort=False):
        out.append({"kind": kind, "level": level, "method": method,
                    "mae_m": pixel_weighted(sub["mae_m"], sub["valid_px"]), "frames": len(sub)})
    return pd.DataFrame(out, columns=["kind", "level", "method", "mae_m", "frames"])


def doubling_level(origin: float, base: float, levels: Sequence[float], maes: Sequence[float]) -> float:
    """The level at which the MAE first reaches twice ``base``, by linear interpolation along the measured curve.

    The curve is the polyline through ``(origin, base)`` and ``(levels[i], maes[i])`` in the given order (of
    increasing severity).  On the first segment whose end reaches ``2 * base`` the level is interpolated linearly
    between the segment's ends.

    Args:
        origin: the level of the unperturbed frames (0, or e.g. 100 for JPEG quality).
        base: the MAE there (metres).
        levels: measured levels, ordered by severity (same unit as ``origin``).
        maes: the MAE at each of them (metres).
    Returns:
        The level (the unit of ``levels``), or NaN when the MAE stays below ``2 * base`` over the measured range,
        when ``base`` is not a positive number, or when a NaN MAE comes before the crossing.
    """
    if not (isinstance(base, int | float) and math.isfinite(base) and base > 0):
        return float("nan")
    target = 2.0 * base
    x0, y0 = float(origin), float(base)
    for x1, y1 in zip(levels, maes, strict=True):
        x1, y1 = float(x1), float(y1)
        if math.isnan(y1):
            return float("nan")
        if y1 >= target:
            return x1 if y1 == y0 else x0 + (target - y0) * (x1 - x0) / (y1 - y0)
        x0, y0 = x1, y1
    return float("nan")


def kind_table(pooled: pd.DataFrame, kind: str, levels: Sequence[float], origin: float,
               methods: Sequence[str]) -> pd.DataFrame:
    """One kind's table: a row per method, the pooled MAE unperturbed and at each level, and the doubling level.

    Args:
        pooled: :func:`pooled_mae` of every row (the :data:`NONE_KIND` rows included).
        kind: the perturbation kind; levels: its levels in order of severity; origin: see :func:`doubling_level`.
        methods: the method labels, in the order of the rows.
    Returns:
        DataFrame indexed by method, columns ``none``, each level (as :func:`format_level` text) and
        ``doubles_at`` (NaN: never within the measured levels).
    """
    def mae(k, level, method):
        sel = pooled[(pooled["kind"] == k) & (pooled["level"] == level) & (pooled["method"] == method)]
        return float(sel["mae_m"].iloc[0]) if len(sel) else float("nan")

    rows = {}
    for method in methods:
        base = mae(NONE_KIND, 0, method)
        values = [mae(kind, level, method) for level in levels]
        rows[method] = {"none": base, **{format_level(lv): v for lv, v in zip(levels, values, strict=True)},
                        "doubles_at": doubling_level(origin, base, levels, values)}
    return pd.DataFrame.from_dict(rows, orient="index")


def level_plot(table: pd.DataFrame, kind: str, unit: str, levels: Sequence[float], origin: float) -> bytes:
    """PNG: pooled MAE against level, one line per method (a :func:`kind_table`), the unperturbed point at
    ``origin``; a symmetric-log x axis (linear around 0) where the levels span more than 10x."""
    fig = Figure(figsize=(6.4, 4.2))
    ax = fig.add_subplot()
    xs = [float(origin), *(float(v) for v in levels)]
    cols = ["none", *(format_level(v) for v in levels)]
    for method, row in table.iterrows():
        ax.plot(xs, row[cols].to_numpy(float), marker="o", label=str(method))
    positive = [abs(x) for x in xs if x > 0]
    if positive and max(positive) / min(positive) > 10:
        ax.set_xscale("symlog", linthresh=min(positive))
        ax.minorticks_off()
    ax.set_xticks(xs, [f"{format_level(origin)} (none)", *cols[1:]])
    ax.set_xlabel(f"{kind} level ({unit})")
    ax.set_ylabel("MAE (m), pooled over frames")
    ax.set_title(f"MAE vs {kind} level", fontsize=10)
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    return png_bytes(fig)


def _cell(x: float, fmt: str = ".4f") -> str:
    return "-" if x is None or not np.isfinite(x) else format(x, fmt)


def robustness_markdown(title: str, intro: str, tables: dict[str, pd.DataFrame], units: dict[str, str],
                        origins: dict[str, float], plots: dict[str, str]) -> str:
    """The text of ``robustness.md``: ``intro`` (markdown), then per kind its table (pooled MAE in metres per
    method and level, and the level at which it doubles, ``-`` if never within the measured levels) and plot.

    Args:
        title: the heading; tables: kind -> :func:`kind_table`; units: kind -> unit of its level;
        origins: kind -> the level of the unperturbed frames; plots: kind -> the PNG's file name.
    """
    lines = [f"# {title}", "", intro.strip(), ""]
    for kind, table in tables.items():
        cols = [c for c in table.columns if c != "doubles_at"]
        head = [f"none ({format_level(origins[kind])})" if c == "none" else c for c in cols]
        lines += [f"## {kind} ({units[kind]})", "",
                  "| method | " + " | ".join(head) + f" | MAE doubles at ({units[kind]}) |",
                  "|---|" + "---:|" * (len(cols) + 1)]
        for method, row in table.iterrows():
            lines.append(f"| {method} | " + " | ".join(_cell(float(row[c])) for c in cols)
                         + f" | {_cell(float(row['doubles_at']), '.3g')} |")
        if kind in plots:
            lines += ["", f"![MAE vs {kind}]({plots[kind]})"]
        lines.append("")
    return "\n".join(lines)

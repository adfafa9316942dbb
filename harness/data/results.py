"""Results sets on disk: the files ``evaluate`` / ``score`` write and ``report`` reads, with :mod:`reports.schema`.

A results directory holds::

    results.csv, results.json   one row per (scene, viewpoint, method): reports.schema.RESULT_COLUMNS
    regions.csv                 the same metrics per region of each frame: REGION_COLUMNS
    breakdown.csv               errors by angle to each baseline, true distance and texture: BREAKDOWN_COLUMNS
    frames.json                 [{scene, viewpoint, path}, ...]: where each evaluated frame lives
    config.json                 tri360 version, every method's configuration ({"methods": {label: {...}}}), ...
    maps/...                    predicted distance (and confidence) maps, laid out by :func:`map_paths`; for a frame
                                without ground truth also the quality maps (:func:`quality_map_path`)

Every file is written atomically (``harness.data.atomic``) as strict JSON (``harness.data.jsonio``) or CSV.
Readers validate against the schema and raise :class:`harness.data.errors.UserError` with one line naming the
file and what is wrong.
"""

from __future__ import annotations

import json
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd

from harness.data import jsonio
from harness.data.atomic import atomic_write_text
from harness.data.errors import UserError
from harness.data.names import check_name
from reconstruction.methods.flow_pipeline import config_label
from reports.schema import (
    BOOL_COLUMNS,
    BREAKDOWN_COLUMNS,
    CALIBRATION_COLUMNS,
    INT_COLUMNS,
    KEY_COLUMNS,
    REGION_COLUMNS,
    REGION_REQUIRED,
    RESULT_COLUMNS,
    RESULT_REQUIRED,
    SUITE_COLUMNS,
    TEXT_COLUMNS,
    unscored_rows,
)

__all__ = ["RESULTS_CSV", "RESULTS_JSON", "REGIONS_CSV", "BREAKDOWN_CSV", "FRAMES_JSON", "CONFIG_JSON", "MAPS_DIR",
           "map_paths", "quality_map_path", "write_results", "read_results", "read_regions", "read_breakdown",
           "read_frames", "read_method_kinds", "read_config", "ResultsSet", "read_results_set"]

RESULTS_CSV = "results.csv"
RESULTS_JSON = "results.json"
REGIONS_CSV = "regions.csv"
BREAKDOWN_CSV = "breakdown.csv"
FRAMES_JSON = "frames.json"
CONFIG_JSON = "config.json"
MAPS_DIR = "maps"


def map_paths(scene: str, viewpoint: str, method: str, flow: str = "", rectify=False,
              variant: str = "", source: str = "method label") -> tuple[Path, Path]:
    """Where a method's maps of one frame live, relative to the results directory.

    Flow-pipeline methods (``flow`` given): ``maps/<scene>/<viewpoint>/<flow>-<rect|plain>/<variant>.distance.exr``
    (+ ``<variant>.confidence.exr``); every other method: ``maps/<scene>/<viewpoint>/<method>/distance.exr``
    (+ ``confidence.exr``).  NaN, inf and ``<= 0`` in a distance map mean "no prediction".  Every component is
    checked with :func:`harness.data.names.check_name`, so no name can point outside the results directory.

    Args:
        scene, viewpoint: the frame; method: the method's label; flow, rectify, variant: the results columns of
            that name (empty for methods that are not the flow pipeline); source: where ``method`` came from, for
            the message (``--method``, a ``method.json`` path, a results file).
    Returns:
        ``(distance map, confidence map)``; the confidence map exists only for methods that give one.
    Raises:
        UserError: a component that cannot be one path component, naming ``source``.
    """
    base = Path(MAPS_DIR) / check_name(scene, "scene") / check_name(viewpoint, "viewpoint")
    if flow:
        key = base / check_name(config_label(flow, bool(rectify)), f"{source} (flow of {method!r})")
        variant = check_name(str(variant), f"{source} (variant of {method!r})")
        return key / f"{variant}.distance.exr", key / f"{variant}.confidence.exr"
    d = base / check_name(method, source)
    return d / "distance.exr", d / "confidence.exr"


def quality_map_path(scene: str, viewpoint: str, method: str, flow: str = "", rectify=False,
                     variant: str = "", source: str = "method label") -> Path:
    """Where the ground-truth-free quality maps (``reconstruction.quality.assess``: one EXR channel per map) of a
    method's prediction of a frame without ground truth live: beside its distance map (:func:`map_paths`, same
    arguments and checks), ``quality.exr`` for ``distance.exr`` and ``<variant>.quality.exr`` for
    ``<variant>.distance.exr``."""
    dist, _ = map_paths(scene, viewpoint, method, flow, rectify, variant, source)
    return dist.with_name(dist.name[: -len("distance.exr")] + "quality.exr")


# ------------------------------------------------------------------------------------------------ writing


def write_results(out: Path, table: pd.DataFrame, breakdown: pd.DataFrame | None = None,
                  regions: pd.DataFrame | None = None, frames: Sequence[Mapping] | None = None,
                  config: Mapping | None = None) -> list[Path]:
    """Write the files of a results set into ``out``, each atomically: ``results.csv``, ``results.json`` and,
    if given, ``breakdown.csv``, ``regions.csv``, ``frames.json`` (list of ``{scene, viewpoint, path}``) and
    ``config.json``.

    Returns:
        The paths written.
    """
    out = Path(out)
    table = table[RESULT_COLUMNS]
    texts = [(RESULTS_CSV, table.to_csv(index=False)), (RESULTS_JSON, jsonio.dumps(table.to_dict(orient="records")))]
    if breakdown is not None:
        texts.append((BREAKDOWN_CSV, breakdown[BREAKDOWN_COLUMNS].to_csv(index=False)))
    if regions is not None:
        texts.append((REGIONS_CSV, regions[REGION_COLUMNS].to_csv(index=False)))
    if frames is not None:
        texts.append((FRAMES_JSON, jsonio.dumps(list(frames))))
    if config is not None:
        texts.append((CONFIG_JSON, jsonio.dumps(config)))
    written = []
    for name, text in texts:
        atomic_write_text(out / name, text)
        written.append(out / name)
    return written


# ------------------------------------------------------------------------------------------------ reading


def _require_dir(results_dir) -> Path:
    d = Path(results_dir)
    if not d.exists():
        raise UserError(f"{d}: results directory does not exist "
                        f"(write one with `tri360 evaluate DATA --out {d}`)")
    if not d.is_dir():
        raise UserError(f"{d}: not a directory (expected a results directory written by `tri360 evaluate`)")
    return d


def _parse_bool(series: pd.Series, path: Path, column: str) -> pd.Series:
    table = {"true": True, "false": False, "1": True, "0": False, "yes": True, "no": False}
    low = series.astype(str).str.strip().str.lower()
    bad = ~low.isin(list(table))
    if bad.any():
        i = int(np.flatnonzero(bad.to_numpy())[0])
        raise UserError(f"{path}: column {column!r} must be true/false, "
                        f"got {series.iloc[i]!r} in data row {i + 1}")
    return low.map(table).astype(bool)


def _parse_numeric(series: pd.Series, path: Path, column: str) -> pd.Series:
    text = series.astype(str).str.strip()
    num = pd.to_numeric(text, errors="coerce")
    missing = text.str.lower().isin(["", "nan"])
    bad = num.isna() & ~missing
    if bad.any():
        i = int(np.flatnonzero(bad.to_numpy())[0])
        raise UserError(f"{path}: column {column!r} must be numeric, "
                        f"got {series.iloc[i]!r} in data row {i + 1}")
    num = num.astype(np.float64)
    if column in INT_COLUMNS:
        if missing.any():
            i = int(np.flatnonzero(missing.to_numpy())[0])
            raise UserError(f"{path}: column {column!r} is empty in data row {i + 1}")
        if not np.all(np.isfinite(num)) or not np.all(num == np.round(num)):
            raise UserError(f"{path}: column {column!r} must hold whole numbers")
        return num.astype(np.int64)
    return num


def _read_csv(path: Path, columns: list[str], what: str, required: list[str] | None = None) -> pd.DataFrame:
    """A CSV of the schema: exactly ``columns`` (optional ones of older files empty), typed as
    :mod:`reports.schema` says (text, bool, int, float)."""
    if path.exists() and not path.is_file():
        raise UserError(f"{path}: not a regular file ({what})")
    if not path.is_file():
        raise UserError(f"{path}: file is missing ({what})")
    try:
        df = pd.read_csv(path, dtype=str, keep_default_na=False)
    except pd.errors.EmptyDataError:
        raise UserError(f"{path}: file is empty "
                        f"(expected a header with columns {', '.join(columns)})") from None
    except (pd.errors.ParserError, UnicodeDecodeError) as exc:
        raise UserError(f"{path}: not a readable CSV file ({str(exc).strip()})") from None
    except OSError as exc:
        raise UserError(f"{path}: cannot be read ({exc.strerror or exc})") from None
    df.columns = [str(c).strip() for c in df.columns]
    missing = [c for c in (required or columns) if c not in df.columns]
    if missing:
        raise UserError(f"{path}: missing column(s) {', '.join(missing)} (found: {', '.join(df.columns)})")
    if df.empty:
        raise UserError(f"{path}: has a header but no data rows")
    for c in columns:  # optional columns of older files: empty
        if c not in df.columns:
            df[c] = ""
    df = df[columns].copy()
    # flow, rectify and variant describe flow-pipeline methods and are empty for the others
    flow_row = df["flow"].astype(str).str.strip() != "" if "flow" in df.columns else None
    for c in columns:
        if c in BOOL_COLUMNS:
            parsed = _parse_bool(df.loc[flow_row, c], path, c) if flow_row.any() else None
            df[c] = ""
            if parsed is not None:
                df[c] = df[c].astype(object)
                df.loc[flow_row, c] = parsed
        elif c in SUITE_COLUMNS or c in CALIBRATION_COLUMNS:  # may be empty (frames of no suite, or of no known
            # family; methods that do not self-calibrate)
            df[c] = df[c].astype(str).str.strip()
        elif c in TEXT_COLUMNS:
            df[c] = df[c].astype(str).str.strip()
            empty = df[c] == ""
            if c in ("flow", "variant"):
                empty &= flow_row
            if empty.any():
                i = int(np.flatnonzero(empty.to_numpy())[0])
                raise UserError(f"{path}: column {c!r} is empty in data row {i + 1}")
        else:
            df[c] = _parse_numeric(df[c], path, c)
    return df


def _read_json(path: Path):
    """The parsed JSON of ``path``, or None if it does not exist; UserError naming it if it is not JSON."""
    if not path.exists():
        return None
    try:
        return json.loads(path.read_text(encoding="utf-8"))
    except (OSError, json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise UserError(f"{path}: not valid JSON ({exc})") from None


def read_results(results_dir) -> pd.DataFrame:
    """Read and validate ``RESULTS/results.csv``.

    Returns:
        DataFrame with exactly :data:`reports.schema.RESULT_COLUMNS`: strings for names, bool ``rectify`` (empty
        for methods that are not the flow pipeline), int sizes and ``valid_px``, float metrics (NaN allowed,
        e.g. for a frame with no scored pixel).
    Raises:
        UserError: missing/empty directory or file, unreadable CSV, missing columns, no rows, non-numeric
            metrics, non-boolean ``rectify`` in a flow-pipeline row, or duplicate (scene, viewpoint, method) rows.
    """
    d = _require_dir(results_dir)
    path = d / RESULTS_CSV
    if not path.is_file() and not any(d.iterdir()):
        raise UserError(f"{d}: results directory is empty (no results.csv; run `tri360 evaluate` first)")
    df = _read_csv(path, RESULT_COLUMNS, "the per-frame results written by `tri360 evaluate`", RESULT_REQUIRED)
    dup = df.duplicated(KEY_COLUMNS, keep=False)
    if dup.any():
        r = df[dup].iloc[0]
        raise UserError(f"{path}: duplicate rows for scene={r.scene} viewpoint={r.viewpoint} method={r.method}")
    return df.reset_index(drop=True)


def read_breakdown(results_dir) -> pd.DataFrame | None:
    """Read and validate ``RESULTS/breakdown.csv``; ``None`` if the file does not exist.

    Raises:
        UserError: for an unreadable or malformed file (naming it).
    """
    path = Path(results_dir) / BREAKDOWN_CSV
    if not path.exists():
        return None
    return _read_csv(path, BREAKDOWN_COLUMNS, "the error breakdown written by `tri360 evaluate`")


def read_regions(results_dir) -> pd.DataFrame | None:
    """Read and validate ``RESULTS/regions.csv``; ``None`` if the file does not exist (older results sets).

    Returns:
        DataFrame with exactly :data:`reports.schema.REGION_COLUMNS` (types as :func:`read_results`).
    Raises:
        UserError: unreadable or malformed file, or duplicate (scene, viewpoint, method, region) rows.
    """
    path = Path(results_dir) / REGIONS_CSV
    if not path.exists():
        return None
    df = _read_csv(path, REGION_COLUMNS, "the per-region metrics written by `tri360 evaluate`", REGION_REQUIRED)
    dup = df.duplicated([*KEY_COLUMNS, "region"], keep=False)
    if dup.any():
        r = df[dup].iloc[0]
        raise UserError(f"{path}: duplicate rows for scene={r.scene} viewpoint={r.viewpoint} method={r.method} "
                        f"region={r.region}")
    return df.reset_index(drop=True)


def read_frames(results_dir) -> list[dict] | None:
    """Read ``RESULTS/frames.json`` -> list of ``{"scene", "viewpoint", "path"}``; ``None`` if absent.

    Raises:
        UserError: if the file is not valid JSON or not a list of objects with those three string keys.
    """
    path = Path(results_dir) / FRAMES_JSON
    raw = _read_json(path)
    if raw is None:
        return None
    if not isinstance(raw, list):
        raise UserError(f"{path}: must be a JSON list of {{scene, viewpoint, path}} objects")
    out = []
    for i, item in enumerate(raw):
        if not isinstance(item, dict) or not all(isinstance(item.get(k), str) for k in ("scene", "viewpoint",
                                                                                        "path")):
            raise UserError(f"{path}: entry {i} must be an object with string keys scene, viewpoint, path")
        out.append({"scene": item["scene"], "viewpoint": item["viewpoint"], "path": item["path"]})
    return out


def read_config(results_dir) -> dict | None:
    """``RESULTS/config.json`` as written (tri360 version, ``methods`` ``{label: configuration}``, ``frames``...);
    ``None`` if the file does not exist.

    Raises:
        UserError: the file is not valid JSON, not an object, or its ``methods`` entry is not an object.
    """
    path = Path(results_dir) / CONFIG_JSON
    raw = _read_json(path)
    if raw is None:
        return None
    if not isinstance(raw, dict) or not isinstance(raw.get("methods", {}), dict):
        raise UserError(f"{path}: must be a JSON object whose 'methods' is an object {{label: configuration}}")
    return raw


def read_method_kinds(results_dir) -> dict[str, str] | None:
    """``RESULTS/config.json`` -> ``{method label: kind}`` (``flow-pipeline``, ``sweep``, ``predictions``...);
    ``None`` if the file does not exist.  A method whose configuration names no kind is left out.

    Raises:
        UserError: the file is not valid JSON or its ``methods`` entry is not an object.
    """
    path = Path(results_dir) / CONFIG_JSON
    raw = _read_json(path)
    if raw is None:
        return None
    methods = raw.get("methods", {}) if isinstance(raw, dict) else None
    if not isinstance(methods, dict):
        raise UserError(f"{path}: 'methods' must be an object {{label: configuration}}")
    return {str(k): str(v["kind"]) for k, v in methods.items() if isinstance(v, dict) and v.get("kind")}


@dataclass
class ResultsSet:
    """A validated results directory, read whole (the maps stay on disk: :func:`map_paths`).

    Attributes:
        directory: where it was read from.
        results: :func:`read_results`; regions, breakdown, frames: the optional files (None when absent);
        kinds: method label -> kind from ``config.json`` (empty when absent).
        missing: one line per optional file that is absent and what the report lacks without it.
    """

    directory: Path
    results: pd.DataFrame
    regions: pd.DataFrame | None
    breakdown: pd.DataFrame | None
    frames: list[dict] | None
    kinds: dict[str, str] = field(default_factory=dict)
    missing: list[str] = field(default_factory=list)


def read_results_set(results_dir) -> ResultsSet:
    """Read and validate every file of a results directory.

    Raises:
        UserError: a missing/empty directory, a missing or malformed ``results.csv``, or a malformed
            ``regions.csv`` / ``breakdown.csv`` / ``frames.json`` / ``config.json`` (one line naming the file).
    """
    d = Path(results_dir)
    results = read_results(d)
    rs = ResultsSet(d, results, read_regions(d), read_breakdown(d), read_frames(d), read_method_kinds(d) or {})
    scored = not unscored_rows(results).all()  # frames without ground truth have no regions or breakdown
    if rs.regions is None and scored:
        rs.missing.append(f"{d / REGIONS_CSV}: file is missing, so the leaderboard has no per-region MAE")
    if rs.breakdown is None and scored:
        rs.missing.append(f"{d / BREAKDOWN_CSV}: file is missing, so there are no breakdown plots")
    if rs.frames is None:
        rs.missing.append(f"{d / FRAMES_JSON}: file is missing, so there are no error maps, region masks, "
                          "sparsification curves or point clouds")
    return rs

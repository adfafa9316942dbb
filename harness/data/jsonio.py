"""Strict JSON for everything tri360 writes: NaN and infinities become ``null`` (plain ``json.dumps`` writes
the non-standard tokens ``NaN``/``Infinity``, which strict readers reject); numpy scalars and arrays, paths,
mappings, tuples and sets become their JSON equivalents.  The one normalisation of values bound for JSON: what
is compared after a round trip through a file (e.g. a frame's recorded scene parameters) is normalised here on
both sides."""

from __future__ import annotations

import json
import math
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

__all__ = ["to_jsonable", "dumps"]


def to_jsonable(obj: Any) -> Any:
    """A copy of ``obj`` made of dicts, lists, strings, finite floats, ints, bools and None."""
    if isinstance(obj, Mapping):
        return {str(k): to_jsonable(v) for k, v in obj.items()}
    if isinstance(obj, list | tuple | set):
        return [to_jsonable(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return to_jsonable(obj.tolist())
    if isinstance(obj, bool | np.bool_):
        return bool(obj)
    if isinstance(obj, int | np.integer):
        return int(obj)
    if isinstance(obj, float | np.floating):
        return float(obj) if math.isfinite(obj) else None
    if obj is None or isinstance(obj, str):
        return obj
    if isinstance(obj, Path):
        return str(obj)
    return str(obj)


def dumps(obj: Any, indent: int | None = 1) -> str:
    """Strict JSON text of ``obj`` (see :func:`to_jsonable`), with a trailing newline."""
    return json.dumps(to_jsonable(obj), indent=indent, allow_nan=False) + "\n"

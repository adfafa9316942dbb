"""What the default's self-calibration fits on each frame of a data root, and whether it applies it.

Run as::

    python -m tools.research.calibration_floor DATA_ROOT [--out FILE.csv]

For every frame (``frame.json`` below ``DATA_ROOT``) the self-calibration of ``fused-mirror``
(:func:`reconstruction.methods.self_calibration.self_calibrate`, on the frame's images and told poses only) runs once;
one row per frame: its condition (``ideal`` or the twin's), per camera U and R the fitted rotation (degrees) and
its test's p-value (and those of the full-resolution fit that must confirm a rotation before it is applied,
``RigParams.confirm_factor``; empty where none ran), the largest mean channel log gain, the field's log range and the
response's log range (over C's 5th-95th percentile of levels) with theirs, what was applied and which rotations the
pre-pass would have applied but the confirming fit did not support (``not_confirmed``: on those frames the default
answers differently from the same method without the confirming pass).
The floors ``PhotometricParams.min_gain`` / ``min_field`` and ``RigParams.min_degrees`` are read against the
``ideal`` rows: cameras that agree, whose fitted differences are the fit's own error.  Prints the table and, per
condition, the largest of each figure; ``--out`` also writes the rows as CSV.
"""

from __future__ import annotations

from harness.runtime import startup

if __name__ == "__main__":  # run as a script: Ctrl-C during the imports below is one line and 130
    startup.guard("calibration_floor")

import sys
from pathlib import Path

import numpy as np
import pandas as pd

from harness.data.atomic import atomic_write_text
from harness.data.errors import FrameError, UserError
from harness.data.frame import find_frames, read_frame
from harness.runtime.progress import progress_bar
from reconstruction.methods.base import MethodInput
from reconstruction.methods.presets import fused_mirror
from reconstruction.methods.self_calibration import self_calibrate
from tools.common import ArgumentParser, user_error

__all__ = ["calibration_rows", "main"]

PROG = "python -m tools.research.calibration_floor"


def _condition(frame) -> str:
    record = frame.renderer.get("condition") if isinstance(frame.renderer, dict) else None
    return record.get("name", "ideal") if isinstance(record, dict) else "ideal"


def calibration_rows(data_root: Path, progress: bool = True) -> pd.DataFrame:
    """One row per frame of ``data_root``: what the default's self-calibration fitted and applied (module doc)."""
    paths = find_frames(Path(data_root))
    if not paths:
        raise UserError(f"{data_root}: no frames (frame.json) found")
    method = fused_mirror()
    rows = []
    with progress_bar(len(paths), "self-calibration", enabled=progress) as bar:
        for path in paths:
            try:
                frame = read_frame(path)
            except FrameError as exc:
                raise UserError(f"{path}: {exc}") from None
            cal = self_calibrate(MethodInput.of(frame), method.flow.photometric, method.flow.rig, method.flow.limits)
            row = {"scene": frame.scene, "viewpoint": frame.viewpoint, "condition": _condition(frame)}
            photo = cal.record.get("photometric", {})
            for k in ("U", "R"):
                rig = cal.record.get("rig", {}).get(k, {})
                row[f"{k}_rotation_deg"] = rig.get("degrees", np.nan)
                row[f"{k}_rotation_p"] = rig.get("evidence", {}).get("p_value", np.nan)
                confirm = rig.get("confirm", {})
                row[f"{k}_confirm_deg"] = confirm.get("degrees", np.nan)
                row[f"{k}_confirm_p"] = confirm.get("evidence", {}).get("p_value", np.nan)
                fit = photo.get(k, {})
                row[f"{k}_log_gain"] = float(np.abs(np.log(fit["gain_rgb"])).max()) if fit else np.nan
                row[f"{k}_gain_p"] = fit.get("gain", {}).get("p_value", np.nan)
                row[f"{k}_log_field"] = float(np.log(fit["field_range"][1] / fit["field_range"][0])) if fit else np.nan
                row[f"{k}_field_p"] = fit.get("field", {}).get("p_value", np.nan)
                row[f"{k}_log_response"] = fit.get("response_range", np.nan)
                row[f"{k}_response_p"] = fit.get("response", {}).get("p_value", np.nan)
            row["applied"] = "; ".join(cal.applied) or "none"
            row["not_confirmed"] = "; ".join(f"{k} rotation" for k, fit in cal.record.get("rig", {}).items()
                                             if "confirm" in fit and not fit["applied"]) or "none"
            rows.append(row)
            bar.update(1)
    return pd.DataFrame(rows)


def main(argv: list[str] | None = None) -> int:
    parser = ArgumentParser(prog=PROG, description="what the default's self-calibration fits and applies per frame")
    parser.add_argument("data_root", type=Path, metavar="DATA_ROOT")
    parser.add_argument("--out", type=Path, default=None, help="also write the rows as CSV")
    parser.add_argument("--quiet", action="store_true", help="no progress bar")
    args = parser.parse_args(argv)
    try:
        table = calibration_rows(args.data_root, not args.quiet)
    except UserError as exc:
        return user_error(PROG, exc)
    with pd.option_context("display.width", 250, "display.max_columns", 30, "display.max_rows", 500):
        print(table.round(4).to_string(index=False))
        figures = [c for c in table.columns if c.endswith(("_deg", "_log_gain", "_log_field", "_log_response"))]
        print("\nlargest per condition:")
        print(table.groupby("condition")[figures].max().round(4).to_string())
    if args.out is not None:
        atomic_write_text(args.out, table.to_csv(index=False))
    return 0


if __name__ == "__main__":
    sys.exit(startup.run_main(main, "calibration_floor"))

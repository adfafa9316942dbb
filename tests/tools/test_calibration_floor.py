"""What the default's self-calibration fits and applies per frame (tools.research.calibration_floor), on exact
ray-cast frames: nothing on cameras that agree, U's and R's gains on a copy whose cameras differ."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from harness.data.frame import write_frame
from reconstruction.photometry import linear_to_srgb, srgb_to_linear
from tests.helpers import make_synthetic_frame
from tools.research.calibration_floor import calibration_rows, main


@pytest.mark.slow
def test_rows_say_what_was_applied(tmp_path, capsys):
    frame = make_synthetic_frame(width=480)
    write_frame(frame, tmp_path)
    images = dict(frame.images)
    for k, gain in (("U", (1.3, 1.2, 1.1)), ("R", (0.75, 0.8, 0.85))):
        images[k] = linear_to_srgb(srgb_to_linear(frame.images[k]) * np.asarray(gain))
    write_frame(dataclasses.replace(frame, scene=frame.scene + ".gains", images=images), tmp_path)
    rows = calibration_rows(tmp_path, progress=False).set_index("scene")
    assert rows.loc[frame.scene, "applied"] == "none" and rows.loc[frame.scene, "not_confirmed"] == "none"
    assert np.isnan(rows.loc[frame.scene, "U_confirm_deg"])  # no rotation to confirm
    assert rows.loc[frame.scene + ".gains", "applied"] == "U gain; R gain"
    # the fitted gains: ln 1.3 = 0.262 (U's largest channel), ln 0.75 = -0.288 (R's); within 0.01
    assert abs(rows.loc[frame.scene + ".gains", "U_log_gain"] - np.log(1.3)) < 0.01
    assert abs(rows.loc[frame.scene + ".gains", "R_log_gain"] - np.log(1 / 0.75)) < 0.01
    assert main([str(tmp_path), "--quiet", "--out", str(tmp_path / "rows.csv")]) == 0
    assert "largest per condition" in capsys.readouterr().out and (tmp_path / "rows.csv").is_file()


def test_an_empty_root_is_one_line(tmp_path, capsys):
    assert main([str(tmp_path), "--quiet"]) == 2
    assert capsys.readouterr().err.strip().count("\n") == 0

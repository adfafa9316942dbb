"""tri360 import: three JPEGs made from a rendered frame + the example rig -> a frame reconstruct processes."""

from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np
import pytest

from harness.cli import main
from harness.data.frame import read_frame, write_frame
from harness.data.results import read_results
from reports.pointcloud import parse_ply
from tests.helpers import make_synthetic_frame

RIG = Path(__file__).resolve().parents[3] / "examples" / "rig_paper_L_0.4m.json"


@pytest.fixture(scope="module")
def jpegs(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("jpg")
    src = write_frame(make_synthetic_frame(width=120), tmp / "data")
    paths = []
    for n in "CUR":
        cv2.imwrite(str(tmp / f"{n}.jpg"), cv2.imread(str(src / f"{n}.png")), [cv2.IMWRITE_JPEG_QUALITY, 95])
        paths.append(str(tmp / f"{n}.jpg"))
    return paths


@pytest.mark.slow
def test_import_then_reconstruct_gives_cloud_and_no_scores(jpegs, tmp_path, capsys):
    out = tmp_path / "real" / "hall" / "pos1"
    assert main(["import", *jpegs, "--rig", str(RIG), "--out", str(out)]) == 0
    frame = read_frame(out)
    assert not frame.has_ground_truth and (frame.width, frame.height) == (120, 60)
    np.testing.assert_allclose(frame.cameras["U"].position, [0, 0, 0.4])
    np.testing.assert_allclose(frame.cameras["R"].position, [0.4, 0, 0])
    assert frame.renderer["name"] == "import" and set(frame.renderer["sources"]) == {"C", "U", "R"}
    pred = tmp_path / "pred"
    assert main(["reconstruct", str(out), "--out", str(pred), "--method", "dis-rect:gradient", "--quiet"]) == 0
    d = pred / "hall" / "pos1"
    info = json.loads((d / "reconstruction.json").read_text())
    assert "metrics" not in info and "MAE" not in capsys.readouterr().out
    assert set(info["quality"]) >= {"photometric_residual_median", "calibration_score", "calibration_flagged"}
    assert {"distance.exr", "confidence.exr", "quality.exr", "cloud.ply"} <= {p.name for p in d.iterdir()}
    points, colors = parse_ply((d / "cloud.ply").read_bytes())
    assert len(points) == info["cloud_points"] > 0.5 * 120 * 60


def test_import_resizes(jpegs, tmp_path):
    out = tmp_path / "real" / "hall" / "small"
    assert main(["import", *jpegs, "--rig", str(RIG), "--out", str(out), "--width", "80"]) == 0
    assert read_frame(out).width == 80


def test_bad_inputs_are_one_line_exit_2(jpegs, tmp_path, capsys):
    bad = tmp_path / "square.png"
    cv2.imwrite(str(bad), np.zeros((50, 50, 3), np.uint8))
    rig = tmp_path / "rig.json"
    rig.write_text(json.dumps({"format": "tri360-rig/1", "cameras": {"U": {"position": [0, 0, 0.4]}}}))
    out = str(tmp_path / "d" / "s" / "v")
    for argv, culprit in ((["import", str(bad), *jpegs[1:], "--rig", str(RIG), "--out", out], "square.png"),
                          (["import", *jpegs, "--rig", str(rig), "--out", out], "rig.json"),
                          (["import", *jpegs, "--rig", str(RIG), "--out", out, "--width", "81"], "--width"),
                          (["import", *jpegs, "--rig", str(RIG), "--out", str(tmp_path / "d" / "s" / "..")],
                           "--out")):
        assert main(argv) == 2
        err = capsys.readouterr().err.strip()
        assert len(err.splitlines()) == 1 and culprit in err, err
    assert not (tmp_path / "d" / "s" / "v").exists()


@pytest.mark.slow
def test_evaluate_runs_methods_and_scores_nothing(jpegs, tmp_path, capsys):
    """A capture has no ground truth: evaluate runs the methods and scores nothing (the whole workflow with the
    report: tests/harness/commands/test_evaluate_nogt.py)."""
    out = tmp_path / "real" / "hall" / "pos1"
    assert main(["import", *jpegs, "--rig", str(RIG), "--out", str(out)]) == 0
    capsys.readouterr()
    assert main(["evaluate", str(tmp_path / "real"), "--out", str(tmp_path / "res"), "--method", "dis-rect:average",
                 "--no-report", "--quiet"]) == 0
    assert "nothing scored" in capsys.readouterr().out
    table = read_results(tmp_path / "res")
    assert len(table) == 1 and table["valid_px"].iloc[0] == 0 and np.isnan(table["mae_m"].iloc[0])
    assert np.isfinite(table["calibration_score"].iloc[0])

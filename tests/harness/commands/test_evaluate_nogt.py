"""evaluate, score and report on frames without ground truth (real captures): methods run, nothing scored.

The capture: a ray-cast synthetic_box frame's PNGs converted to JPEGs and imported with the example rig
(``tri360 import``), so the frame has no distance files.  No Blender.
"""

from __future__ import annotations

import contextlib
import io
import json
import shutil
from pathlib import Path

import cv2
import numpy as np
import pandas as pd
import pytest

from harness.cli import main
from harness.commands.report import build_report
from harness.data.exr import CONFIDENCE_CHANNEL, DISTANCE_CHANNEL, read_exr_channels, read_float_map
from harness.data.frame import read_frame, write_frame
from harness.data.outputs import MARKER
from harness.data.results import map_paths, quality_map_path, read_results, read_results_set
from reconstruction.methods.base import reference_distance, run_methods, with_references
from reconstruction.methods.presets import fused, fused_mirror
from reconstruction.quality import assess
from reports.pointcloud import parse_ply
from reports.schema import METRIC_COLUMNS, QUALITY_COLUMNS, RESULT_COLUMNS, unscored_rows
from reports.sections import capture_part, quality_part
from reports.tables import NOTHING_SCORED
from tests.helpers import make_synthetic_frame

RIG = Path(__file__).resolve().parents[3] / "examples" / "rig_paper_L_0.4m.json"
WIDTH = 160
METHODS = ["--method", "dis-rect:average", "sweep"]
PNG = b"\x89PNG\r\n\x1a\n"


@pytest.fixture(scope="module")
def capture(tmp_path_factory):
    """``(tmp, data root, frame dir)``: three JPEGs of a rendered frame imported as ``real/hall/pos1``."""
    tmp = tmp_path_factory.mktemp("nogt")
    src = write_frame(make_synthetic_frame(width=WIDTH), tmp / "rendered")
    jpegs = []
    for n in "CUR":
        cv2.imwrite(str(tmp / f"{n}.jpg"), cv2.imread(str(src / f"{n}.png")), [cv2.IMWRITE_JPEG_QUALITY, 92])
        jpegs.append(str(tmp / f"{n}.jpg"))
    frame_dir = tmp / "real" / "hall" / "pos1"
    assert main(["import", *jpegs, "--rig", str(RIG), "--out", str(frame_dir)]) == 0
    assert not read_frame(frame_dir).has_ground_truth
    return tmp, tmp / "real", frame_dir


@pytest.fixture(scope="module")
def results(capture):
    """The results set of ``evaluate`` (with its report) on the capture, and what it printed."""
    tmp, root, _ = capture
    out = tmp / "res"
    cap = {}
    buf_out, buf_err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(buf_out), contextlib.redirect_stderr(buf_err):
        cap["code"] = main(["evaluate", str(root), "--out", str(out), *METHODS, "--quiet"])
    cap["out"], cap["err"] = buf_out.getvalue(), buf_err.getvalue()
    return out, cap


@pytest.mark.slow
def test_evaluate_runs_the_methods_and_scores_nothing(capture, results):
    _, _, frame_dir = capture
    out, cap = results
    assert cap["code"] == 0, cap["err"]
    assert NOTHING_SCORED in cap["out"] and "MAE" not in cap["out"]
    table = read_results(out)  # validates against the schema
    assert sorted(table["method"]) == ["dis-rect:average", "sweep"] and unscored_rows(table).all()
    for c in METRIC_COLUMNS:
        if c == "valid_px":
            assert (table[c] == 0).all()
        elif c == "seconds":
            assert np.isfinite(table[c]).all() and (table[c] >= 0).all()
        else:
            assert table[c].isna().all(), c
    assert not (out / "regions.csv").exists() and not (out / "breakdown.csv").exists()
    assert json.loads((out / MARKER).read_text())["kind"] == "results"
    config = json.loads((out / "config.json").read_text())
    assert config["frames"][0]["ground_truth"] is False and set(config["methods"]) == {"dis-rect:average", "sweep"}
    rows = json.loads((out / "results.json").read_text())
    assert all(r["mae_m"] is None and r["valid_px"] == 0 for r in rows)
    # every quality figure is reconstruction.quality.assess's on the written distance map
    frame = read_frame(frame_dir)
    for _, row in table.iterrows():
        dist_rel, conf_rel = map_paths("hall", "pos1", row["method"], row["flow"], row["rectify"], row["variant"])
        distance = read_float_map(out / dist_rel, DISTANCE_CHANNEL)
        assert distance.shape == (WIDTH // 2, WIDTH) and np.isfinite(distance).mean() > 0.9
        confidence = read_float_map(out / conf_rel, CONFIDENCE_CHANNEL)
        assert confidence.shape == distance.shape
        maps, summary = assess(frame, distance, confidence)  # neither method hands back a reference
        for c in QUALITY_COLUMNS:
            assert np.isfinite(row[c]), c
            assert row[c] == pytest.approx(summary[c], rel=1e-6, abs=1e-9), c
        stored = read_exr_channels(out / quality_map_path("hall", "pos1", row["method"], row["flow"],
                                                          row["rectify"], row["variant"]))
        assert set(stored) == set(maps)
        for k, v in maps.items():
            np.testing.assert_allclose(stored[k], v, rtol=1e-6, atol=1e-6, equal_nan=True)


@pytest.mark.slow
def test_report_shows_clouds_and_maps_and_nothing_scored(capture, results, capsys):
    out, cap = results
    assert cap["code"] == 0, cap["err"]
    html = (out / "report.html").read_text()
    assert NOTHING_SCORED in html and "Quality without ground truth" in html
    assert 'class="problems"' not in html  # nothing missing: no regions/breakdown expected without ground truth
    assert "Leaderboard" not in html and "error maps" not in html and "Sparsification" not in html
    files = {p.relative_to(out).as_posix() for p in out.rglob("*") if p.is_file()}
    assert not [f for f in files if f.endswith("errors.png") or f.endswith("regions.png")]
    assert not {"leaderboard.csv", "mae.md", "fig4_mae.png", "sparsification.png", "error_vs_angle.png"} & files
    assert {"quality.csv", "quality.md", "figures/hall/pos1/maps.png", "figures/hall/pos1/dis-rect.clouds.png",
            "figures/hall/pos1/other-methods.clouds.png"} <= files
    assert (out / "figures/hall/pos1/maps.png").read_bytes().startswith(PNG)
    assert not [f for f in files if "ground_truth" in f]
    table = read_results(out)
    for ply, (method, flow, rect, variant) in {
            "clouds/hall/pos1/dis-rect/average.ply": ("dis-rect:average", "dis", True, "average"),
            "clouds/hall/pos1/sweep.ply": ("sweep", "", "", "")}.items():
        points, colors = parse_ply((out / ply).read_bytes())
        distance = read_float_map(out / map_paths("hall", "pos1", method, flow, rect, variant)[0], DISTANCE_CHANNEL)
        assert len(points) == int(np.count_nonzero(np.isfinite(distance) & (distance > 0))) > 0.9 * WIDTH ** 2 / 2
        assert len(colors) == len(points)
    quality = (out / "quality.md").read_text()
    assert NOTHING_SCORED in quality and all(m in quality for m in table["method"])
    # report again by itself: exit 0, the printed text is the quality table
    capsys.readouterr()
    assert main(["report", str(out), "--ply", "none"]) == 0
    printed = capsys.readouterr().out
    assert "Quality without ground truth" in printed and NOTHING_SCORED in printed and "Leaderboard" not in printed
    assert read_results_set(out).missing == []


@pytest.mark.slow
def test_score_of_predictions_without_ground_truth(capture, tmp_path, capsys):
    """A predictions root (tri360-pred/1) on the capture is scored the same way: nothing scored, quality given."""
    _, root, frame_dir = capture
    pred = tmp_path / "pred"
    assert main(["reconstruct", str(frame_dir), "--out", str(pred), "--method", "dis-rect:average", "--quiet"]) == 0
    res = tmp_path / "res"
    assert main(["score", str(pred), "--data", str(root), "--out", str(res), "--no-report", "--quiet"]) == 0
    assert NOTHING_SCORED in capsys.readouterr().out
    table = read_results(res)
    assert len(table) == 1 and unscored_rows(table).all()
    info = json.loads((pred / "hall" / "pos1" / "reconstruction.json").read_text())
    for c in QUALITY_COLUMNS:  # the same figures as reconstruct's own record of the same map
        assert table[c].iloc[0] == pytest.approx(info["quality"][c], rel=1e-6, abs=1e-9), c


@pytest.mark.slow
def test_mixed_data_root_is_refused_in_one_line(capture, tmp_path, capsys, monkeypatch):
    _, _, frame_dir = capture
    mixed = tmp_path / "mixed"
    shutil.copytree(frame_dir, mixed / "hall" / "pos1")
    scored = write_frame(make_synthetic_frame(width=64), mixed)

    def forbidden(*args, **kwargs):
        raise AssertionError("a method ran before the frames were checked")
    monkeypatch.setattr("harness.commands.evaluate.run_blind", forbidden)
    capsys.readouterr()
    assert main(["evaluate", str(mixed), "--out", str(tmp_path / "res"), *METHODS, "--quiet"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1, err
    assert str(mixed / "hall" / "pos1") in err and str(scored) in err and "no ground-truth" in err, err
    assert not (tmp_path / "res").exists()


@pytest.mark.slow
def test_oracle_needs_ground_truth_refused_before_work(capture, tmp_path, capsys):
    _, root, frame_dir = capture
    capsys.readouterr()
    assert main(["evaluate", str(root), "--out", str(tmp_path / "res"), "--flow", "oracle", "--variants",
                 "average", "--quiet"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and str(frame_dir) in err and "oracle" in err, err
    assert not (tmp_path / "res").exists()


@pytest.mark.slow
def test_capture_and_quality_parts_in_memory(capture):
    """reports.sections on a frame without ground truth: no error map, no ground-truth cloud, every PLY; the
    quality table is empty for scored rows."""
    _, _, frame_dir = capture
    frame = read_frame(frame_dir)
    rng = np.random.default_rng(0)
    d = (2.0 + rng.random((frame.height, frame.width))).astype(np.float32)
    d[0, :7] = np.nan  # no prediction there
    rows = {"m": {"method": "m", "flow": "", "rectify": "", "variant": ""}}
    part = capture_part(frame, rows, {"m": d}, {"m": -np.abs(d - 2.5)},
                        {"m": {"uncertainty": d - 2.0, "photometric_residual": d}}, cloud_points=200)
    assert set(part.files) == {"figures/hall/pos1/maps.png", "figures/hall/pos1/other-methods.clouds.png",
                               "clouds/hall/pos1/m.ply"}
    points, _ = parse_ply(part.files["clouds/hall/pos1/m.ply"])
    assert len(points) == d.size - 7 and not part.curves and NOTHING_SCORED in part.html
    empty = capture_part(frame, rows, {})
    assert empty.html == "" and "no distance map" in empty.problems[0]
    scored_row = {"scene": "s", "viewpoint": "v", "method": "m", "flow": "", "rectify": "", "variant": "",
                  "valid_px": 10, "mae_m": 0.1, "seconds": 1.0}
    assert quality_part(pd.DataFrame([scored_row])).html == ""


SUITE = """\
format = "tri360-suite/1"
name = "one"
description = "one ray-cast frame"

[render]
width = 64

[[frames]]
family = "synthetic_box"
seed = 3
viewpoints = 1
split = "dev"
"""


def test_suite_evaluation_still_needs_ground_truth(tmp_path, capsys):
    suite = tmp_path / "one.toml"
    suite.write_text(SUITE, encoding="utf-8")
    root = tmp_path / "data"
    assert main(["render", "--suite", str(suite), "--split", "dev", "--out", str(root), "--quiet"]) == 0
    (frame,) = [p.parent for p in root.rglob("frame.json")]
    for k in "CUR":
        (frame / f"{k}.distance.exr").unlink()
    capsys.readouterr()
    assert main(["evaluate", str(root), "--suite", str(suite), "--split", "dev", "--out", str(tmp_path / "res"),
                 "--method", "dis-rect:average", "--quiet"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and str(frame) in err and "no ground-truth" in err, err
    assert not (tmp_path / "res").exists()


def test_results_sets_without_quality_columns_still_load(tmp_path):
    """A results.csv of an earlier release (no quality columns) reads with them empty, and counts as scored."""
    old = [c for c in RESULT_COLUMNS if c not in QUALITY_COLUMNS]
    row = {c: "" for c in old} | {"scene": "s", "viewpoint": "v", "width": 64, "height": 32, "method": "m",
                                  "mae_m": 0.1, "valid_px": 100, "seconds": 1.0, **dict.fromkeys(
                                      ("rmse_m", "median_m", "absrel", "delta1", "outlier_rate"), 0.1)}
    (tmp_path / "r").mkdir()
    pd.DataFrame([row], columns=old).to_csv(tmp_path / "r" / "results.csv", index=False)
    table = read_results(tmp_path / "r")
    assert list(table.columns) == RESULT_COLUMNS and table[QUALITY_COLUMNS].isna().all().all()
    assert not unscored_rows(table).any() and quality_part(table).html == ""


@pytest.mark.slow
def test_report_names_a_missing_quality_map_and_still_draws_the_frame(results, tmp_path):
    out, _ = results
    copy = tmp_path / "res"
    shutil.copytree(out, copy)
    (copy / quality_map_path("hall", "pos1", "sweep")).unlink()
    outcome = build_report(copy, ply="none", cloud_points=500)
    assert len(outcome.problems) == 1 and "sweep" in outcome.problems[0] and "quality.exr" in outcome.problems[0]
    html = (copy / "report.html").read_text()
    assert 'class="problems"' in html and "distance, confidence and quality maps" in html


@pytest.mark.slow
def test_a_quality_reference_the_method_does_not_compute_runs_along(capture, tmp_path):
    """The default (fused-mirror) computes no refined flow, but its quality is compared with fused's (its
    ``quality_flow``): evaluate runs that flow method along on a frame without ground truth, reports only the asked
    method, and its disagreement map is assess's with that method's distance as the reference."""
    _, root, frame_dir = capture
    method, flow = fused_mirror(), fused().flow
    assert method.reference_method.label == flow.label != method.flow.label
    assert [m.label for m in with_references([method])] == [method.label, flow.label]
    assert [m.label for m in with_references([method, flow])] == [method.label, flow.label]
    frame = read_frame(frame_dir)
    outputs = run_methods(frame, [method])
    assert outputs[method.label].reference is None  # not computed by the method: not in its time
    ref = reference_distance(frame, method, outputs)  # run now: the outputs lack it
    alone = run_methods(frame, [flow])[flow.label].distance
    np.testing.assert_allclose(ref, alone, rtol=1e-5, atol=1e-5, equal_nan=True)
    out = tmp_path / "res-method"
    assert main(["evaluate", str(root), "--out", str(out), "--method", method.label, "--quiet"]) == 0
    table = read_results(out)
    assert list(table["method"]) == [method.label]
    distance = read_float_map(out / map_paths("hall", "pos1", method.label)[0], DISTANCE_CHANNEL)
    confidence = read_float_map(out / map_paths("hall", "pos1", method.label)[1], CONFIDENCE_CHANNEL)
    stored = read_exr_channels(out / quality_map_path("hall", "pos1", method.label))
    maps, _ = assess(frame, distance, confidence, reference=ref)
    assert "disagreement" in stored
    np.testing.assert_allclose(stored["disagreement"], maps["disagreement"], rtol=1e-4, atol=1e-4, equal_nan=True)

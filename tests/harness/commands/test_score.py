"""`tri360 score`: outside predictions in tri360-pred/1 scored like built-in methods; malformed ones refused."""

from __future__ import annotations

import json

import numpy as np
import OpenEXR
import pandas as pd
import pytest

from harness.cli import main
from harness.commands.evaluate import evaluate
from harness.commands.score import PredictionMethod
from harness.data.frame import read_frame
from harness.data.predictions import write_method_info, write_prediction
from harness.runtime.context import QUIET
from reconstruction.methods.registry import flow_methods
from reports.floor import floor_mae, frame_floor_sigma


def outside_prediction(frame, seed=0):
    """A plausible outside method: truth x (1 + 5 % noise), 2 % of pixels without a prediction (NaN), and a
    confidence that is higher where the error is smaller (plus noise)."""
    rng = np.random.default_rng(seed)
    gt = frame.distance["C"].astype(np.float64)
    pred = gt * (1 + 0.05 * rng.standard_normal(gt.shape))
    pred[rng.random(gt.shape) < 0.02] = np.nan
    pred[~np.isfinite(gt)] = np.nan
    conf = 1.0 / (1.0 + np.abs(pred - gt) + 0.02 * rng.random(gt.shape))
    return pred.astype(np.float32), np.nan_to_num(conf, nan=0.0).astype(np.float32)


def independent_metrics(pred, gt):
    """Straightforward per-pixel loop-free reference of the issue's definitions (not reports.metrics)."""
    scored = np.isfinite(gt) & (gt > 0)
    g = gt[scored].astype(np.float64)
    p = pred[scored].astype(np.float64)
    ok = np.isfinite(p) & (p > 0)
    err = np.abs(np.where(ok, p, 0.0) - g)
    return {"mae_m": err.mean(), "median_m": np.median(err), "rmse_m": np.sqrt((err ** 2).mean()),
            "p90_m": np.percentile(err, 90), "coverage": ok.mean()}


@pytest.fixture
def pred_root(tmp_path, synthetic_root):
    root = tmp_path / "preds"
    frames = {}
    for vp in ("vp000", "vp001"):
        frame = read_frame(synthetic_root / "synthetic_box" / vp)
        pred, conf = outside_prediction(frame, seed=int(vp[-1]))
        write_prediction(root, "synthetic_box", vp, pred, conf)
        frames[vp] = (frame, pred)
    write_method_info(root, {"name": "noisy-outside", "description": "truth + 5 % noise", "url": "https://x.y"})
    return root, frames


def test_score_matches_an_independent_computation(pred_root, synthetic_root, tmp_path, capsys):
    root, frames = pred_root
    out = tmp_path / "res"
    assert main(["score", str(root), "--data", str(synthetic_root), "--out", str(out), "--no-report", "--quiet"]) == 0
    table = pd.read_csv(out / "results.csv")
    assert set(table.method) == {"noisy-outside"}
    for vp, (frame, pred) in frames.items():
        row = table[table.viewpoint == vp].iloc[0]
        ref = independent_metrics(pred, frame.distance["C"])
        for key in ("mae_m", "rmse_m", "coverage"):
            assert row[key] == pytest.approx(ref[key], rel=1e-4), key
        for key in ("median_m", "p90_m"):
            assert row[key] == pytest.approx(ref[key], rel=1e-3), key
        assert np.isfinite(row["ause"]) and row["ause"] >= 0
        assert row["flow"] != row["flow"] or row["flow"] == ""  # empty (NaN in pandas) for outside methods
        # the frame's floor (an ideal matcher's MAE over the same pixels) and the MAE as a multiple of it
        floor = floor_mae(frame_floor_sigma(frame))
        assert row["floor_m"] == pytest.approx(floor, rel=1e-9) and 0 < floor < row["mae_m"]  # metres
        assert row["mae_x_floor"] == pytest.approx(ref["mae_m"] / floor, rel=1e-4)
    regions = pd.read_csv(out / "regions.csv")
    got = set(regions.region)
    assert {"all", "textureless", "discontinuity", "occluded"} <= got
    for vp in frames:
        r_all = regions[(regions.viewpoint == vp) & (regions.region == "all")].iloc[0]
        assert r_all["mae_m"] == table[table.viewpoint == vp].iloc[0]["mae_m"]
    cfg = json.loads((out / "config.json").read_text())
    assert cfg["methods"]["noisy-outside"]["method.json"]["url"] == "https://x.y"
    assert "noisy-outside" in capsys.readouterr().out


@pytest.mark.slow
def test_score_and_evaluate_agree_for_a_builtin_method(synthetic_root, tmp_path):
    """A built-in method scored by evaluate and its predictions scored by score give identical rows."""
    (m,) = flow_methods(["oracle"], [True], ["gradient"])
    direct = evaluate(synthetic_root, tmp_path / "direct", [m], report=False, ctx=QUIET)
    for vp in ("vp000", "vp001"):
        assert main(["reconstruct", str(synthetic_root / "synthetic_box" / vp), "--method", m.label, "--out",
                     str(tmp_path / "preds"), "--quiet"]) == 0
    assert main(["score", str(tmp_path / "preds"), "--data", str(synthetic_root), "--out", str(tmp_path / "scored"),
                 "--no-report", "--quiet"]) == 0
    scored = pd.read_csv(tmp_path / "scored" / "results.csv")
    assert list(scored.method) == [m.label] * 2
    for col in ("mae_m", "median_m", "p90_m", "coverage", "delta1", "bad_1pct", "floor_m", "mae_x_floor"):
        np.testing.assert_allclose(scored[col], direct[col], rtol=1e-6, err_msg=col)


def _exr(path, channels):
    path.parent.mkdir(parents=True, exist_ok=True)
    OpenEXR.File({"type": OpenEXR.scanlineimage}, channels).write(str(path))


@pytest.mark.parametrize("case, expect", [
    ("wrong-size", "size 40x20 != the frame's 200x100"),
    ("wrong-channel", "no channel named 'distance' (found depth)"),
    ("missing-frame", "file is missing"),
    ("all-nan", "no pixel holds a valid prediction"),
    ("negative", "negative distance"),
    ("bad-method-json", "method.json: not valid JSON"),
])
def test_malformed_predictions_are_one_line_naming_the_file(case, expect, pred_root, synthetic_root, tmp_path,
                                                            capsys):
    root, frames = pred_root
    target = root / "synthetic_box" / "vp001" / "distance.exr"
    good = frames["vp001"][1]
    if case == "wrong-size":
        _exr(target, {"distance": np.ones((20, 40), np.float32)})
    elif case == "wrong-channel":
        _exr(target, {"depth": good})
    elif case == "missing-frame":
        target.unlink()
    elif case == "all-nan":
        _exr(target, {"distance": np.full_like(good, np.nan)})
    elif case == "negative":
        bad = good.copy()
        bad[3, 4] = -1.5
        _exr(target, {"distance": bad})
    elif case == "bad-method-json":
        target = root / "method.json"
        target.write_text("{nope")
    out = tmp_path / "res"
    assert main(["score", str(root), "--data", str(synthetic_root), "--out", str(out), "--quiet"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and expect in err[0] and str(target) in err[0], err
    assert not out.exists() and not [p for p in tmp_path.iterdir() if p.name.startswith(".res")]


def test_names_must_match_roots(pred_root, synthetic_root, tmp_path, capsys):
    root, _ = pred_root
    assert main(["score", str(root), str(root), "--data", str(synthetic_root), "--out", str(tmp_path / "r")]) == 2
    assert "both named noisy-outside" in capsys.readouterr().err
    assert main(["score", str(root), "--method", "a", "b", "--data", str(synthetic_root), "--out",
                 str(tmp_path / "r")]) == 2
    assert "2 name(s) for 1 predictions root" in capsys.readouterr().err


def test_prediction_method_reads_confidence(pred_root):
    root, frames = pred_root
    frame = frames["vp000"][0]
    out = PredictionMethod("x", root).run(frame)
    assert out.confidence is not None and out.confidence.shape == (frame.height, frame.width)

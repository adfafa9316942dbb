"""The tri360 command line: reconstruct and evaluate on synthetic frames, and one-line errors."""

import json

import pandas as pd
import pytest

from harness.cli import main
from harness.data.frame import read_distance_exr
from harness.jobs.evaluate import RESULT_COLUMNS


def test_reconstruct_writes_every_variant(synthetic_root, tmp_path, capsys):
    out = tmp_path / "rec"
    assert main(["reconstruct", str(synthetic_root / "synthetic_box" / "vp000"), "--flow", "oracle",
                 "--out", str(out)]) == 0
    text = capsys.readouterr().out
    for v in ("average", "angle", "gradient", "color"):
        d = read_distance_exr(out / f"{v}.distance.exr")
        assert d.shape == (100, 200)
        assert f"{v}" in text
    info = json.loads((out / "reconstruction.json").read_text())
    # oracle: exact geometry (metres); the colour term moves distances by the views' sub-pixel intensity
    # differences, which at this 200 x 100 size (a pixel spans ~3 cm at 1 m) is a few millimetres
    assert all(m["mae_m"] < 1e-3 for v, m in info["metrics"].items() if v != "color")
    assert info["metrics"]["color"]["mae_m"] < 5e-3


def test_evaluate_writes_results_schema(synthetic_root, tmp_path, capsys):
    out = tmp_path / "res"
    assert main(["evaluate", str(synthetic_root), "--out", str(out), "--flow", "oracle", "dis",
                 "--variants", "average", "gradient", "--no-report"]) == 0
    table = pd.read_csv(out / "results.csv")
    assert list(table.columns) == RESULT_COLUMNS
    assert len(table) == 2 * 2 * 2  # frames x flows x variants
    assert (table[table.flow == "oracle"].mae_m < 1e-3).all()
    assert json.loads((out / "results.json").read_text())[0].keys() == set(RESULT_COLUMNS)
    assert (out / "breakdown.csv").exists() and (out / "frames.json").exists()
    assert (out / "maps/synthetic_box/vp001/dis-rect/gradient.distance.exr").exists()
    assert "MAE" in capsys.readouterr().out


@pytest.mark.parametrize("argv, culprit", [
    (["evaluate", "/nonexistent/root"], "/nonexistent/root"),
    (["reconstruct", "/nonexistent/frame", "--out", "x"], "frame.json"),
    (["evaluate", "{root}", "--variants", "average", "bogus"], "bogus"),
])
def test_errors_are_one_line_and_non_zero(argv, culprit, synthetic_root, capsys):
    argv = [a.replace("{root}", str(synthetic_root)) for a in argv]
    assert main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and culprit in err[0] and "error" in err[0]


def test_empty_root_is_an_error(tmp_path, capsys):
    assert main(["evaluate", str(tmp_path)]) == 2
    assert "no tri360 frames" in capsys.readouterr().err


def test_unknown_flow_is_rejected_by_the_parser(synthetic_root):
    with pytest.raises(SystemExit) as exc:
        main(["evaluate", str(synthetic_root), "--flow", "nope"])
    assert exc.value.code == 2

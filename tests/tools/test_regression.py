"""CI accuracy regression (tools.regression): the real run against tests/regression_bounds.json, and
unit tests of ``check`` on hand-made tables."""

from __future__ import annotations

import json
from pathlib import Path

import pandas as pd
import pytest

from reconstruction.methods.flow_pipeline import config_label
from reconstruction.methods.registry import DEFAULT_VARIANTS
from tools.regression import (
    FINAL,
    REGRESSION_METHODS,
    check,
    load_bounds,
    main,
    make_bounds,
    measured_mae,
    measured_text,
    regression_configs,
    run_regression,
    write_bounds,
)

#: the repository's bounds file (the regression job takes it as ``--bounds``: no path is built into the package)
BOUNDS_PATH = Path(__file__).resolve().parents[1] / "regression_bounds.json"

VARIANTS = ["average", "angle", "gradient", "color"]


def _table(values: dict[tuple[str, str, bool, str], list[float]], width: int = 400) -> pd.DataFrame:
    """Results rows from ``{(scene, flow, rectify, variant): [MAE of vp000, vp001, ...]}`` (metres)."""
    rows = [{"scene": s, "viewpoint": f"vp{i:03d}", "width": width, "height": width // 2,
             "method": f"{config_label(f, r)}:{v}", "flow": f, "rectify": r, "variant": v, "mae_m": mae}
            for (s, f, r, v), maes in values.items() for i, mae in enumerate(maes)]
    return pd.DataFrame(rows)


def _good_values() -> dict:
    """Two scenes x two configurations where every refined variant beats average."""
    out = {}
    for scene, n in (("room", 1), ("box", 2)):
        for flow, rect in (("dis", True), ("deepflow-opencv", False)):
            for v, mae in zip(VARIANTS, (0.30, 0.20, 0.21, 0.25), strict=True):
                out[(scene, flow, rect, v)] = [mae] * n
    return out


def _bounds_for(values: dict, margin: float = 0.15) -> dict:
    return make_bounds(_table(values), margin)["bounds"]


def test_check_passes_when_every_mae_is_within_its_bound():
    values = _good_values()
    assert check(_table(values), _bounds_for(values), (400, 200)) == []


def test_check_bound_is_on_the_mean_over_frames():
    values = _good_values()
    bounds = _bounds_for(values, margin=0.10)  # box/dis-rect/angle: 0.22 m
    values[("box", "dis", True, "angle")] = [0.15, 0.285]  # one frame above, mean 0.2175 m below
    assert check(_table(values), bounds) == []
    values[("box", "dis", True, "angle")] = [0.15, 0.295]  # mean 0.2225 m > 0.22 m
    problems = check(_table(values), bounds)
    assert len(problems) == 1 and problems[0].startswith("box/dis-rect/angle: MAE 0.2225 m > bound 0.2200 m")


def test_check_reports_a_bound_exceeded():
    values = _good_values()
    bounds = _bounds_for(values)
    values[("room", "deepflow-opencv", False, "gradient")] = [0.26]  # bound 0.21 x 1.15 = 0.2415 m
    problems = check(_table(values), bounds)
    assert problems == ["room/deepflow-opencv-plain/gradient: MAE 0.2600 m > bound 0.2415 m (+7.7%)"]


def test_check_reports_nan_mae():
    values = _good_values()
    bounds = _bounds_for(values)
    values[("room", "dis", True, "color")] = [float("nan")]
    problems = check(_table(values), bounds)
    assert any(p.startswith("room/dis-rect/color: MAE nan m > bound") for p in problems), problems


def test_check_reports_missing_keys_both_ways():
    values = _good_values()
    bounds = _bounds_for(values)
    del values[("box", "deepflow-opencv", False, "color")]  # a bound without a result
    values[("box", "farneback", True, "average")] = [0.5]  # a result without a bound
    values[("box", "farneback", True, "angle")] = [0.4]
    problems = check(_table(values), bounds)
    assert "box/deepflow-opencv-plain/color: no result (bound 0.2875 m)" in problems
    assert any(p.startswith("box/farneback-rect/average: no bound (measured 0.5000 m") for p in problems)
    assert any(p.startswith("box/farneback-rect/angle: no bound") for p in problems)
    assert len(problems) == 3, problems
    bounds["newscene"] = {"dis-rect": {"average": 1.0}}  # a whole scene missing from the results
    assert "newscene/dis-rect/average: no result (bound 1.0000 m)" in check(_table(values), bounds)


def test_a_method_that_is_no_flow_configuration_has_one_final_bound():
    """``fused`` rows (no flow, rectify or variant) are bounded as ``scene/fused/final``, not compared with average."""
    values = _good_values()
    fused = pd.DataFrame([{"scene": "room", "viewpoint": "vp000", "width": 400, "height": 200, "method": "fused",
                           "flow": float("nan"), "rectify": float("nan"), "variant": float("nan"), "mae_m": 0.1}])
    table = pd.concat([_table(values), fused], ignore_index=True)
    bounds = make_bounds(table, 0.15)["bounds"]
    assert bounds["room"]["fused"] == {FINAL: 0.115}
    assert check(table, bounds) == []
    worse = table.assign(mae_m=[*table.mae_m[:-1], 0.12])
    assert check(worse, bounds) == ["room/fused/final: MAE 0.1200 m > bound 0.1150 m (+4.3%)"]


def test_check_reports_refined_not_beating_average():
    values = _good_values()
    for v in ("angle", "gradient", "color"):  # every refined variant worse than average on one scene
        values[("box", "dis", True, v)] = [0.31, 0.31]
    bounds = {s: {c: {v: 10.0 for v in vs} for c, vs in cs.items()} for s, cs in _bounds_for(values).items()}
    problems = check(_table(values), bounds)
    assert problems == ["box/dis-rect: best refined variant angle (MAE 0.3100 m) does not beat average (0.3000 m)"]
    values[("box", "dis", True, "gradient")] = [0.30, 0.30]  # a tie is not an improvement either
    assert check(_table(values), bounds)[0].startswith("box/dis-rect: best refined variant gradient (MAE 0.3000 m)")
    values[("box", "dis", True, "gradient")] = [0.29, 0.30]  # one refined variant better: fine
    assert check(_table(values), bounds) == []


def test_waiver_excuses_refined_not_beating_average_but_not_the_bounds():
    values = _good_values()
    for v in ("angle", "gradient", "color"):
        values[("room", "deepflow-opencv", False, v)] = [0.35]
    bounds = _bounds_for(values)
    waivers = {"room/deepflow-opencv-plain": "known: outliers"}
    assert check(_table(values), bounds, waivers=waivers) == []
    values[("room", "deepflow-opencv", False, "color")] = [0.45]  # bound 0.35 x 1.15 = 0.4025 m still applies
    assert check(_table(values), bounds, waivers=waivers) == [
        "room/deepflow-opencv-plain/color: MAE 0.4500 m > bound 0.4025 m (+11.8%)"]


def test_stale_waiver_is_reported_and_dropped_on_update():
    values = _good_values()
    waivers = {"room/dis-rect": "was worse once", "box/deepflow-opencv-plain": "still worse", "gone/dis-rect": "x"}
    for v in ("angle", "gradient", "color"):
        values[("box", "deepflow-opencv", False, v)] = [0.4, 0.4]
    data = make_bounds(_table(values), waivers=waivers)
    assert data["waivers"] == {"box/deepflow-opencv-plain": "still worse"}
    problems = check(_table(values), data["bounds"], waivers=waivers)
    assert problems == ["room/dis-rect: waiver no longer needed, best refined variant angle (MAE 0.2000 m) beats "
                        "average (0.3000 m); remove it (make regress-update)"]


def test_check_reports_average_missing_as_uncomparable():
    values = _good_values()
    bounds = _bounds_for(values)
    del values[("room", "dis", True, "average")]
    problems = check(_table(values), bounds)
    assert "room/dis-rect/average: no result (bound 0.3450 m)" in problems
    assert any(p.startswith("room/dis-rect: cannot compare refinement with average") for p in problems)


def test_check_reports_other_resolution():
    values = _good_values()
    bounds = _bounds_for(values)
    problems = check(_table(values, width=200), bounds, (400, 200))
    assert problems == ["box: frames are 200x100, bounds were measured at 400x200",
                        "room: frames are 200x100, bounds were measured at 400x200"]


def test_make_bounds_and_file_round_trip(tmp_path):
    values = _good_values()
    values[("box", "dis", True, "angle")] = [0.1, 0.3]
    data = make_bounds(_table(values), margin=0.15)
    assert data["margin"] == 0.15 and data["resolution"] == [400, 200] and data["frames"] == {"box": 2, "room": 1}
    assert data["measured"]["box"]["dis-rect"]["angle"] == pytest.approx(0.2)
    assert data["bounds"]["box"]["dis-rect"]["angle"] == pytest.approx(0.23)  # 0.2 m x 1.15
    assert all(b >= m * 1.15 - 1e-12 for b, m in zip(*(  # rounded up, never below measured x (1 + margin)
        [x for cs in data[k].values() for vs in cs.values() for x in vs.values()] for k in ("bounds", "measured")),
        strict=True))
    path = tmp_path / "bounds.json"
    write_bounds(data, path)
    text = path.read_text()
    assert json.loads(text) == data and text.index('"bounds"') < text.index('"measured"')
    assert list(json.loads(text)["bounds"]) == ["box", "room"]  # keys sorted for readable diffs
    assert load_bounds(path) == data
    with pytest.raises(ValueError, match="margin"):
        make_bounds(_table(values), margin=-0.1)


def test_load_bounds_errors_name_the_file(tmp_path):
    with pytest.raises(FileNotFoundError, match="regress-update"):
        load_bounds(tmp_path / "missing.json")
    bad = tmp_path / "bad.json"
    bad.write_text('{"margin": 0.15}')
    with pytest.raises(ValueError, match="bad.json"):
        load_bounds(bad)


def test_committed_bounds_cover_every_regression_key():
    """The committed file names every scene x configuration x variant the regression run produces."""

    data = load_bounds(BOUNDS_PATH)
    want = {config_label(f, r) for f, r in regression_configs()}
    for scene in ("classroom", "synthetic_box"):
        assert set(data["bounds"][scene]) == want | set(REGRESSION_METHODS)
        for label in REGRESSION_METHODS:
            assert set(data["bounds"][scene][label]) == {FINAL}
        for label in [*want, *REGRESSION_METHODS]:
            if label not in REGRESSION_METHODS:
                assert set(data["bounds"][scene][label]) == set(DEFAULT_VARIANTS)
            for v, bound in data["bounds"][scene][label].items():
                measured = data["measured"][scene][label][v]
                assert 0 < measured <= bound <= measured * (1 + data["margin"]) + 1e-4


@pytest.mark.blender
def test_accuracy_has_not_regressed(tmp_path):
    """Render the regression set (Cycles classroom + ray-cast synthetic_box), evaluate, check the bounds."""
    data = load_bounds(BOUNDS_PATH)
    width, height = data["resolution"]
    table = run_regression(tmp_path, width=width, samples=data["blender_samples"])
    assert set(table.scene) == set(data["bounds"])
    problems = check(table, data["bounds"], (width, height), data["waivers"])
    got = json.dumps(measured_mae(table), indent=1, sort_keys=True)
    assert problems == [], ("accuracy regressed against tests/regression_bounds.json:\n  " + "\n  ".join(problems)
                            + f"\nmeasured MAE (m):\n{got}\n(if the change is intended: make regress-update)")


def test_measured_text_lists_every_bounds_key():
    values = _good_values()
    lines = measured_text(_table(values)).splitlines()
    assert len(lines) == len(values)
    assert lines[0].split() == ["box/deepflow-opencv-plain/angle", "0.2000"]  # metres, sorted by key


def test_main_needs_a_bounds_file(capsys):
    """The bounds file is named on the command line (found without assuming a source checkout)."""
    with pytest.raises(SystemExit) as info:
        main([])
    assert info.value.code == 2 and "--bounds" in capsys.readouterr().err

"""reports: the leaderboard (methods x overall metrics and region MAEs), sparsification curves, the all-method
error maps and region masks, and reports of results that hold no flow-pipeline method."""

from __future__ import annotations

from html.parser import HTMLParser
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from harness.commands.report import build_report
from harness.data.errors import UserError
from harness.data.exr import CONFIDENCE_CHANNEL, DISTANCE_CHANNEL, read_float_map
from harness.data.frame import read_frame
from harness.data.results import map_paths, read_regions, read_results
from reports import html as H
from reports import plots
from reports.floor import GAUSSIAN_MAE_FACTOR, frame_floor_sigma
from reports.metrics import pooled_sparsification_curves, pooled_summary, sparsification_curves
from reports.regions import regions
from reports.tables import (
    FLOOR_ROW,
    LEADERBOARD_REGIONS,
    PAPER_MAE_M,
    floor_region_display,
    floor_region_table,
    leaderboard_display,
    leaderboard_markdown,
    leaderboard_table,
    pixel_weighted,
)
from tests.reports.test_reports import CONFIGS, OTHERS, VARIANTS, make_results

SCENES = ("room", "hall")  # two frames with different numbers of scored pixels (make_results)


@pytest.fixture(scope="module")
def mixed(tmp_path_factory):
    """A results set with the flow pipeline and two other methods on two frames, and its report."""
    res = make_results(tmp_path_factory.mktemp("mixed"), scenes=SCENES, others=True)
    return res, build_report(res, ply="none", cloud_points=200)


class _Table(HTMLParser):
    """Cells of ``table#leaderboard``: per body row, a list of (text, class, data-v); header attributes."""

    def __init__(self):
        super().__init__()
        self.inside = self.in_body = False
        self.rows, self.heads, self.cell = [], [], None

    def handle_starttag(self, tag, attrs):
        a = dict(attrs)
        if tag == "table" and a.get("id") == "leaderboard":
            self.inside = True
        if not self.inside:
            return
        if tag == "tbody":
            self.in_body = True
        elif tag == "tr" and self.in_body:
            self.rows.append([])
        elif tag == "th" and "data-key" in a:
            self.heads.append(a)
        elif tag == "td":
            self.cell = ["", a.get("class") or "", a.get("data-v")]

    def handle_data(self, data):
        if self.cell is not None:
            self.cell[0] += data

    def handle_endtag(self, tag):
        if tag == "td" and self.cell is not None:
            self.rows[-1].append(tuple(self.cell))
            self.cell = None
        if tag == "table":
            self.inside = self.in_body = False


# --------------------------------------------------------------------------------------------- pooling


def _by_hand_results():
    base = {"flow": "", "rectify": "", "variant": "", "delta110": 0.9, "coverage": 1.0, "bad_5pct": 0.1,
            "median_m": 0.05, "p90_m": 0.2, "ause": 0.01}
    results = pd.DataFrame([
        {**base, "scene": "s", "viewpoint": "a", "method": "m1", "valid_px": 100, "mae_m": 0.1, "coverage": 0.5},
        {**base, "scene": "s", "viewpoint": "b", "method": "m1", "valid_px": 300, "mae_m": 0.2, "ause": np.nan},
        {**base, "scene": "s", "viewpoint": "a", "method": "m0", "valid_px": 100, "mae_m": 0.05},
        {**base, "scene": "s", "viewpoint": "b", "method": "m0", "valid_px": 300, "mae_m": 0.07},
    ])
    region = []
    for method, (m_a, m_b) in {"m1": (0.3, np.nan), "m0": (0.2, 0.4)}.items():
        for vp, mae, n in (("a", m_a, 10), ("b", m_b, 0 if method == "m1" else 30)):
            region.append({"scene": "s", "viewpoint": vp, "method": method, "flow": "", "rectify": "",
                           "variant": "", "region": "textureless", "mae_m": mae, "valid_px": n})
    return results, pd.DataFrame(region)


def test_leaderboard_pools_frames_by_scored_pixels():
    results, region = _by_hand_results()
    t = leaderboard_table(results, region, {"m1": "predictions"}).set_index("method")
    assert t.loc["m1", "mae_m"] == pytest.approx((0.1 * 100 + 0.2 * 300) / 400, abs=1e-12)  # metres
    assert t.loc["m1", "coverage"] == pytest.approx((0.5 * 100 + 1.0 * 300) / 400, abs=1e-12)
    assert np.isnan(t.loc["m1", "ause"])  # a frame without AUSE: no pooled AUSE, never a partial mean
    assert t.loc["m0", "ause"] == pytest.approx(0.01, abs=1e-12)
    # per region: weights are the region's pixels; a frame where the region is empty (NaN MAE) carries none
    assert t.loc["m1", "mae_textureless"] == pytest.approx(0.3, abs=1e-12)
    assert t.loc["m0", "mae_textureless"] == pytest.approx((0.2 * 10 + 0.4 * 30) / 40, abs=1e-12)
    assert np.isnan(t.loc["m0", "mae_pole"])  # no row for that region at all
    assert t.loc["m1", "kind"] == "predictions" and t.loc["m0", "kind"] == ""
    assert list(t.index) == ["m0", "m1", *(f"paper: deepflow-rect:{v}" for v in PAPER_MAE_M)]  # by MAE, then paper
    paper = t[t["source"] == "paper"]
    assert paper["mae_m"].tolist() == list(PAPER_MAE_M.values())
    assert paper.drop(columns=["mae_m", "frames"]).select_dtypes("number").isna().all().all()  # MAE only


def test_leaderboard_floor_is_pooled_and_the_multiple_is_a_ratio_of_pooled_values():
    results, region = _by_hand_results()
    results["floor_m"] = [0.02, 0.05, 0.02, 0.05]  # the frame's floor: the same for every method of a frame
    results["mae_x_floor"] = results["mae_m"] / results["floor_m"]
    t = leaderboard_table(results, region).set_index("method")
    assert t.loc["m1", "floor_m"] == pytest.approx((0.02 * 100 + 0.05 * 300) / 400, abs=1e-12)  # metres
    # (0.1 * 100 + 0.2 * 300) / (0.02 * 100 + 0.05 * 300), not the pixel-weighted mean of the ratios (4.25)
    assert t.loc["m1", "mae_x_floor"] == pytest.approx(0.175 / 0.0425, abs=1e-12)
    assert t.loc["m0", "mae_x_floor"] == pytest.approx(0.065 / 0.0425, abs=1e-12)
    assert t.loc[t["source"] == "paper", ["floor_m", "mae_x_floor"]].isna().all().all()
    assert t.loc["m1", "mae_m"] == pytest.approx(0.175, abs=1e-12)  # the other columns are unchanged
    md = leaderboard_markdown(leaderboard_table(results[results["method"] == "m1"], region))
    assert "| m1 | — | 2 | 0.17500 | 4.12 | 0.04250 |" in md
    # results without the floor (older sets): the columns are empty, never made up
    old = leaderboard_table(results.drop(columns=["floor_m", "mae_x_floor"]), region).set_index("method")
    assert old[["floor_m", "mae_x_floor"]].isna().all().all()


def test_floor_region_table_by_hand():
    results, region = _by_hand_results()
    results["floor_m"] = [0.02, 0.05, 0.02, 0.05]
    region["floor_m"] = [0.1, np.nan, 0.1, 0.2]  # per frame: a 0.1, b 0.2 (NaN where m1's region is empty)
    table = floor_region_table(results, region, methods=["m0", "m1"]).set_index("method")
    assert list(table.index) == [FLOOR_ROW, "m0", "m1"]
    assert list(table.columns) == ["all", *LEADERBOARD_REGIONS]
    assert table.loc[FLOOR_ROW, "all"] == pytest.approx(0.0425, abs=1e-12)  # every frame once, by its pixels
    assert table.loc[FLOOR_ROW, "textureless"] == pytest.approx((0.1 * 10 + 0.2 * 30) / 40, abs=1e-12)
    assert table.loc["m0", "textureless"] == pytest.approx(((0.2 * 10 + 0.4 * 30) / 40) / 0.175, abs=1e-12)
    assert table.loc["m1", "textureless"] == pytest.approx(0.3 / 0.1, abs=1e-12)  # only frame a has the region
    assert table.loc["m0", "all"] == pytest.approx(0.065 / 0.0425, abs=1e-12)
    assert np.isnan(table.loc["m0", "pole"]) and np.isnan(table.loc[FLOOR_ROW, "pole"])  # no rows for it
    view = floor_region_display(table.reset_index())
    assert list(view.iloc[0][["all", "pole"]]) == ["0.04250", "—"] and view.iloc[2]["textureless"] == "3.00"
    no_regions = floor_region_table(results, None)
    assert no_regions[list(LEADERBOARD_REGIONS)].isna().all().all() and no_regions["all"].notna().all()


def test_pixel_weighted_edge_cases():
    assert pixel_weighted([1.0, np.nan], [2, 0]) == 1.0  # NaN without weight is ignored
    assert np.isnan(pixel_weighted([1.0, np.nan], [2, 1]))
    assert np.isnan(pixel_weighted([1.0], [0]))


@pytest.mark.slow
def test_region_and_overall_columns_equal_pooling_the_pixels(mixed):
    """The leaderboard (from the CSVs) equals reports.metrics.pooled_summary over the maps of both frames."""
    res, out = mixed
    results = read_results(res)
    frames = {s: read_frame(res.parent / "data" / s / "v0") for s in SCENES}
    assert len({int(np.isfinite(f.distance["C"]).sum()) for f in frames.values()}) == 2  # weights differ
    masks = {s: regions(f) for s, f in frames.items()}
    board = out.leaderboard.set_index("method")
    for method in ("dis-rect:gradient", "outside", "matcher"):
        items = []
        for s, f in frames.items():
            row = results[(results["method"] == method) & (results["scene"] == s)].iloc[0]
            dist_rel, _ = map_paths(s, "v0", method, row["flow"], row["rectify"], row["variant"])
            items.append((read_float_map(res / dist_rel, DISTANCE_CHANNEL), f.distance["C"]))
        pooled = pooled_summary(items)
        for col in ("mae_m", "bad_5pct", "delta110", "coverage"):
            assert board.loc[method, col] == pytest.approx(pooled[col], abs=1e-9), (method, col)
        compared = 0
        for region in LEADERBOARD_REGIONS:
            pooled = pooled_summary([(p, g, None, masks[s][region]) for (p, g), s in zip(items, SCENES, strict=True)])
            got = board.loc[method, f"mae_{region}"]
            assert got == pytest.approx(pooled["mae_m"], abs=1e-9, nan_ok=True), (method, region)
            compared += bool(np.isfinite(got))
        assert compared >= 5  # discontinuity, epipoles, pole, distance bands hold pixels here
        # the floor pools the frames' ideal-matcher errors over the same pixels: sqrt(2/pi) x their mean sigma
        sigmas = np.concatenate([frame_floor_sigma(f)[np.isfinite(f.distance["C"])] for f in frames.values()])
        assert board.loc[method, "floor_m"] == pytest.approx(GAUSSIAN_MAE_FACTOR * sigmas.mean(), rel=1e-9)
        assert board.loc[method, "mae_x_floor"] == pytest.approx(board.loc[method, "mae_m"] / sigmas.mean()
                                                                 / GAUSSIAN_MAE_FACTOR, rel=1e-9)
    assert board.loc["outside", "coverage"] < 1.0  # its NaN pixels count


@pytest.mark.slow
def test_leaderboard_files_and_html(mixed):
    res, out = mixed
    board = pd.read_csv(res / "leaderboard.csv", keep_default_na=True)
    methods = sorted(set(read_results(res)["method"]))
    assert len(methods) == len(CONFIGS) * len(VARIANTS) + len(OTHERS)
    assert sorted(board.loc[board["source"] == "tri360", "method"]) == methods
    assert list(board.columns[:7]) == ["source", "method", "kind", "flow", "rectify", "variant", "frames"]
    assert [f"mae_{r}" for r in LEADERBOARD_REGIONS] == list(board.columns[-len(LEADERBOARD_REGIONS):])
    assert (board.loc[board["source"] == "tri360", "frames"] == len(SCENES)).all()
    kinds = board.set_index("method")["kind"]
    assert kinds["matcher"] == "sweep" and kinds["outside"] == "predictions" and kinds["dis-rect:color"] == \
        "flow-pipeline"
    md = (res / "leaderboard.md").read_text()
    assert all(f"| {m} |" in md for m in methods) and md.count("| quoted from the paper |") == 3
    assert out.markdown.startswith(md)
    # the floor per region, after the leaderboard: the floor's row, then every method in the leaderboard's order
    floors = floor_region_table(read_results(res), read_regions(res), list(board.loc[board["source"] == "tri360",
                                                                                          "method"]))
    section = md.split("## The floor and the MAE as a multiple of it, per region")[1]
    body = [line for line in section.splitlines() if line.startswith("| ") and not line.startswith("| method")]
    assert [line.split(" | ")[0][2:] for line in body] == [FLOOR_ROW, *board.loc[board["source"] == "tri360",
                                                                                     "method"]]
    assert body[0].split(" | ")[1] == f"{floors['all'].iloc[0]:.5f}"
    ours_by_label = board[board["source"] == "tri360"].set_index("method")
    by_label = floors.set_index("method")
    for region in ("all", "pole", "d<2m"):  # the multiple per region is the region's pooled MAE over its floor
        mae = ours_by_label["mae_m" if region == "all" else f"mae_{region}"]
        assert mae.notna().all(), region
        np.testing.assert_allclose(by_label.loc[mae.index, region] * by_label.loc[FLOOR_ROW, region], mae,
                                   rtol=1e-9, err_msg=region)  # every method has both frames: the same floor
    page = (res / "report.html").read_text()
    assert "<h3>The floor and the MAE as a multiple of it, per region</h3>" in page
    assert '<tr class="reference"><td class="text">floor (m)</td>' in page

    parser = _Table()
    parser.feed((res / "report.html").read_text())
    assert len(parser.rows) == len(methods) + 3
    keys = [h["data-key"] for h in parser.heads]
    assert keys[:4] == ["method", "kind", "frames", "mae_m"]
    better = {h["data-key"]: h["data-better"] for h in parser.heads}
    assert better["mae_m"] == "low" and better["delta110"] == "high" and better["coverage"] == "high"
    assert better["method"] == "" and better["mae_x_floor"] == "low" and better["floor_m"] == "ref"
    # the floor is a reference: sorted as a number, never highlighted
    j_floor = keys.index("floor_m")
    assert not any("best" in r[j_floor][1] for r in parser.rows)
    assert next(h for h in parser.heads if h["data-key"] == "floor_m")["data-type"] == "num"
    # the best cell of every numeric column is the best tri360 value (ties included), never a paper row
    ours = board[board["source"] == "tri360"].reset_index(drop=True)
    for j, key in enumerate(keys):
        if better[key] not in ("low", "high"):
            continue
        marked = [r[0][0] for r in parser.rows if "best" in r[j][1]]
        values = ours[key].to_numpy(dtype=float)
        if np.isnan(values).all():
            assert marked == []
            continue
        target = np.nanmin(values) if better[key] == "low" else np.nanmax(values)
        assert sorted(marked) == sorted(ours.loc[np.abs(values - target) <= 1e-9 * max(1.0, abs(target)),
                                                  "method"]), key
    # sort keys: full precision numbers, empty where there is no value (the paper rows beyond MAE)
    first = parser.rows[0]
    assert float(first[keys.index("mae_m")][2]) == pytest.approx(ours["mae_m"].iloc[0], abs=1e-15)
    paper_row = next(r for r in parser.rows if r[0][0] == "paper: deepflow-rect:gradient")
    assert paper_row[keys.index("mae_m")][0] == "0.10906" and paper_row[keys.index("median_m")][2] == ""


def test_leaderboard_display_and_markdown_of_a_single_method():
    results, region = _by_hand_results()
    table = leaderboard_table(results[results["method"] == "m1"], region)
    view = leaderboard_display(table)
    assert view["row_classes"] == ["", "paper", "paper", "paper"]
    assert view["display"].iloc[0]["coverage (%)"] == "87.50"  # shares shown in percent
    assert view["best"][0, 3] and not view["best"][1:, 3].any()  # one method: it is the best; paper rows never
    assert view["keys"][1][view["columns"].index("median_m")] is None
    md = leaderboard_markdown(table)
    assert "| m1 | — | 2 | 0.17500 |" in md


def test_sortable_table_needs_a_key_per_cell():
    df = pd.DataFrame({"a": ["x"], "b": ["1"]})
    with pytest.raises(ValueError, match="one sort key per cell"):
        H.sortable_table(df, [["x"]], ["", "low"], table_id="t")
    html = H.sortable_table(df, [["x", 1.5]], ["", "low"], table_id="t")
    assert 'data-v="1.5"' in html and 'data-type="num"' in html


# ------------------------------------------------------------------------------------------ sparsification


@pytest.mark.slow
def test_sparsification_curves_pool_frames_like_the_results(mixed):
    res, out = mixed
    results = read_results(res)
    assert sorted(out.sparsification) == ["matcher"]  # the only method with a confidence
    assert (res / "sparsification.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    c = out.sparsification["matcher"]
    rows = results[results["method"] == "matcher"]
    assert c["frames"] == 2 and c["pixels"] == rows["valid_px"].sum()
    # the area between the pooled curves is the pixel-weighted mean of the per-frame AUSE (and the leaderboard's)
    expect = float(np.sum(rows["ause"] * rows["valid_px"]) / rows["valid_px"].sum())
    assert c["ause"] == pytest.approx(expect, abs=1e-9)  # metres
    assert out.leaderboard.set_index("method").loc["matcher", "ause"] == pytest.approx(expect, abs=1e-12)
    assert c["curve"][0] == pytest.approx(out.leaderboard.set_index("method").loc["matcher", "mae_m"], abs=1e-9)
    assert c["fractions"].shape == c["curve"].shape == c["oracle"].shape == (21,)
    assert np.all(c["oracle"] <= c["curve"] + 1e-12)  # nothing beats the oracle
    assert c["curve"][10] < 0.8 * c["curve"][0]  # its confidence ranks the errors: removing half helps


def test_sparsification_of_repeated_frames_is_the_frame_curve():
    rng = np.random.default_rng(3)
    gt = rng.uniform(1, 5, (8, 16))
    pred = gt + rng.normal(0, 0.1, gt.shape)
    conf = -np.abs(pred - gt) + rng.normal(0, 0.05, gt.shape)
    one = sparsification_curves(pred, gt, conf)
    two = pooled_sparsification_curves([(*one, gt.size), (*one, gt.size)])
    np.testing.assert_allclose(two["curve"], one[1], atol=1e-12)
    np.testing.assert_allclose(two["oracle"], one[2], atol=1e-12)
    assert two["frames"] == 2 and two["pixels"] == 2 * gt.size
    with pytest.raises(ValueError, match="scored pixel"):
        pooled_sparsification_curves([(*one, 0)])


def test_pooled_sparsification_is_the_pixel_weighted_mean_and_its_ause():
    """Two frames of 3 and 1 scored pixels: the pooled curve is (3 c1 + c2) / 4 and its AUSE the same mean of the
    frames' AUSE (the area is linear in the curves)."""
    rng = np.random.default_rng(4)
    parts, auses = [], []
    for n in (3, 1):
        gt = rng.uniform(1, 4, (4, 8))
        gt.ravel()[n * 8:] = np.inf  # n rows scored
        pred = gt + rng.normal(0, 0.2, gt.shape)
        conf = rng.normal(size=gt.shape)
        parts.append((*sparsification_curves(pred, gt, conf), n * 8))
        auses.append(pooled_summary([(pred, gt, conf)])["ause"])
    pooled = pooled_sparsification_curves(parts)
    np.testing.assert_allclose(pooled["curve"], (24 * parts[0][1] + 8 * parts[1][1]) / 32, atol=1e-12)
    assert pooled["ause"] == pytest.approx((24 * auses[0] + 8 * auses[1]) / 32, abs=1e-12)  # metres
    assert pooled["frames"] == 2 and pooled["pixels"] == 32
    with pytest.raises(ValueError, match="removal fractions"):
        pooled_sparsification_curves([parts[0], (parts[1][0][::2], parts[1][1][::2], parts[1][2][::2], 8)])


# -------------------------------------------------------------------------------- results without the flow pipeline


@pytest.mark.slow
def test_only_other_methods_give_a_complete_report(tmp_path):
    res = make_results(tmp_path, flow=False, others=True)
    out = build_report(res, ply="all", cloud_points=200)
    assert out.problems == []
    for rel in ("leaderboard.csv", "leaderboard.md", "sparsification.png", "error_vs_angle.png",
                "error_by_distance_texture.png", "figures/room/v0/errors.png", "figures/room/v0/regions.png",
                "figures/room/v0/other-methods.clouds.png", "clouds/room/v0/ground_truth.ply",
                "clouds/room/v0/matcher.ply", "clouds/room/v0/outside.ply", "report.html"):
        assert (res / rel).is_file() and (res / rel).stat().st_size > 0, rel
    assert not (res / "mae.md").exists() and not (res / "fig4_mae.png").exists()
    text = (res / "report.html").read_text()
    assert "no flow-pipeline method" in text
    parser = _Table()
    parser.feed(text)
    assert [r[0][0] for r in parser.rows][:2] == ["matcher", "outside"]  # by MAE (3 % vs 6 % noise)
    assert len(parser.rows) == 2 + 3
    assert text.count("<img ") == 3 + 3  # sparsification, 2 breakdown plots; errors, regions, clouds
    assert out.markdown == (res / "leaderboard.md").read_text()


@pytest.mark.slow
def test_missing_map_of_another_method_is_a_problem_not_fatal(tmp_path):
    res = make_results(tmp_path, others=True)
    (res / "maps/room/v0/outside/distance.exr").unlink()
    (res / "maps/room/v0/matcher/confidence.exr").write_bytes(b"not an exr")
    out = build_report(res, ply="none", cloud_points=100)
    assert any("outside/distance.exr" in p and "missing" in p for p in out.problems)
    assert any("matcher/confidence.exr" in p for p in out.problems)
    assert "matcher" not in out.sparsification  # its confidence could not be read
    assert (res / "figures/room/v0/errors.png").is_file()  # the other methods are still drawn
    assert len(out.leaderboard) == len(CONFIGS) * len(VARIANTS) + len(OTHERS) + 3  # the CSVs still rank all


@pytest.mark.slow
def test_error_maps_hold_every_method(tmp_path, monkeypatch):
    res = make_results(tmp_path, others=True)
    seen = {}

    def spy(gt, preds, title, ncols=None):
        seen[title] = list(preds)
        return real(gt, preds, title, ncols)

    real = plots.error_maps
    monkeypatch.setattr(plots, "error_maps", spy)
    build_report(res, ply="none", cloud_points=100)
    (labels,) = seen.values()
    flow = [f"{f}-{'rect' if r else 'plain'}:{v}" for f, r in CONFIGS for v in VARIANTS]
    assert labels == [*flow, *OTHERS]  # flow configurations (paper set-up first), then the others
    # the maps it read are the ones evaluate wrote, NaN (no prediction) included
    outside = read_float_map(res / "maps/room/v0/outside/distance.exr", DISTANCE_CHANNEL)
    assert np.isnan(outside).sum() == 3
    assert read_float_map(res / "maps/room/v0/matcher/confidence.exr", CONFIDENCE_CHANNEL).shape == outside.shape


def test_read_regions(tmp_path):
    res = make_results(tmp_path)
    table = read_regions(res)
    assert set(table["region"]) == {"all", *LEADERBOARD_REGIONS}
    assert table["valid_px"].dtype == np.int64
    text = (res / "regions.csv").read_text().splitlines()
    (res / "regions.csv").write_text("\n".join([*text, text[1]]) + "\n")
    with pytest.raises(UserError, match=r"regions\.csv: duplicate rows"):
        read_regions(res)
    (res / "regions.csv").unlink()
    assert read_regions(res) is None
    assert read_regions(Path(tmp_path / "nowhere")) is None

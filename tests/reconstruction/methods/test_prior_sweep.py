"""The fused method (sweep with the flow distance as SGM prior), the prior cost, LM started from any distance, and
the flow pipeline's per-pixel confidence."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest

import reconstruction.methods.flow_pipeline as pipeline
from reconstruction.methods import presets
from reconstruction.methods.base import method_groups, run_methods
from reconstruction.methods.flow_refine import refine_variant
from reconstruction.methods.flow_stages import flow_confidence, prepare
from reconstruction.methods.prior_sweep import PriorParams, PriorSweepMethod, prior_weight
from reconstruction.methods.registry import DEFAULT_METHOD, evaluate_default_methods, flow_methods
from reconstruction.methods.sweep import Prior, sweep_distance, sweep_distances
from reconstruction.photometry import NO_CALIBRATION
from reconstruction.refine.lm import get_variant
from reconstruction.rig_calibration import NO_RIG_CALIBRATION
from reconstruction.sweep.planes import add_prior
from tests.helpers import make_synthetic_frame
from tests.reconstruction.sweep.test_sweep import tilted_frame


def uncalibrated(m: PriorSweepMethod) -> PriorSweepMethod:
    """``m`` without photometric or rig self-calibration: the plain sweep then sees exactly the images and poses
    the fused sweep sees (with it, the fused sweep fits the gain field from its prior's correspondences, the plain
    sweep from its coarse pass's, and the fused sweep matches with the flow's self-calibrated poses)."""
    return dataclasses.replace(m, flow=dataclasses.replace(m.flow, photometric=NO_CALIBRATION, rig=NO_RIG_CALIBRATION),
                               sweep=dataclasses.replace(m.sweep, photometric=NO_CALIBRATION))


@pytest.fixture(scope="module")
def frame():
    return make_synthetic_frame(240)


def test_prior_cost_is_zero_at_the_prior_label_and_truncated():
    cost = np.zeros((1, 2, 12), np.uint16)
    inv_d = 0.1 + 0.1 * np.arange(10)  # 10 sphere labels, 0.1 to 1.0 / m
    prior = np.array([[2.0, np.nan]])  # 2 m = 0.5 / m = label 4 at pixel 0, none at pixel 1
    add_prior(cost, 10, inv_d, prior, np.array([[3.0, 3.0]], np.float32), 2.0, 1000)
    np.testing.assert_array_equal(cost[0, 0, :10], [6, 6, 6, 3, 0, 3, 6, 6, 6, 6])
    assert not cost[0, 0, 10:].any() and not cost[0, 1].any()  # plane labels and unset pixels untouched


@pytest.mark.slow
def test_lm_can_start_from_any_distance(frame):
    """Started from the true distance, gradient-LM ends at least as close to it as from the average fusion; with
    ``start`` None the result is the unchanged default."""
    prep = prepare(frame, "dis", True)
    cfg = get_variant("gradient")
    gt = frame.distance["C"]
    ok = np.isfinite(gt)
    d_default, _ = refine_variant(frame, prep, cfg)
    d_none, _ = refine_variant(frame, prep, cfg, start=None)
    np.testing.assert_array_equal(d_default, d_none)
    d_gt, _ = refine_variant(frame, prep, cfg, start=np.where(ok, gt, np.nan))
    assert np.abs(d_gt - gt)[ok].mean() <= np.abs(d_default - gt)[ok].mean() + 1e-3
    conf = flow_confidence(d_default, prep)
    assert conf.shape == gt.shape and conf.dtype == np.float32 and conf.min() >= 0 and conf.max() <= 1
    # pixels whose best pair agrees with the result are more accurate than the others
    err = np.abs(d_default - gt)
    assert err[ok & (conf > 0.5)].mean() < err[ok & (conf <= 0.5)].mean()


@pytest.mark.slow
def test_fused_beats_or_matches_both_parts_on_exact_frame(frame):
    """On an exact ray-cast frame the fused method is within 2 % of the mean distance and gives a confidence."""
    m = presets.fused()
    out = m.run(frame)
    gt = frame.distance["C"]
    ok = np.isfinite(gt)
    mae = np.abs(out.distance[ok] - gt[ok]).mean()
    assert mae <= 0.02 * gt[ok].mean(), mae
    assert out.confidence is not None and 0 <= out.confidence.min() and out.confidence.max() <= 1
    assert {"flow", "cost", "sgm", "wta", "total"} <= set(out.seconds)
    assert out.info["cpu_seconds"]["total"] > 0


@pytest.mark.slow
def test_fused_config_is_json_and_prior_weight_zero_is_the_plain_sweep(frame):
    m = uncalibrated(presets.fused())
    cfg = json.loads(json.dumps(m.config()))
    assert cfg["kind"] == "fused" and cfg["flow"]["label"] == "dis-rect:gradient" and cfg["prior"]["weight"] > 0
    small = make_synthetic_frame(120)
    plain = m.sweep.run(small).distance
    off = PriorSweepMethod(flow=m.flow, sweep=m.sweep, prior=PriorParams(weight=0.0)).run(small).distance
    # two code paths (the sweep alone; the flow, then the sweep with a zero prior): within 1 micrometre, as the
    # shared and the lone sweeps below; one label off would move a pixel by centimetres
    np.testing.assert_allclose(off, plain, rtol=0, atol=1e-6)  # metres
    assert cfg["sweep"]["photometric"]["mode"] == "none"


@pytest.mark.slow
def test_fused_on_tilted_yawed_rig_with_rotated_r():
    """Never an upright rig or shared rotations: pitched/rolled/yawed rig, baseline 0.3 m, R yawed 1.5 deg against C
    (exact ray-cast): within 2 % of the mean distance (measured 0.89 % at 400x200, docs/matching.md)."""
    f = tilted_frame(240)
    out = presets.fused().run(f)
    gt = f.distance["C"]
    ok = np.isfinite(gt)
    assert np.abs(out.distance[ok] - gt[ok]).mean() <= 0.02 * gt[ok].mean()


@pytest.mark.slow
@pytest.mark.parametrize("make", [lambda: make_synthetic_frame(240), lambda: tilted_frame(240)],
                         ids=["synthetic_box", "tilted_rig"])
def test_the_default_and_the_previous_one_are_within_2_percent_on_small_exact_frames(make):
    """``fused-mirror`` (the default; on a box without mirror images it is ``fused-gated`` exactly) and
    ``fused-adaptive`` on exact ray-cast 240x120 frames, upright and tilted/yawed with R yawed against C: MAE within
    2 % of the mean distance (``fused-adaptive`` measured 1.14 % and 1.22 %, against 1.36 % and 1.50 % for
    ``fused``; at 1000x500 see docs/matching.md)."""
    f = make()
    gt = f.distance["C"]
    ok = np.isfinite(gt)
    for method in (presets.fused_mirror(), presets.fused_adaptive()):
        out = method.run(f)
        assert np.abs(out.distance[ok] - gt[ok]).mean() <= 0.02 * gt[ok].mean(), method.label


def test_the_default_is_fused_gated_with_its_mirror_test_cost_labels_room_bound_refill_and_planes():
    """What the default is made of; its values are in the reviewed snapshot (test_presets_snapshot.py)."""
    cfg = json.loads(json.dumps(presets.fused_mirror().config()))
    gated = json.loads(json.dumps(presets.fused_gated().config()))
    assert cfg["kind"] == "fused" and cfg["label"] == "fused-mirror" == DEFAULT_METHOD
    assert cfg["sweep"]["planes"]["mirror_tolerance"] > 0
    assert gated["sweep"]["planes"]["mirror_tolerance"] == 0.0  # 0: no mirror test
    # more sphere labels than gated's, and its least confident pixels refilled (gated refills none)
    assert cfg["sweep"]["cost"]["levels"] > gated["sweep"]["cost"]["levels"]
    assert cfg["sweep"]["post"]["min_confidence"] > 0 == gated["sweep"]["post"]["min_confidence"]
    cfg["sweep"]["post"] = gated["sweep"]["post"]
    # both its costs keep only part of their preference where C shows no texture above its noise (gated: all)
    flat = ("flat_contrast", "flat_weight")
    assert cfg["sweep"]["cost"]["flat_contrast"] > 0 == gated["sweep"]["cost"]["flat_contrast"]
    assert cfg["sweep"]["cost"]["flat_weight"] < 1 == gated["sweep"]["cost"]["flat_weight"]
    assert all(cfg["sweep"]["corrected_cost"][k] == cfg["sweep"]["cost"][k] for k in flat)
    for cost in (cfg["sweep"]["cost"], cfg["sweep"]["corrected_cost"]):
        cost.update({k: gated["sweep"]["cost"][k] for k in flat})
    # otherwise its own cost is gated's; the lighter intensity term, the blur and the noise's blur only when the
    # self-calibration corrected the images
    assert cfg["sweep"]["cost"] == {**gated["sweep"]["cost"], "levels": cfg["sweep"]["cost"]["levels"]}
    corrected = cfg["sweep"].pop("corrected_cost")
    changed = ("intensity_weight", "blur_px", "noise_blur", "noise_floor", "noise_scale", "levels")
    assert corrected == {**gated["sweep"]["cost"], **{k: corrected[k] for k in changed}}
    assert corrected["levels"] == cfg["sweep"]["cost"]["levels"]
    cfg["sweep"]["cost"]["levels"] = gated["sweep"]["cost"]["levels"]
    assert corrected["blur_px"] > 0 and corrected["noise_blur"] > 0 and corrected["noise_scale"] > 1
    assert corrected["intensity_weight"] < gated["sweep"]["cost"]["intensity_weight"]
    cfg["sweep"]["planes"]["mirror_tolerance"] = 0.0
    # the room bound closer to the floor and ceiling the coarse pass found
    assert cfg["sweep"]["planes"]["bound_margin"] < gated["sweep"]["planes"]["bound_margin"]
    cfg["sweep"]["planes"]["bound_margin"] = gated["sweep"]["planes"]["bound_margin"]
    # a match beyond the bound dearer and put on the floor (gated: forbidden) ...
    assert cfg["sweep"]["planes"]["bound_penalty"] > 0 == gated["sweep"]["planes"]["bound_penalty"]
    cfg["sweep"]["planes"]["bound_penalty"] = 0.0
    # ... away from the horizon only
    assert 0 < cfg["sweep"]["planes"]["bound_penalty_min_az"] < 1
    cfg["sweep"]["planes"]["bound_penalty_min_az"] = gated["sweep"]["planes"]["bound_penalty_min_az"]
    # the walls' yaw where the walls hold the most points when the surface normals' vote finds none (gated: the vote)
    assert (cfg["sweep"]["planes"]["wall_yaw"], gated["sweep"]["planes"]["wall_yaw"]) == ("normals-or-offsets",
                                                                                          "normals")
    cfg["sweep"]["planes"]["wall_yaw"] = "normals"
    # its floor and ceiling searched again from the images, what lies beyond a wall put on it, and where no wall
    # found encloses a side, the ceiling's edge, and a wall with more beyond it that the ceiling stops at (gated:
    # none of it)
    assert "refine_planes" not in gated["sweep"]
    refine = cfg["sweep"].pop("refine_planes")
    assert refine["max_se"] > 0 and refine["wall_margin"] > 0 and 0 < refine["ceiling_edge"] < 1
    assert refine["wall_max_share"] < refine["closed_max_share"] < 1 and 0 < refine["closed_ceiling_share"] < 1
    # its prior spares the frame's share at U's epipoles on a noisy rig where the flow is on the room's plane
    cone = ("epipole_cone_deg", "epipole_cone_noise_low", "epipole_cone_noise_high", "epipole_cone_room")
    assert all(cfg["prior"][k] > 0 == gated["prior"][k] for k in cone)
    cfg["prior"].update({k: gated["prior"][k] for k in cone})
    assert {**cfg, "label": "fused-gated"} == gated


def test_fused_gated_is_the_gated_prior_from_the_unrefined_flow_with_wall_families():
    cfg = json.loads(json.dumps(presets.fused_gated().config()))
    assert cfg["kind"] == "fused" and cfg["label"] == "fused-gated"
    assert cfg["sweep"] == json.loads(json.dumps(presets.fused_adaptive().config()))["sweep"]
    assert cfg["sweep"]["planes"]["wall_labels"] > 0
    assert presets.fused_gated().flow.label == "dis-rect:average"  # no LM: no slower than fused
    gated = presets.fused_gated().prior
    # gated by C's contrast, the plain sweep's confidence and the frame's agreement (each 0 = off)
    assert cfg["prior"] == dataclasses.asdict(gated)
    assert gated.contrast_high > 0 and gated.sweep_confidence_power > 0 and gated.frame_agreement_high > 0
    assert cfg["prior"]["weight"] == json.loads(json.dumps(presets.fused().config()))["prior"]["weight"]


def test_fused_adaptive_is_fused_with_wall_families_and_the_frame_agreement_gate():
    cfg = json.loads(json.dumps(presets.fused_adaptive().config()))
    assert cfg["kind"] == "fused" and cfg["label"] == "fused-adaptive"
    assert cfg["sweep"]["planes"]["wall_labels"] > 0
    assert cfg["prior"]["frame_agreement_high"] > 0 and cfg["prior"]["contrast_high"] == 0
    base = json.loads(json.dumps(presets.fused().config()))
    assert cfg["flow"] == base["flow"] and cfg["prior"]["weight"] == base["prior"]["weight"]
    assert presets.fused_adaptive().prior.needs_plain_sweep


def test_prior_weight_defaults_to_one_constant_and_gates_by_contrast_and_confidence():
    rng = np.random.default_rng(0)
    image = np.zeros((40, 80, 3), np.uint8)
    image[:, 40:] = rng.integers(0, 256, (40, 40, 3), dtype=np.uint8)  # left half plain, right half textured
    conf = np.full((40, 80), 0.5, np.float32)
    np.testing.assert_array_equal(prior_weight(PriorParams(), image, conf), np.full((40, 80), 16.0, np.float32))
    gated = prior_weight(PriorParams(contrast_low=1.0, contrast_high=4.0), image, None)
    assert gated[:, 12:28].max() == 0.0 and gated[:, 52:68].min() == 16.0  # 3 sigma from the seam and the edge
    both = prior_weight(PriorParams(use_confidence=True, contrast_low=1.0, contrast_high=4.0), image, conf)
    np.testing.assert_allclose(both, 0.5 * gated, atol=1e-6)
    with pytest.raises(ValueError, match="contrast_low 4.0 must be below contrast_high 2.0"):
        PriorParams(contrast_low=4.0, contrast_high=2.0)


def test_the_contrast_gate_reads_the_contrast_above_the_noise():
    """``contrast_noise``: a plain image with noise of about 3 gray levels opens the plain gate (its local contrast is
    the noise's) and not the one that reads the contrast above the noise; a textured half (standard deviation about
    74 gray levels) is gated open either way; a noise-free plain image is gated shut either way."""
    rng = np.random.default_rng(1)
    plain = np.full((60, 120, 3), 128.0)
    image = np.clip(plain + rng.normal(0.0, 3.0, (60, 120, 1)), 0, 255).astype(np.uint8)
    image[:, 60:] = rng.integers(0, 256, (60, 60, 1), dtype=np.uint8)
    gate = PriorParams(contrast_low=0.5, contrast_high=2.0)
    above = PriorParams(contrast_low=0.5, contrast_high=2.0, contrast_noise=1.0)
    plain_part, textured = (slice(None), slice(12, 48)), (slice(None), slice(72, 108))
    assert prior_weight(gate, image, None)[plain_part].mean() > 14.0
    assert prior_weight(above, image, None)[plain_part].mean() < 4.0
    assert prior_weight(above, image, None)[textured].min() == 16.0
    flat = plain.astype(np.uint8)
    assert prior_weight(above, flat, None).max() == 0.0 and prior_weight(gate, flat, None).max() == 0.0
    with pytest.raises(ValueError, match="contrast_noise must be >= 0"):
        PriorParams(contrast_noise=-1.0)


@pytest.mark.slow
def test_one_cost_volume_for_several_priors_gives_each_prior_its_own_sweep():
    """``sweep_distances`` shares the room-bound pass and the cost volume: each result equals the sweep run alone
    with that prior (within 1 micrometre)."""
    f = make_synthetic_frame(120)
    s = dataclasses.replace(presets.fused().sweep, photometric=NO_CALIBRATION)
    prior_d = f.distance["C"] * 1.1
    priors = [None, Prior(prior_d, np.full(prior_d.shape, 16.0, np.float32), 16.0),
              Prior(prior_d, np.full(prior_d.shape, 64.0, np.float32), 16.0)]
    shared = sweep_distances(f, s, priors)
    assert len(shared) == 3 and shared[0][3]["copy_seconds"] > 0 and shared[2][3]["copy_seconds"] == 0
    assert shared[1][2].keys() == shared[2][2].keys()  # the copy is the price of sharing: no stage of its own
    for prior, (d, conf, _seconds, _info) in zip(priors, shared, strict=True):
        alone = sweep_distance(f, s, prior=prior)
        np.testing.assert_allclose(d, alone[0], rtol=0, atol=1e-6)
        np.testing.assert_allclose(conf, alone[1], rtol=0, atol=1e-6)
    assert not np.array_equal(shared[0][0], shared[2][0])  # the strong prior changed the result


@pytest.mark.slow
def test_default_evaluate_computes_the_flow_once_for_fused_and_the_flow_methods(monkeypatch):
    """``fused`` declares the work it shares: with the default methods, the dis-rect flow, triangulation and LM run
    once per frame (one ``reconstruct`` call for fused and the four dis-rect variants), and fused's result is the
    same as alone (within 1 micrometre)."""
    f = make_synthetic_frame(120)
    methods = [presets.fused_mirror(), presets.fused(),
               *(m for m in evaluate_default_methods() if m.label.startswith("dis-rect:"))]
    assert evaluate_default_methods()[0].label == DEFAULT_METHOD == "fused-mirror"
    extra = PriorSweepMethod(flow=methods[1].flow, prior=PriorParams(use_confidence=True), label="fused-conf")
    methods.append(extra)
    assert len(method_groups(methods)) == 1
    calls = []
    real = pipeline.reconstruct

    def counting(frame, *args, **kwargs):
        calls.append(args)
        return real(frame, *args, **kwargs)

    monkeypatch.setattr(pipeline, "reconstruct", counting)
    outs = run_methods(f, methods)
    assert len(calls) == 1
    assert list(outs) == [m.label for m in methods]
    alone = presets.fused().run(f)
    np.testing.assert_allclose(outs["fused"].distance, alone.distance, rtol=0, atol=1e-6)
    np.testing.assert_allclose(outs["fused-mirror"].distance, presets.fused_mirror().run(f).distance, rtol=0, atol=1e-6)
    assert outs["fused-mirror"].seconds["flow"] == pytest.approx(outs["dis-rect:average"].total_seconds)
    assert outs["fused"].seconds["flow"] == pytest.approx(outs["dis-rect:gradient"].total_seconds)
    np.testing.assert_allclose(outs["dis-rect:gradient"].distance,
                               flow_methods(["dis"], [True], ["gradient"])[0].run(f).distance, rtol=0, atol=1e-6)
    assert not np.array_equal(outs["fused-conf"].distance, outs["fused"].distance)


def test_a_group_of_two_flow_configurations_is_refused():
    f = make_synthetic_frame(120)
    other = PriorSweepMethod(flow=flow_methods(["farneback"], [True], ["gradient"])[0], label="fused-farneback")
    with pytest.raises(ValueError, match="different flow configurations.*fused-farneback"):
        presets.fused().run_group(f, [presets.fused(), other])


def test_sweep_gate_keeps_a_confident_sweep_and_scales_by_the_frames_agreement():
    from reconstruction.methods.prior_sweep import sweep_gate

    flow = np.full((2, 4), 2.0)
    sweep = np.array([[2.0, 2.05, 3.0, 3.0], [2.0, 2.0, 3.0, 3.0]])  # 4 of 8 agree within 5 %
    conf = np.array([[0.0, 0.0, 1.0, 0.5], [1.0, 1.0, 0.0, 0.5]])
    g = sweep_gate(PriorParams(sweep_confidence_power=2.0), flow, sweep, conf)
    np.testing.assert_allclose(g, [[1, 1, 0, 0.25], [1, 1, 1, 0.25]], atol=1e-6)
    g = sweep_gate(PriorParams(frame_agreement_low=0.4, frame_agreement_high=0.6), flow, sweep, conf)
    np.testing.assert_allclose(g, 0.5, atol=1e-6)  # agreement 0.5: half way up the ramp
    g = sweep_gate(PriorParams(frame_agreement_low=0.6, frame_agreement_high=0.8), flow, sweep, conf)
    np.testing.assert_allclose(g, 0.0, atol=1e-6)
    with pytest.raises(ValueError, match="frame_agreement_low 0.8 must be below frame_agreement_high 0.6"):
        PriorParams(frame_agreement_low=0.8, frame_agreement_high=0.6)


def test_the_frames_agreement_share_can_count_only_the_pixels_with_texture_above_the_noise():
    """``frame_agreement_contrast``: flow and sweep agree on the textured half of C and disagree on its plain,
    noisy half.  Over every pixel the share is 0.5 (no prior with the ramp 0.6-0.8); over the pixels whose contrast
    above the noise is at least 4 gray levels it is 1 (the full prior).  Without a textured pixel: no prior."""
    from reconstruction.methods.prior_sweep import contrast_above_noise, sweep_gate

    rng = np.random.default_rng(2)
    image = np.clip(128.0 + rng.normal(0.0, 3.0, (60, 120, 1)), 0, 255).astype(np.uint8).repeat(3, axis=2)
    image[:, 60:] = rng.integers(0, 256, (60, 60, 1), dtype=np.uint8)
    flow = np.full((60, 120), 2.0)
    sweep = np.where(np.arange(120) < 60, 3.0, 2.0)[None, :].repeat(60, axis=0)
    conf = np.zeros((60, 120), np.float32)
    every = PriorParams(frame_agreement_low=0.6, frame_agreement_high=0.8)
    textured = dataclasses.replace(every, frame_agreement_contrast=4.0)
    np.testing.assert_allclose(sweep_gate(every, flow, sweep, conf, image), 0.0, atol=1e-6)
    np.testing.assert_allclose(sweep_gate(textured, flow, sweep, conf, image), 1.0, atol=1e-6)
    # the plain half's contrast as it is is its noise (above 2 gray levels); above the noise it is below 4
    c, above = contrast_above_noise(image, 3.0, 0.0), contrast_above_noise(image, 3.0)
    assert np.median(c[:, 12:48]) > 2.0 and np.percentile(above[:, 12:48], 99) < 4.0
    plain = np.full_like(image, 128)
    np.testing.assert_allclose(sweep_gate(textured, flow, sweep, conf, plain), 0.0, atol=1e-6)
    with pytest.raises(ValueError, match="needs C's image"):
        sweep_gate(textured, flow, sweep, conf)
    with pytest.raises(ValueError, match="frame_agreement_contrast must be >= 0"):
        PriorParams(frame_agreement_contrast=-1.0)


def test_the_gates_blur_follows_the_noise_and_leaves_a_noise_free_image_as_it_is():
    """``contrast_blur``: a plain gray half with noise of 4 gray levels per channel and a half of 8-pixel checks.
    Blurred by up to 3 pixels the plain half's contrast falls below a quarter of its unblurred figure while the
    checks keep more than the gate's ``contrast_high`` (2 gray levels; a 3-pixel blur leaves a fifth of 8-pixel
    checks' contrast); on the same image without noise (below the floor) the blur is none, the contrast exactly the
    unblurred one; the gate's weight follows."""
    from reconstruction.methods.prior_sweep import contrast_above_noise, prior_weight

    rng = np.random.default_rng(5)
    h, w = 64, 128
    checks = np.where(((np.arange(h)[:, None] // 8) + (np.arange(w)[None, :] // 8)) % 2 == 0, 100.0, 156.0)
    clean = np.where(np.arange(w)[None, :] < w // 2, 128.0, checks)
    noisy = clean[..., None] + rng.normal(0.0, 4.0, (h, w, 3))
    clean_u8 = np.repeat(clean[..., None], 3, axis=2).astype(np.uint8)
    noisy_u8 = np.clip(np.rint(noisy), 0, 255).astype(np.uint8)
    blur = (4.0, 0.6, 3.0)
    plain, textured = (slice(8, -8), slice(8, w // 2 - 8)), (slice(8, -8), slice(w // 2 + 8, -8))
    c0, c1 = contrast_above_noise(noisy_u8, 3.0, 0.0), contrast_above_noise(noisy_u8, 3.0, 0.0, blur)
    assert np.median(c0[plain]) > 2.0 and np.median(c1[plain]) < 0.25 * np.median(c0[plain])
    assert np.percentile(c1[textured], 1) > 2.0
    np.testing.assert_array_equal(contrast_above_noise(clean_u8, 3.0, 0.0, blur),
                                  contrast_above_noise(clean_u8, 3.0, 0.0))
    gate = PriorParams(contrast_low=0.5, contrast_high=2.0)
    blurred = dataclasses.replace(gate, contrast_blur=4.0, contrast_blur_floor=0.6)
    np.testing.assert_array_equal(prior_weight(blurred, clean_u8, None), prior_weight(gate, clean_u8, None))
    w0, w1 = prior_weight(gate, noisy_u8, None), prior_weight(blurred, noisy_u8, None)
    assert w0[plain].mean() > 12.0 and w1[plain].mean() < 4.0  # the full weight is 16
    np.testing.assert_allclose(w1[textured], 16.0, atol=1e-5)
    for name in ("contrast_blur", "contrast_blur_floor", "contrast_max_blur_px"):
        with pytest.raises(ValueError, match=f"{name} must be >= 0"):
            PriorParams(**{name: -1.0})


def test_the_epipole_cone_is_the_pixels_near_the_baseline_both_ways():
    """Camera C level at the origin, U 0.4 m straight above: the cone of 20 degrees is the top and bottom 20 degrees
    of latitude (rows), for any yaw of C; a tilted baseline moves it; 0 degrees is no pixel."""
    from reconstruction.methods.prior_sweep import epipole_cone

    w, h = 72, 36  # 5 degrees per pixel; row centres at latitude 87.5, 82.5, ...
    yaw = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
    for rot in (np.eye(3), yaw):
        cone = epipole_cone(w, h, [0, 0, 0], rot, [0, 0, 0.4], 20.0)
        lat = 90.0 - 5.0 * (np.arange(h) + 0.5)
        np.testing.assert_array_equal(cone, np.repeat((np.abs(lat) > 70.0)[:, None], w, axis=1))
    assert not epipole_cone(w, h, [0, 0, 0], np.eye(3), [0, 0, 0.4], 0.0).any()
    # the baseline along camera +X (longitude 90 degrees at the horizon): the pixels around (row 17-18, column 54)
    side = epipole_cone(w, h, [1, 2, 3], np.eye(3), [1.4, 2, 3], 10.0)
    assert side[17:19, 53:56].all() and side[17:19, 17:20].all() and not side[:10].any() and side.sum() < 0.05 * w * h
    with pytest.raises(ValueError, match="coincides"):
        epipole_cone(w, h, [0, 0, 0], np.eye(3), [0, 0, 0], 10.0)
    with pytest.raises(ValueError, match="epipole_cone_deg must be in"):
        PriorParams(epipole_cone_deg=90.0)


def test_the_cone_floor_spares_the_frames_agreement_factor_in_proportion_to_the_rigs_noise():
    """``sweep_gate``'s floor: the frame's factor is at least the floor, the per-pixel factor still applies;
    ``cone_floor``: the rig's noise share inside U's cone, 0 outside; with a noise ramp a noise-free rig gets 0, a
    noisy one 1, and the noisiest image of the three decides."""
    from reconstruction.methods.prior_sweep import cone_floor, sweep_gate

    flow = np.full((2, 4), 2.0)
    sweep = np.array([[2.0, 2.05, 3.0, 3.0], [2.0, 2.0, 3.0, 3.0]])  # 4 of 8 agree: no prior with the ramp 0.6-0.8
    conf = np.array([[0.0, 0.0, 1.0, 0.5], [1.0, 1.0, 0.0, 0.5]])
    floor = np.array([[1.0, 0.0, 1.0, 1.0], [0.5, 0.0, 0.0, 0.0]], np.float32)
    p = PriorParams(sweep_confidence_power=2.0, frame_agreement_low=0.6, frame_agreement_high=0.8)
    g = sweep_gate(p, flow, sweep, conf, floor=floor)
    np.testing.assert_allclose(g, [[1, 0, 0, 0.25], [0.5, 0, 0, 0]], atol=1e-6)
    np.testing.assert_allclose(sweep_gate(p, flow, sweep, conf), 0.0, atol=1e-6)

    f = make_synthetic_frame(80)  # U straight above C
    rng = np.random.default_rng(0)
    plain = {k: np.full_like(v, 128) for k, v in f.images.items()}
    noisy = dict(plain, R=np.clip(128.0 + rng.normal(0.0, 4.0, plain["R"].shape), 0, 255).astype(np.uint8))
    lat = 90.0 - 180.0 * (np.arange(f.height) + 0.5) / f.height
    inside = np.repeat((np.abs(lat) > 70.0)[:, None], f.width, axis=1)
    always = PriorParams(epipole_cone_deg=20.0)
    ramp = dataclasses.replace(always, epipole_cone_noise_low=0.6, epipole_cone_noise_high=1.2)
    np.testing.assert_array_equal(cone_floor(always, dataclasses.replace(f, images=plain)), inside.astype(np.float32))
    np.testing.assert_array_equal(cone_floor(ramp, dataclasses.replace(f, images=plain)), 0.0)
    np.testing.assert_array_equal(cone_floor(ramp, dataclasses.replace(f, images=noisy)), inside.astype(np.float32))
    with pytest.raises(ValueError, match="epipole_cone_noise_low 1.2 must be below epipole_cone_noise_high 0.6"):
        PriorParams(epipole_cone_noise_low=1.2, epipole_cone_noise_high=0.6)


def test_the_cone_spares_the_frames_factor_only_where_the_c_r_flow_comes_back():
    """``epipole_cone_fb_*``: inside U's cone the floor falls linearly from 1 at ``fb_low`` to 0 at ``fb_high``
    pixels of the C -> R flow's forward-backward inconsistency (NaN counts as inconsistent); outside it stays 0;
    without the inconsistency it is a ValueError, and the ramp must rise."""
    from reconstruction.methods.prior_sweep import cone_floor

    f = make_synthetic_frame(80)  # U straight above C: the cone is the rows within 20 degrees of either pole
    lat = 90.0 - 180.0 * (np.arange(f.height) + 0.5) / f.height
    inside = np.repeat((np.abs(lat) > 70.0)[:, None], f.width, axis=1)
    fb = np.tile(np.linspace(0.0, 4.0, f.width, dtype=np.float32), (f.height, 1))
    fb[0, :3] = np.nan
    p = PriorParams(epipole_cone_deg=20.0, epipole_cone_fb_low=1.0, epipole_cone_fb_high=3.0)
    floor = cone_floor(p, f, fb)
    expected = np.where(inside, np.clip((3.0 - fb) / 2.0, 0.0, 1.0), 0.0)
    expected[0, :3] = 0.0
    assert floor.dtype == np.float32
    np.testing.assert_allclose(floor, expected, atol=1e-6)
    assert floor[inside & (fb <= 1.0)].min() == 1.0 and floor[inside & (fb >= 3.0)].max() == 0.0
    np.testing.assert_array_equal(cone_floor(PriorParams(epipole_cone_deg=20.0), f, fb), inside.astype(np.float32))
    with pytest.raises(ValueError, match="forward-backward"):
        cone_floor(p, f)
    with pytest.raises(ValueError, match="epipole_cone_fb_low 3.0 must be below epipole_cone_fb_high 1.0"):
        PriorParams(epipole_cone_fb_low=3.0, epipole_cone_fb_high=1.0)
    with pytest.raises(ValueError, match="epipole_cone_fb_low must be >= 0"):
        PriorParams(epipole_cone_fb_low=-1.0)


def test_the_cone_spares_the_frames_factor_only_where_the_flow_is_on_the_room_plane():
    """``epipole_cone_room``: the floor counts only where the flow is within that relative tolerance of the room's
    floor or ceiling (no plane, inf: not at all); the per-pixel factor still applies; without the room's distance it
    is a ValueError."""
    from reconstruction.methods.prior_sweep import sweep_gate

    flow = np.array([[2.0, 2.0, 2.0, 2.0]])
    sweep = np.array([[3.0, 3.0, 3.0, 3.0]])  # no pixel agrees: the frame's factor is 0
    conf = np.array([[0.0, 0.0, 0.5, 0.0]])
    floor = np.ones((1, 4), np.float32)
    room = np.array([[2.1, 2.5, 2.1, np.inf]], np.float32)  # within 10 %, 22 % off, within 10 %, no plane
    p = PriorParams(sweep_confidence_power=1.0, frame_agreement_low=0.5, frame_agreement_high=0.7,
                    epipole_cone_room=0.1)
    np.testing.assert_allclose(sweep_gate(p, flow, sweep, conf, floor=floor, room_m=room), [[1, 0, 0.5, 0]], atol=1e-6)
    wide = dataclasses.replace(p, epipole_cone_room=0.3)
    np.testing.assert_allclose(sweep_gate(wide, flow, sweep, conf, floor=floor, room_m=room), [[1, 1, 0.5, 0]],
                               atol=1e-6)
    off = dataclasses.replace(p, epipole_cone_room=0.0)
    np.testing.assert_allclose(sweep_gate(off, flow, sweep, conf, floor=floor), [[1, 1, 0.5, 1]], atol=1e-6)
    with pytest.raises(ValueError, match="room's floor and ceiling"):
        sweep_gate(p, flow, sweep, conf, floor=floor)
    with pytest.raises(ValueError, match="epipole_cone_room must be >= 0"):
        PriorParams(epipole_cone_room=-0.1)


def test_the_flow_group_hands_the_c_r_flows_inconsistency_to_the_cone(monkeypatch):
    """Run in its flow's group, a prior whose cone reads the C -> R flow's forward-backward inconsistency gets the
    reconstruction's (the same as the flow stages compute) and runs."""
    import reconstruction.methods.prior_sweep as prior_sweep

    f = make_synthetic_frame(120)
    m = uncalibrated(presets.fused())
    seen = []
    real = prior_sweep.cone_floor

    def spy(params, frame, fb_error_px=None):
        seen.append(fb_error_px)
        return real(params, frame, fb_error_px)

    monkeypatch.setattr(prior_sweep, "cone_floor", spy)
    cone = PriorSweepMethod(flow=m.flow, sweep=m.sweep, label="cone",
                            prior=dataclasses.replace(m.prior, frame_agreement_low=0.5, frame_agreement_high=0.7,
                                                      sweep_confidence_power=1.0, epipole_cone_deg=20.0,
                                                      epipole_cone_fb_low=1.0, epipole_cone_fb_high=3.0,
                                                      epipole_cone_room=0.1))
    out = run_methods(f, [cone])["cone"]
    assert np.isfinite(out.distance).all()
    assert len(seen) == 1 and seen[0].shape == (f.height, f.width)
    flows = pipeline.reconstruct(f, m.flow.flow, m.flow.rectify, ["average"], m.flow.limits)
    assert np.mean(np.abs(seen[0] - flows.pair_fb_px["R"])) < 0.05  # pixels


@pytest.mark.slow
def test_a_frame_whose_flow_disagrees_with_the_coarse_sweep_gets_the_plain_sweep():
    """The gate uses the coarse room-bound pass (no extra aggregation); when the frame's agreement is below the
    ramp the prior is off and fused gives exactly the plain sweep; a gate that always passes gives fused."""
    f = make_synthetic_frame(120)
    m = uncalibrated(presets.fused())
    never = PriorSweepMethod(flow=m.flow, sweep=m.sweep, label="never",
                        prior=PriorParams(frame_agreement_low=0.9995, frame_agreement_high=0.9999))
    always = PriorSweepMethod(flow=m.flow, sweep=m.sweep, label="always",
                         prior=PriorParams(frame_agreement_low=-2.0, frame_agreement_high=-1.0))
    outs = run_methods(f, [m, never, always])
    np.testing.assert_allclose(outs["never"].distance, m.sweep.run(f).distance, rtol=0, atol=1e-6)
    np.testing.assert_allclose(outs["always"].distance, outs["fused"].distance, rtol=0, atol=1e-6)

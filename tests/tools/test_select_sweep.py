"""The selections of the default's sweep: its floor and ceiling families and room bound, its SGM jump penalty and
plane preference, how far it gives up its matching preference where C shows no texture: the candidates, and bad
input."""

from __future__ import annotations

import dataclasses

import pytest

from harness.data.errors import UserError
from reconstruction.methods.presets import fused_mirror
from tools.research import (
    select_bound,
    select_ceiling_edge,
    select_closed_walls,
    select_confirm,
    select_edges,
    select_flat,
    select_gate,
    select_median,
    select_normalized,
    select_planes,
    select_refine_planes,
    select_response,
    select_sgm,
    select_wall_yaw,
    select_walls,
)
from tools.research.select_planes import CANDIDATES, REFERENCE, candidate_methods, planes_method
from tools.research.select_sgm import sgm_method


def test_candidates_the_reference_first_and_the_default_once():
    methods = candidate_methods()
    labels = [m.label for m in methods]
    assert labels[0] == "fused-mirror-planes-0-0.2-0.25" and labels[-1] == "fused-mirror"
    assert len(set(labels)) == len(labels) and len(methods) <= len(CANDIDATES) + 2
    ref = methods[0]
    p = ref.sweep.planes
    assert (p.room_labels, p.room_spread, p.bound_margin) == REFERENCE
    # everything but the three values is the default's
    default = fused_mirror()
    m = planes_method(9, 0.1, 0.15)
    p = m.sweep.planes
    assert (p.room_labels, p.room_spread, p.bound_margin) == (9, 0.1, 0.15)
    assert m.flow == default.flow and m.prior == default.prior and m.sweep.cost == default.sweep.cost
    assert m.sweep.sgm == default.sweep.sgm and m.sweep.post == default.sweep.post
    assert m.sweep.planes.wall_labels == default.sweep.planes.wall_labels
    assert [x.label for x in candidate_methods(["9-0.1-0.25"])][1:-1] in ([], ["fused-mirror-planes-9-0.1-0.25"])
    with pytest.raises(UserError, match="unknown candidate"):
        candidate_methods(["9-0.1-0.3"])


def test_sgm_candidates_the_reference_first_and_the_default_once():
    methods = select_sgm.candidate_methods()
    labels = [m.label for m in methods]
    assert labels[0] == "fused-mirror-sgm-800-4"
    assert len(set(labels)) == len(labels) and len(methods) <= len(select_sgm.CANDIDATES) + 2
    ref = methods[0]
    assert (ref.sweep.sgm.p2, ref.sweep.planes.bias) == select_sgm.REFERENCE
    # the default runs once: as itself, last, unless the reference is configured as it
    default = fused_mirror()
    same = [m for m in methods if {**m.config(), "label": None} == {**default.config(), "label": None}]
    assert len(same) == 1 and (labels[-1] == "fused-mirror") == (same[0] is not ref)
    # everything but the two values is the default's
    m = sgm_method(1600, 2)
    assert (m.sweep.sgm.p2, m.sweep.planes.bias) == (1600, 2)
    assert m.flow == default.flow and m.prior == default.prior and m.sweep.cost == default.sweep.cost
    assert m.sweep.post == default.sweep.post
    assert (m.sweep.sgm.p1, m.sweep.sgm.p3, m.sweep.sgm.edge) == (default.sweep.sgm.p1, default.sweep.sgm.p3,
                                                                  default.sweep.sgm.edge)
    assert m.sweep.planes.bound_margin == default.sweep.planes.bound_margin
    assert [x.label for x in select_sgm.candidate_methods(["1200-8"])][1:] in (
        [], ["fused-mirror-sgm-1200-8"], ["fused-mirror"], ["fused-mirror-sgm-1200-8", "fused-mirror"])
    with pytest.raises(UserError, match="unknown candidate"):
        select_sgm.candidate_methods(["1200-3"])


def _candidates(script, reference: str):
    """``script``'s methods (the reference, labelled ``reference``, first; each once), the default and the one method
    configured as it: the default is run once, as itself, or as the reference or a candidate configured as it."""
    methods = script.candidate_methods()
    labels = [m.label for m in methods]
    assert labels[0] == reference
    assert len(set(labels)) == len(labels) and len(methods) <= len(script.CANDIDATES) + 2
    default = fused_mirror()
    same = [m for m in methods if {**m.config(), "label": None} == {**default.config(), "label": None}]
    assert len(same) == 1
    return methods, default, same[0]


def test_flat_candidates_the_reference_first_and_the_default_once():
    methods, default, same = _candidates(select_flat, "fused-mirror-flat-0-1")
    assert (methods[-1].label == "fused-mirror") == (same.label == "fused-mirror")
    assert methods[0].sweep.cost.flat_contrast == methods[0].sweep.corrected_cost.flat_contrast == 0.0
    # everything but the two values, in both sweep costs, is the default's
    m = select_flat.flat_method(2.5, 0.25)
    assert m.label == "fused-mirror-flat-2.5-0.25"
    assert m.sweep.cost == dataclasses.replace(default.sweep.cost, flat_contrast=2.5, flat_weight=0.25)
    assert m.sweep.corrected_cost == dataclasses.replace(default.sweep.corrected_cost, flat_contrast=2.5,
                                                         flat_weight=0.25)
    assert m.flow == default.flow and m.prior == default.prior and m.sweep.sgm == default.sweep.sgm
    assert m.sweep.planes == default.sweep.planes and m.sweep.post == default.sweep.post
    assert [x.label for x in select_flat.candidate_methods(["1-0.5"])][1:] in (
        [], ["fused-mirror-flat-1-0.5"], ["fused-mirror"], ["fused-mirror-flat-1-0.5", "fused-mirror"])
    with pytest.raises(UserError, match="unknown candidate"):
        select_flat.candidate_methods(["3-1"])


def test_edges_candidates_the_reference_first_and_the_default_once():
    methods, default, _ = _candidates(select_edges, "fused-mirror-edges-0-10-5-4")
    assert methods[0].sweep.post.edge_radius_px == 0
    # everything but the four post-processing values is the default's
    m = select_edges.edges_method(6, 15.0, 4.0, 3)
    assert m.label == "fused-mirror-edges-6-15-4-3"
    assert m.sweep.post == dataclasses.replace(default.sweep.post, edge_radius_px=6, edge_sigma_color=15.0,
                                               edge_sigma_px=4.0, edge_reach_px=3)
    assert m.sweep.cost == default.sweep.cost and m.sweep.corrected_cost == default.sweep.corrected_cost
    assert m.flow == default.flow and m.prior == default.prior and m.sweep.sgm == default.sweep.sgm
    with pytest.raises(UserError, match="unknown candidate"):
        select_edges.candidate_methods(["3-1-1-1"])


def test_confirm_candidates_the_reference_first_and_the_default_once():
    methods, default, _ = _candidates(select_confirm, "fused-mirror-confirm-0")
    assert methods[0].flow.rig.confirm_factor == 0
    # everything but the rig fit's confirming pass is the default's
    m = select_confirm.confirm_method(2)
    assert m.label == "fused-mirror-confirm-2"
    assert m.flow == dataclasses.replace(default.flow, rig=dataclasses.replace(default.flow.rig, confirm_factor=2))
    assert m.sweep == default.sweep and m.prior == default.prior
    assert m.quality_flow is None or m.quality_flow.rig.confirm_factor == 2
    with pytest.raises(UserError, match="unknown candidate"):
        select_confirm.candidate_methods(["3"])


def test_response_candidates_the_reference_first_and_the_default_once():
    methods, default, _ = _candidates(select_response, "fused-mirror-response-1")
    assert methods[0].flow.photometric.response == 1
    # everything but the response's degree (in the flow's, the sweep's and the quality flow's self-calibration) is
    # the default's
    m = select_response.response_method(3)
    photometric = dataclasses.replace(default.flow.photometric, response=3)
    assert m.label == "fused-mirror-response-3"
    assert m.flow == dataclasses.replace(default.flow, photometric=photometric)
    assert m.sweep == dataclasses.replace(default.sweep, photometric=photometric) and m.prior == default.prior
    assert m.quality_flow is None or m.quality_flow.photometric == photometric
    with pytest.raises(UserError, match="unknown candidate"):
        select_response.candidate_methods(["4"])


def test_median_candidates_the_reference_first_and_the_default_once():
    methods, default, same = _candidates(select_median, "fused-mirror-median-5")
    assert same is methods[0] and methods[0].sweep.post.median_px == 5
    # everything but the median's side is the default's
    m = select_median.median_method(9)
    assert m.label == "fused-mirror-median-9"
    assert m.sweep == dataclasses.replace(default.sweep, post=dataclasses.replace(default.sweep.post, median_px=9))
    assert m.flow == default.flow and m.prior == default.prior and m.quality_flow == default.quality_flow
    with pytest.raises(UserError, match="unknown candidate"):
        select_median.candidate_methods(["11"])


def test_normalized_candidates_the_reference_first_and_the_default_once():
    methods, default, same = _candidates(select_normalized, "fused-mirror-normalized-0")
    assert same is methods[0] and methods[0].sweep.cost.normalized_weight == 0
    # everything but the mix in both costs is the default's
    m = select_normalized.normalized_method(0.5, 2.0)
    assert m.label == "fused-mirror-normalized-0.5-2"
    mixed = {k: dataclasses.replace(getattr(default.sweep, k), normalized_weight=0.5, normalized_contrast=2.0)
             for k in ("cost", "corrected_cost")}
    assert m.sweep == dataclasses.replace(default.sweep, **mixed)
    assert m.flow == default.flow and m.prior == default.prior and m.quality_flow == default.quality_flow
    with pytest.raises(UserError, match="unknown candidate"):
        select_normalized.candidate_methods(["0.5"])


def test_refine_planes_candidates_the_reference_first_and_the_default_once():
    methods, default, _ = _candidates(select_refine_planes, "fused-mirror-refine-planes-0-0-0")
    assert methods[0].sweep.refine_planes is None
    # everything but the three values is the default's
    m = select_refine_planes.refine_planes_method(0.004, 0.02, 0.05)
    assert m.label == "fused-mirror-refine-planes-0.004-0.02-0.05"
    assert m.sweep.refine_planes == dataclasses.replace(default.sweep.refine_planes, max_se=0.004, max_basin=0.02,
                                                        snap=0.05)
    assert m.sweep.cost == default.sweep.cost and m.sweep.post == default.sweep.post
    assert m.flow == default.flow and m.prior == default.prior and m.sweep.sgm == default.sweep.sgm
    with pytest.raises(UserError, match="unknown candidate"):
        select_refine_planes.candidate_methods(["1-1-1"])


def test_bound_candidates_the_reference_first_and_the_default_once():
    methods, default, _ = _candidates(select_bound, "fused-mirror-bound-0-0")
    assert methods[0].sweep.planes.bound_penalty == 0
    # everything but the penalty and where it applies is the default's
    m = select_bound.bound_method(3.0, 0.15)
    assert m.label == "fused-mirror-bound-3-0.15"
    assert m.sweep.planes == dataclasses.replace(default.sweep.planes, bound_penalty=3.0, bound_penalty_min_az=0.15)
    assert m.sweep.cost == default.sweep.cost and m.sweep.post == default.sweep.post
    assert m.sweep.refine_planes == default.sweep.refine_planes
    assert m.flow == default.flow and m.prior == default.prior and m.sweep.sgm == default.sweep.sgm
    with pytest.raises(UserError, match="unknown candidate"):
        select_bound.candidate_methods(["3"])


def test_walls_candidates_the_reference_first_and_the_default_once():
    methods, default, _ = _candidates(select_walls, "fused-mirror-walls-0.2-0.03")
    p = methods[0].sweep.refine_planes
    assert (p.wall_margin, p.wall_max_share) == select_walls.REFERENCE == (0.2, 0.03)
    # everything but the two values is the default's
    m = select_walls.walls_method(0.3, 0.02)
    assert m.label == "fused-mirror-walls-0.3-0.02"
    assert m.sweep.refine_planes == dataclasses.replace(default.sweep.refine_planes, wall_margin=0.3,
                                                        wall_max_share=0.02)
    assert m.sweep.planes == default.sweep.planes and m.sweep.cost == default.sweep.cost
    assert m.flow == default.flow and m.prior == default.prior and m.sweep.post == default.sweep.post
    with pytest.raises(UserError, match="unknown candidate"):
        select_walls.candidate_methods(["0.3-0.02"])


def test_wall_yaw_candidates_the_reference_first_and_the_default_once():
    methods, default, _ = _candidates(select_wall_yaw, "fused-mirror-wall-yaw-normals")
    assert (methods[0].sweep.planes.wall_yaw,) == select_wall_yaw.REFERENCE == ("normals",)
    # everything but the one value is the default's
    m = select_wall_yaw.wall_yaw_method("normals")
    assert m.sweep.planes == dataclasses.replace(default.sweep.planes, wall_yaw="normals")
    assert m.sweep.refine_planes == default.sweep.refine_planes and m.sweep.cost == default.sweep.cost
    assert m.flow == default.flow and m.prior == default.prior and m.sweep.post == default.sweep.post
    with pytest.raises(UserError, match="unknown candidate"):
        select_wall_yaw.candidate_methods(["vanishing"])


def test_ceiling_edge_candidates_the_reference_first_and_the_default_once():
    methods, default, _ = _candidates(select_ceiling_edge, "fused-mirror-ceiling-edge-0")
    assert (methods[0].sweep.refine_planes.ceiling_edge,) == select_ceiling_edge.REFERENCE == (0.0,)
    # everything but the one value is the default's
    m = select_ceiling_edge.ceiling_edge_method(0.9)
    assert m.label == "fused-mirror-ceiling-edge-0.9"
    assert m.sweep.refine_planes == dataclasses.replace(default.sweep.refine_planes, ceiling_edge=0.9)
    assert m.sweep.planes == default.sweep.planes and m.sweep.cost == default.sweep.cost
    assert m.flow == default.flow and m.prior == default.prior and m.sweep.post == default.sweep.post
    with pytest.raises(UserError, match="unknown candidate"):
        select_ceiling_edge.candidate_methods(["0.9"])


def test_closed_walls_candidates_the_reference_first_and_the_default_once():
    methods, default, _ = _candidates(select_closed_walls, "fused-mirror-closed-walls-0-0")
    p = methods[0].sweep.refine_planes
    assert (p.closed_max_share, p.closed_ceiling_share) == select_closed_walls.REFERENCE == (0.0, 0.0)
    # everything but the two values is the default's
    m = select_closed_walls.closed_walls_method(0.2, 0.05)
    assert m.label == "fused-mirror-closed-walls-0.2-0.05"
    assert m.sweep.refine_planes == dataclasses.replace(default.sweep.refine_planes, closed_max_share=0.2,
                                                        closed_ceiling_share=0.05)
    assert m.sweep.planes == default.sweep.planes and m.sweep.cost == default.sweep.cost
    assert m.flow == default.flow and m.prior == default.prior and m.sweep.post == default.sweep.post
    with pytest.raises(UserError, match="unknown candidate"):
        select_closed_walls.candidate_methods(["0.2-0.05"])


def test_gate_candidates_the_reference_first_and_the_default_once():
    methods, default, _ = _candidates(select_gate, "fused-mirror-gate-0-0-0.5-0.7-0-0-0-0-0-3-0-0-0")
    p = methods[0].prior
    assert (p.contrast_noise, p.frame_agreement_contrast, p.frame_agreement_low, p.frame_agreement_high,
            p.epipole_cone_deg, p.epipole_cone_noise_low, p.epipole_cone_noise_high, p.contrast_blur,
            p.contrast_blur_floor, p.contrast_max_blur_px, p.epipole_cone_fb_low,
            p.epipole_cone_fb_high, p.epipole_cone_room) == select_gate.REFERENCE
    # everything but the thirteen values is the default's
    m = select_gate.gate_method(2.0, 8.0, 0.3, 0.9, 12.0, 0.5, 1.5, 4.0, 0.6, 1.5, 0.5, 2.5, 0.15)
    assert m.label == "fused-mirror-gate-2-8-0.3-0.9-12-0.5-1.5-4-0.6-1.5-0.5-2.5-0.15"
    assert m.prior == dataclasses.replace(default.prior, contrast_noise=2.0, frame_agreement_contrast=8.0,
                                          frame_agreement_low=0.3, frame_agreement_high=0.9, epipole_cone_deg=12.0,
                                          epipole_cone_noise_low=0.5, epipole_cone_noise_high=1.5,
                                          contrast_blur=4.0, contrast_blur_floor=0.6, contrast_max_blur_px=1.5,
                                          epipole_cone_fb_low=0.5, epipole_cone_fb_high=2.5, epipole_cone_room=0.15)
    assert m.sweep == default.sweep and m.flow == default.flow and m.quality_flow == default.quality_flow
    assert all(len(c) == len(select_gate.REFERENCE) for c in select_gate.CANDIDATES)
    with pytest.raises(UserError, match="unknown candidate"):
        select_gate.candidate_methods(["3"])


@pytest.mark.parametrize("main", [select_planes.main, select_sgm.main, select_flat.main, select_edges.main,
                                  select_confirm.main, select_refine_planes.main, select_bound.main,
                                  select_walls.main, select_gate.main, select_response.main, select_median.main,
                                  select_normalized.main, select_wall_yaw.main, select_ceiling_edge.main,
                                  select_closed_walls.main],
                         ids=["planes", "sgm", "flat", "edges", "confirm", "refine_planes", "bound", "walls", "gate",
                              "response", "median", "normalized", "wall_yaw", "ceiling_edge",
                              "closed_walls"])
def test_a_missing_data_root_is_one_line_and_writes_nothing(main, tmp_path, capsys):
    out = tmp_path / "sel"
    assert main([str(tmp_path / "nope"), "--out", str(out), "--quiet", "--frames", "a/vp000"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "nope" in err[0]
    assert not out.exists()

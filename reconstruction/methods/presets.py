"""The named built-in methods (``tri360 methods``), each written out in full.

One function per method returns its whole configuration as one tree of dataclasses, every field of every parameter
dataclass given (a test parses this module and refuses a constructor call that leaves one to its default) and the
flow's parameters too (:func:`reconstruction.flow.backends.builtin_flow` refuses a missing one):
reading one function is reading the method, and ``tri360 methods --show LABEL`` prints what it builds, which is what
``config.json`` records.  No preset is built from another: a sub-tree used twice within one method (its
photometric and rig self-calibration, shared by its flow, its sweep and its quality flow) is one local name.
Comments beside a value say why it is that value; the parameter dataclasses' docstrings say what each field does.

:data:`PRESETS` and :data:`ABLATIONS` name them, one line each (:mod:`reconstruction.methods.registry` registers
them with every configuration of the flow pipeline).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

from reconstruction.flow.backends import builtin_flow
from reconstruction.methods.base import Method
from reconstruction.methods.flow_pipeline import FlowMethod
from reconstruction.methods.prior_sweep import PriorParams, PriorSweepMethod
from reconstruction.methods.sweep import PostParams, SgmParams, SweepMethod
from reconstruction.photometry import PhotometricParams
from reconstruction.refine.lm import RefineConfig
from reconstruction.refine.planes import PlaneRefineParams
from reconstruction.refine.triangulate import TriangulationLimits
from reconstruction.rig_calibration import RigParams
from reconstruction.sweep.cost import CostParams
from reconstruction.sweep.planes import PlaneParams

__all__ = ["Preset", "PRESETS", "ABLATIONS", "DEFAULT_METHOD", "fused_mirror", "fused", "sweep", "fused_mirror_raw",
           "fused_mirror_told_rig", "fused_mirror_raw_images", "fused_mirror_shared_falloff", "fused_gated",
           "fused_adaptive"]

#: what ``tri360 reconstruct`` runs by default, :func:`fused_mirror`: its matching chosen by
#: ``python -m tools.research.select_matching`` on the dev split of suites/tri360-v1.toml (docs/matching.md), its
#: photometric self-calibration and intensity weight by ``python -m tools.research.select_photometric`` on the dev split
#: of suites/tri360-v2.toml under both conditions (docs/photometry.md)
DEFAULT_METHOD = "fused-mirror"


@dataclass(frozen=True)
class Preset:
    """A named built-in method.

    Attributes:
        label: its label (``--method``).
        build: makes the method.
        description: one line: what it does and how it differs from the other presets.
    """

    label: str
    build: Callable[[], Method]
    description: str


# ----------------------------------------------------------------------------------------------- the presets
# Values shared by every preset, and why: the flow is DIS (``dis``, chosen by measurement, docs/refinement.md) with
# its built-in parameters; the refinement variant ``gradient`` and the triangulation limits as measured in
# docs/refinement.md; the sweep's cost, SGM and post-processing as chosen with the flow prior (over the 4 classroom
# frames + synthetic_box, docs/matching.md), which also serve the plain sweep best: a strong +-1-step penalty (P1 120,
# P2 800), truncation 30 gray levels, 160 labels and pixel-wise costs (no blur, no box filter, gradients weighted 2);
# the self-calibration's values as PhotometricParams' and RigParams' docstrings explain them; its pre-pass flow is the
# same DIS (on images reduced by prepass_factor).


def fused_mirror() -> PriorSweepMethod:
    """``fused-mirror``, the default (:data:`DEFAULT_METHOD`): ``fused-gated`` whose room bound tells a polished
    floor's mirror image of the ceiling from the floor, and whose sweep matches images the self-calibration changed
    with a cost of its own (chosen on the dev split of suites/tri360-v2.toml under both conditions and of tri360-v3
    under its low-light family, docs/photometry.md), and whose sweep keeps only half its preference where C shows no
    texture above its noise (docs/edges.md)."""
    dis = builtin_flow("dis", {
        "preset": "medium", "finest_scale": 0, "patch_size": 8, "patch_stride": 3, "gd_iterations": 25,
        "var_iterations": 10, "var_alpha": 10.0, "spatial_propagation": True})
    limits = TriangulationLimits(min_angle_deg=3.0, min_parallax_rad=2e-4, d_min_m=0.05, d_max_m=100.0)
    photometric = PhotometricParams(
        mode="gain-field", degree=2, pixel_degree=0, prepass_factor=2, ridge=0.0, factor=4, dark=0.01, bright=0.9,
        tukey_c=4.685, iterations=8, max_log_gain=2.0, even=False, central=True, common_field=False, min_gain=0.05,
        min_field=0.1, min_common=0.5, flat_log_gradient=0.1, alpha=0.001, agreement=0.05, response=1,
        min_response=0.1, prepass_flow=dis, max_fit_pixels=15000, hemispheres=0.0,
        longitude_blocks=16, min_block_samples=50)
    rig = RigParams(
        mode="rotation", max_fb_px=0.5, texture_quantile=0.7, min_sin=0.3, max_degrees=2.0, alpha=0.01,
        min_degrees=0.072, iterations=6, tukey_c=4.685, max_matches=40000, hemispheres=0.0,
        confirm_factor=1, longitude_blocks=16, min_block_samples=50)
    return PriorSweepMethod(
        label="fused-mirror",
        # the prior is the unrefined flow: the flow pipeline without its LM, about 0.6 s less per 1000x500 frame
        # than fused's refined one
        flow=FlowMethod(flow=dis, rectify=True, refine=None, limits=limits, photometric=photometric, rig=rig),
        sweep=SweepMethod(
            pairs=("U", "R"), label="sweep", photometric=photometric,
            # the floor and the ceiling the coarse pass found searched again from the images at 0.5 % steps over
            # +-15 %, applied where the search is sure (jackknife standard error at most 0.5 %, its basin at most 3 %
            # wide, of two minima within 5 % the farther: chair bases and mats lie above a floor), and the pixels
            # within 6 % of it put on it (chosen on tri360-v3 dev's ideal frames, docs/edges.md); then the pixels
            # more than 20 % beyond a wall that at most 6 % of the pixels facing it lie beyond are put on it: a glossy
            # wall's mirror images (chosen by python -m tools.research.select_walls on the dev split, docs/edges.md),
            # and up to 10 % if at most 4 % of the ceiling's pixels facing it lie beyond it: the ceiling stops at a
            # wall, not at a shelf (python -m tools.research.select_closed_walls on the dev split, docs/edges.md);
            # on a side where no wall found encloses but one encloses the opposite side, the wall where 99 % of the
            # ceiling's area seen on that side ends, if the rig resolves the ceiling there (python -m
            # tools.research.select_ceiling_edge on the dev split, docs/edges.md)
            refine_planes=PlaneRefineParams(
                select=0.12, search=0.15, steps=61, truncate=20.0, min_gradient=1.0, max_pixels=40000, min_cos=0.1,
                max_se=0.005, longitude_blocks=32, min_block_pixels=50, snap=0.06, rise=0.05, max_basin=0.03,
                far_share=0.05, wall_margin=0.2, wall_max_share=0.06,
                closed_max_share=0.10, closed_ceiling_share=0.04, ceiling_edge=0.99),
            # the cost when the self-calibration changed no image (cameras that agree): the sweep's own but for its
            # 200 sphere labels (the sweep's 160): at 1000 px and the 0.4 m baseline a label is 1.3 px of parallax
            # at 160 and 1.06 px at 200, which brings far surfaces closer to what the rig resolves; 240 measured
            # better still, but its peak memory at 1000x500 (1.01 GB) misses the 1 GB a frame may take (python -m
            # tools.research.select_fill, docs/edges.md); every pair votes everywhere (occlusion 0: visibility from
            # the coarse pass's distances cut the occluded pixels' error to 0.86x but cost lecture halls 1.10x,
            # docs/edges.md); where C's local contrast is below its noise (flat_contrast 1), both costs move half
            # way to their mean (flat_weight 0.5): the plain floors and ceilings follow their textured neighbours
            # (chosen by python -m tools.research.select_flat among none, 0.7-1, 1-1 and 1-0.5 on tri360-v3 dev
            # under all seven camera conditions, docs/edges.md)
            cost=CostParams(
                d_min_m=0.3, d_max_m=30.0, levels=200, blur_px=0.0, gradient_weight=2.0, intensity_weight=1.0,
                truncate=30.0, box_px=1, scale=8.0, pair_power=2.0, feature="intensity", noise_blur=0.0,
                noise_floor=1.0, max_noise_blur_px=1.5, noise_scale=1, occlusion=0.0, occlusion_min_share=0.25,
                flat_contrast=1.0, flat_weight=0.5, flat_sigma_px=2.0, flat_min_noise=0.5,
                normalized_weight=0.0, normalized_contrast=1.0),
            planes=PlaneParams(
                per_side=32, h_min_m=0.3, h_max_m=5.0, bias=4, room_bound=True, bound_min_share=0.03,
                coarse_factor=2, wall_spread=0.1, wall_min_share=0.01,
                # the walls' yaw (for the wall labels and the wall step) from the surface normals' vote and, where it
                # finds no wall direction (a plain white lab under every camera condition), where the four walls
                # hold the most points (chosen by python -m tools.research.select_wall_yaw on the dev split,
                # docs/edges.md)
                wall_yaw="normals-or-offsets",
                # nothing more than 10 % beyond the floor and the ceiling the coarse pass found (the sweep's 25 %
                # lets a glossy floor's reflections and plain floors drift below it; 5 % cuts off true floors and
                # tiers: the coarse pass finds floors up to 3.3 % too near on the dev split): chosen by python -m
                # tools.research.select_planes on the dev split (docs/edges.md)
                bound_margin=0.1,
                # a sphere label beyond that bound costs 2 gray levels more rather than being forbidden, and a pixel
                # that still wins one is put on the floor (ceiling) found: a polished floor's reflections of the
                # lamps match below the floor, and forbidden there they took nearer labels (chosen by python -m
                # tools.research.select_bound on the dev split, docs/edges.md)
                bound_penalty=2.0,
                # only at bearings more than 11.5 degrees above or below the horizon (|sine of the elevation| >=
                # 0.2): nearer it the bound is crossed only far away, and a noisy camera's wrong match to a far label
                # put the pixel on the floor far beyond the wall it shows (labs under camera conditions); chosen by
                # python -m tools.research.select_bound among 0, 0.1 and 0.2 on the dev split (docs/edges.md)
                bound_penalty_min_az=0.2,
                # the horizontal planes plus 9 labels per wall found by the coarse pass
                wall_labels=9,
                # the mirror test of the room bound: a floor found by the coarse pass within 20 % of where the
                # ceiling's mirror image in a nearer, well-supported plane would be is that mirror image, the nearer
                # plane is the floor (likewise for the ceiling).  20 % is about two plane-label spacings (the 32
                # heights per side are 9.5 % apart); on the dev split the mirrored floors it corrects lie 12-14 % off
                mirror_tolerance=0.2, room_labels=0, room_spread=0.2),
            sgm=SgmParams(p1=120, p2=800, p3=200, edge=8.0, paths=8),
            # the pixels whose winner is within 10 % of the best other label (SGM confidence below 0.1: weak
            # texture, occlusions, edges) refilled from the confident ones without crossing C's image edges at 4 gray
            # levels (chosen by python -m tools.research.select_fill on the dev split, docs/edges.md)
            post=PostParams(min_confidence=0.1, fill_lambda=200.0, fill_sigma_color=4.0, median_px=5,
                            fill_space="inverse", edge_radius_px=0, edge_sigma_color=10.0, edge_sigma_px=5.0,
                            edge_jump=0.05, edge_reach_px=4),
            # the cost when the self-calibration changed the images
            corrected_cost=CostParams(
                d_min_m=0.3, d_max_m=30.0, levels=200, gradient_weight=2.0, truncate=30.0, box_px=1, scale=8.0,
                pair_power=2.0, feature="intensity", max_noise_blur_px=1.5,
                # what a gain difference between the cameras leaves after the self-calibration weighs less against
                # the gradients (2): chosen by ``python -m tools.research.select_photometric`` among 1, 0.5 and
                # 0.25 on the dev split under both conditions (docs/photometry.md)
                intensity_weight=0.25,
                # a Gaussian blur of the grey images, pixels: what a real camera's noise and JPEG leave on far,
                # weakly textured surfaces weighs less in the gradients; chosen by select_photometric among 0, 0.5,
                # 0.7 and 1 on the dev split under both conditions (docs/photometry.md)
                blur_px=0.7,
                # on noisier images a blur of 1 px per gray level of noise above noise_floor (at most
                # max_noise_blur_px, never less than blur_px), the noise measured on the images' 2 x 2 means
                # (noise_scale 2: JPEG flattens the noise at the pixel scale, not at the scale the blurred cost
                # matches at): rendered frames measure 0.1-0.4 gray levels there, the suite's other camera families
                # 0.9-2.9 and its low-light ones 3.1-6.5 (reconstruction.sweep.cost.image_noise; chosen on tri360-v3
                # dev's low-light family, docs/photometry.md)
                noise_blur=1.0, noise_floor=2.0, noise_scale=2, occlusion=0.0, occlusion_min_share=0.25,
                flat_contrast=1.0, flat_weight=0.5, flat_sigma_px=2.0, flat_min_noise=0.5,
                normalized_weight=0.0, normalized_contrast=1.0)),
        # fused's weight (16), times a ramp of C's local contrast (0 below 0.5, full above 2 gray levels: no prior
        # where there is no texture for the flow to follow), times 1 - c_sweep where the flow and the plain coarse
        # sweep disagree by more than 5 % (a confident sweep keeps its answer), times the frame's agreement share
        # ramped from 0 at 50 % to full at 70 % (chosen on the dev split, docs/matching.md); within 20 degrees of
        # U's epipoles (the floor below the rig, the ceiling) that share is spared, in proportion to the rig's noise
        # from 0.6 to 1.2 gray levels (none on a noise-free rig), where the flow lies within 10 % of the floor or
        # ceiling the coarse pass found (chosen on tri360-v3 dev's camera twins, docs/photometry.md)
        prior=PriorParams(
            weight=16.0, truncate_levels=16.0, use_confidence=False, contrast_low=0.5, contrast_high=2.0,
            contrast_sigma_px=3.0, contrast_noise=0.0, contrast_blur=0.0, contrast_blur_floor=0.0,
            contrast_max_blur_px=3.0, sweep_confidence_power=1.0, agree_tolerance=0.05,
            frame_agreement_low=0.5, frame_agreement_high=0.7, frame_agreement_contrast=0.0,
            epipole_cone_deg=20.0, epipole_cone_noise_low=0.6, epipole_cone_noise_high=1.2,
            epipole_cone_fb_low=0.0, epipole_cone_fb_high=0.0, epipole_cone_room=0.1),
        # the quality measures compare the distance with fused's refined flow distance (computed only when the
        # quality is assessed): on the dev split that ranks pixels by error better than the unrefined prior
        # (docs/real-captures.md)
        quality_flow=FlowMethod(
            flow=dis, rectify=True, limits=limits, photometric=photometric, rig=rig,
            refine=RefineConfig(
                name="gradient", angle_power=2.0, gradient=True, gradient_scale=0.02, gradient_floor=0.05,
                color_weight=0.0, color_saturation=0.1, color_blur_px=1.0, color_rgb=False, color_patch=1,
                color_iters=6, color_min_gradient=0.01, lateral_px=1.0, lateral_max_px=3.0, fb_max_px=1.0,
                fallback_weight=1e-3, outlier_log_ratio=0.5, fill_lambda=1e4, fill_sigma_color=8.0, max_iters=30,
                tol_m=1e-7, description="LM, angle x epipolar-gradient weights (paper eq. 1)")))


def fused() -> PriorSweepMethod:
    """``fused``: the sweep with the ``dis-rect:gradient`` distance as prior at one constant weight
    (docs/matching.md)."""
    dis = builtin_flow("dis", {
        "preset": "medium", "finest_scale": 0, "patch_size": 8, "patch_stride": 3, "gd_iterations": 25,
        "var_iterations": 10, "var_alpha": 10.0, "spatial_propagation": True})
    limits = TriangulationLimits(min_angle_deg=3.0, min_parallax_rad=2e-4, d_min_m=0.05, d_max_m=100.0)
    photometric = PhotometricParams(
        mode="gain-field", degree=2, pixel_degree=0, prepass_factor=2, ridge=0.0, factor=4, dark=0.01, bright=0.9,
        tukey_c=4.685, iterations=8, max_log_gain=2.0, even=False, central=True, common_field=False, min_gain=0.05,
        min_field=0.1, min_common=0.5, flat_log_gradient=0.1, alpha=0.001, agreement=0.05, response=1,
        min_response=0.1, prepass_flow=dis, max_fit_pixels=15000, hemispheres=0.0,
        longitude_blocks=16, min_block_samples=50)
    rig = RigParams(
        mode="rotation", max_fb_px=0.5, texture_quantile=0.7, min_sin=0.3, max_degrees=2.0, alpha=0.01,
        min_degrees=0.072, iterations=6, tukey_c=4.685, max_matches=40000, hemispheres=0.0,
        confirm_factor=1, longitude_blocks=16, min_block_samples=50)
    return PriorSweepMethod(
        label="fused", quality_flow=None,
        flow=FlowMethod(
            flow=dis, rectify=True, limits=limits, photometric=photometric, rig=rig,
            refine=RefineConfig(
                name="gradient", angle_power=2.0, gradient=True, gradient_scale=0.02, gradient_floor=0.05,
                color_weight=0.0, color_saturation=0.1, color_blur_px=1.0, color_rgb=False, color_patch=1,
                color_iters=6, color_min_gradient=0.01, lateral_px=1.0, lateral_max_px=3.0, fb_max_px=1.0,
                fallback_weight=1e-3, outlier_log_ratio=0.5, fill_lambda=1e4, fill_sigma_color=8.0, max_iters=30,
                tol_m=1e-7, description="LM, angle x epipolar-gradient weights (paper eq. 1)")),
        sweep=SweepMethod(
            pairs=("U", "R"), label="sweep", photometric=photometric, corrected_cost=None,
            refine_planes=None,
            cost=CostParams(
                d_min_m=0.3, d_max_m=30.0, levels=160, blur_px=0.0, gradient_weight=2.0, intensity_weight=1.0,
                truncate=30.0, box_px=1, scale=8.0, pair_power=2.0, feature="intensity", noise_blur=0.0,
                noise_floor=1.0, max_noise_blur_px=1.5, noise_scale=1, occlusion=0.0, occlusion_min_share=0.25,
                flat_contrast=0.0, flat_weight=1.0, flat_sigma_px=2.0, flat_min_noise=0.5,
                normalized_weight=0.0, normalized_contrast=1.0),
            # spheres and floor/ceiling planes, no wall planes
            planes=PlaneParams(
                per_side=32, h_min_m=0.3, h_max_m=5.0, bias=4, room_bound=True, bound_margin=0.25, bound_penalty=0.0,
                bound_penalty_min_az=0.0, bound_min_share=0.03, coarse_factor=2,
                wall_labels=0, wall_spread=0.1, wall_min_share=0.01, wall_yaw="normals",
                mirror_tolerance=0.0, room_labels=0, room_spread=0.2),
            sgm=SgmParams(p1=120, p2=800, p3=200, edge=8.0, paths=8),
            post=PostParams(min_confidence=0.0, fill_lambda=200.0, fill_sigma_color=8.0, median_px=5,
                            fill_space="inverse", edge_radius_px=0, edge_sigma_color=10.0, edge_sigma_px=5.0,
                            edge_jump=0.05, edge_reach_px=4)),
        prior=PriorParams(
            weight=16.0, truncate_levels=16.0, use_confidence=False, contrast_low=0.0, contrast_high=0.0,
            contrast_sigma_px=3.0, contrast_noise=0.0, contrast_blur=0.0, contrast_blur_floor=0.0,
            contrast_max_blur_px=3.0, sweep_confidence_power=0.0, agree_tolerance=0.05,
            frame_agreement_low=0.0, frame_agreement_high=0.0, frame_agreement_contrast=0.0,
            epipole_cone_deg=0.0, epipole_cone_noise_low=0.0, epipole_cone_noise_high=0.0,
            epipole_cone_fb_low=0.0, epipole_cone_fb_high=0.0, epipole_cone_room=0.0))


def sweep() -> SweepMethod:
    """``sweep``: the trinocular sphere sweep with SGM over spheres and floor/ceiling planes, no flow."""
    # the self-calibration's pre-pass flow (the sweep itself matches no flow)
    dis = builtin_flow("dis", {
        "preset": "medium", "finest_scale": 0, "patch_size": 8, "patch_stride": 3, "gd_iterations": 25,
        "var_iterations": 10, "var_alpha": 10.0, "spatial_propagation": True})
    photometric = PhotometricParams(
        mode="gain-field", degree=2, pixel_degree=0, prepass_factor=2, ridge=0.0, factor=4, dark=0.01, bright=0.9,
        tukey_c=4.685, iterations=8, max_log_gain=2.0, even=False, central=True, common_field=False, min_gain=0.05,
        min_field=0.1, min_common=0.5, flat_log_gradient=0.1, alpha=0.001, agreement=0.05, response=1,
        min_response=0.1, prepass_flow=dis, max_fit_pixels=15000, hemispheres=0.0,
        longitude_blocks=16, min_block_samples=50)
    return SweepMethod(
        pairs=("U", "R"), label="sweep", photometric=photometric, corrected_cost=None,
        refine_planes=None,
        cost=CostParams(
            d_min_m=0.3, d_max_m=30.0, levels=160, blur_px=0.0, gradient_weight=2.0, intensity_weight=1.0,
            truncate=30.0, box_px=1, scale=8.0, pair_power=2.0, feature="intensity", noise_blur=0.0, noise_floor=1.0,
            max_noise_blur_px=1.5, noise_scale=1, occlusion=0.0, occlusion_min_share=0.25, flat_contrast=0.0,
            flat_weight=1.0, flat_sigma_px=2.0, flat_min_noise=0.5,
            normalized_weight=0.0, normalized_contrast=1.0),
        planes=PlaneParams(
            per_side=32, h_min_m=0.3, h_max_m=5.0, bias=4, room_bound=True, bound_margin=0.25, bound_penalty=0.0,
            bound_penalty_min_az=0.0, bound_min_share=0.03, coarse_factor=2,
            wall_labels=0, wall_spread=0.1, wall_min_share=0.01, wall_yaw="normals",
            mirror_tolerance=0.0, room_labels=0, room_spread=0.2),
        sgm=SgmParams(p1=120, p2=800, p3=200, edge=8.0, paths=8),
        post=PostParams(min_confidence=0.0, fill_lambda=200.0, fill_sigma_color=8.0, median_px=5, fill_space="inverse",
                        edge_radius_px=0, edge_sigma_color=10.0, edge_sigma_px=5.0, edge_jump=0.05, edge_reach_px=4))


# ----------------------------------------------------------------------------------------------- the ablations


def fused_mirror_raw() -> PriorSweepMethod:
    """``fused-mirror-raw``: ``fused-mirror`` matching the images as they are with the told poses (no photometric
    or rig self-calibration) and the sweep's own cost always: what the self-calibration and the cost chosen with it
    do (on cameras that meter each on their own they are what keeps the sweep working)."""
    dis = builtin_flow("dis", {
        "preset": "medium", "finest_scale": 0, "patch_size": 8, "patch_stride": 3, "gd_iterations": 25,
        "var_iterations": 10, "var_alpha": 10.0, "spatial_propagation": True})
    limits = TriangulationLimits(min_angle_deg=3.0, min_parallax_rad=2e-4, d_min_m=0.05, d_max_m=100.0)
    # mode "none": the images as they are (the other fields are not used)
    photometric = PhotometricParams(
        mode="none", degree=2, pixel_degree=0, prepass_factor=2, ridge=0.0, factor=4, dark=0.01, bright=0.9,
        tukey_c=4.685, iterations=8, max_log_gain=2.0, even=False, central=True, common_field=False, min_gain=0.05,
        min_field=0.1, min_common=0.5, flat_log_gradient=0.1, alpha=0.001, agreement=0.05, response=1,
        min_response=0.1, prepass_flow=dis, max_fit_pixels=15000, hemispheres=0.0,
        longitude_blocks=16, min_block_samples=50)
    # mode "none": the told poses as they are (the other fields are not used)
    rig = RigParams(
        mode="none", max_fb_px=0.5, texture_quantile=0.7, min_sin=0.3, max_degrees=2.0, alpha=0.01, min_degrees=0.072,
        iterations=6, tukey_c=4.685, max_matches=40000, hemispheres=0.0, confirm_factor=1,
        longitude_blocks=16, min_block_samples=50)
    return PriorSweepMethod(
        label="fused-mirror-raw",
        flow=FlowMethod(flow=dis, rectify=True, refine=None, limits=limits, photometric=photometric, rig=rig),
        sweep=SweepMethod(
            pairs=("U", "R"), label="sweep", photometric=photometric, corrected_cost=None,
            refine_planes=PlaneRefineParams(
                select=0.12, search=0.15, steps=61, truncate=20.0, min_gradient=1.0, max_pixels=40000, min_cos=0.1,
                max_se=0.005, longitude_blocks=32, min_block_pixels=50, snap=0.06, rise=0.05, max_basin=0.03,
                far_share=0.05, wall_margin=0.2, wall_max_share=0.06,
                closed_max_share=0.10, closed_ceiling_share=0.04, ceiling_edge=0.99),
            cost=CostParams(
                d_min_m=0.3, d_max_m=30.0, levels=200, blur_px=0.0, gradient_weight=2.0, intensity_weight=1.0,
                truncate=30.0, box_px=1, scale=8.0, pair_power=2.0, feature="intensity", noise_blur=0.0,
                noise_floor=1.0, max_noise_blur_px=1.5, noise_scale=1, occlusion=0.0, occlusion_min_share=0.25,
                flat_contrast=1.0, flat_weight=0.5, flat_sigma_px=2.0, flat_min_noise=0.5,
                normalized_weight=0.0, normalized_contrast=1.0),
            planes=PlaneParams(
                per_side=32, h_min_m=0.3, h_max_m=5.0, bias=4, room_bound=True, bound_margin=0.1, bound_penalty=2.0,
                bound_penalty_min_az=0.2, bound_min_share=0.03, coarse_factor=2,
                wall_labels=9, wall_spread=0.1, wall_min_share=0.01, wall_yaw="normals-or-offsets",
                mirror_tolerance=0.2, room_labels=0, room_spread=0.2),
            sgm=SgmParams(p1=120, p2=800, p3=200, edge=8.0, paths=8),
            post=PostParams(min_confidence=0.1, fill_lambda=200.0, fill_sigma_color=4.0, median_px=5,
                            fill_space="inverse", edge_radius_px=0, edge_sigma_color=10.0, edge_sigma_px=5.0,
                            edge_jump=0.05, edge_reach_px=4)),
        prior=PriorParams(
            weight=16.0, truncate_levels=16.0, use_confidence=False, contrast_low=0.5, contrast_high=2.0,
            contrast_sigma_px=3.0, contrast_noise=0.0, contrast_blur=0.0, contrast_blur_floor=0.0,
            contrast_max_blur_px=3.0, sweep_confidence_power=1.0, agree_tolerance=0.05,
            frame_agreement_low=0.5, frame_agreement_high=0.7, frame_agreement_contrast=0.0,
            epipole_cone_deg=20.0, epipole_cone_noise_low=0.6, epipole_cone_noise_high=1.2,
            epipole_cone_fb_low=0.0, epipole_cone_fb_high=0.0, epipole_cone_room=0.1),
        quality_flow=FlowMethod(
            flow=dis, rectify=True, limits=limits, photometric=photometric, rig=rig,
            refine=RefineConfig(
                name="gradient", angle_power=2.0, gradient=True, gradient_scale=0.02, gradient_floor=0.05,
                color_weight=0.0, color_saturation=0.1, color_blur_px=1.0, color_rgb=False, color_patch=1,
                color_iters=6, color_min_gradient=0.01, lateral_px=1.0, lateral_max_px=3.0, fb_max_px=1.0,
                fallback_weight=1e-3, outlier_log_ratio=0.5, fill_lambda=1e4, fill_sigma_color=8.0, max_iters=30,
                tol_m=1e-7, description="LM, angle x epipolar-gradient weights (paper eq. 1)")))


def fused_mirror_told_rig() -> PriorSweepMethod:
    """``fused-mirror-told-rig``: ``fused-mirror`` with the told poses (no rig self-calibration; its photometric
    one as it is)."""
    dis = builtin_flow("dis", {
        "preset": "medium", "finest_scale": 0, "patch_size": 8, "patch_stride": 3, "gd_iterations": 25,
        "var_iterations": 10, "var_alpha": 10.0, "spatial_propagation": True})
    limits = TriangulationLimits(min_angle_deg=3.0, min_parallax_rad=2e-4, d_min_m=0.05, d_max_m=100.0)
    photometric = PhotometricParams(
        mode="gain-field", degree=2, pixel_degree=0, prepass_factor=2, ridge=0.0, factor=4, dark=0.01, bright=0.9,
        tukey_c=4.685, iterations=8, max_log_gain=2.0, even=False, central=True, common_field=False, min_gain=0.05,
        min_field=0.1, min_common=0.5, flat_log_gradient=0.1, alpha=0.001, agreement=0.05, response=1,
        min_response=0.1, prepass_flow=dis, max_fit_pixels=15000, hemispheres=0.0,
        longitude_blocks=16, min_block_samples=50)
    # mode "none": the told poses as they are (the other fields are not used)
    rig = RigParams(
        mode="none", max_fb_px=0.5, texture_quantile=0.7, min_sin=0.3, max_degrees=2.0, alpha=0.01, min_degrees=0.072,
        iterations=6, tukey_c=4.685, max_matches=40000, hemispheres=0.0, confirm_factor=1,
        longitude_blocks=16, min_block_samples=50)
    return PriorSweepMethod(
        label="fused-mirror-told-rig",
        flow=FlowMethod(flow=dis, rectify=True, refine=None, limits=limits, photometric=photometric, rig=rig),
        sweep=SweepMethod(
            pairs=("U", "R"), label="sweep", photometric=photometric,
            refine_planes=PlaneRefineParams(
                select=0.12, search=0.15, steps=61, truncate=20.0, min_gradient=1.0, max_pixels=40000, min_cos=0.1,
                max_se=0.005, longitude_blocks=32, min_block_pixels=50, snap=0.06, rise=0.05, max_basin=0.03,
                far_share=0.05, wall_margin=0.2, wall_max_share=0.06,
                closed_max_share=0.10, closed_ceiling_share=0.04, ceiling_edge=0.99),
            cost=CostParams(
                d_min_m=0.3, d_max_m=30.0, levels=200, blur_px=0.0, gradient_weight=2.0, intensity_weight=1.0,
                truncate=30.0, box_px=1, scale=8.0, pair_power=2.0, feature="intensity", noise_blur=0.0,
                noise_floor=1.0, max_noise_blur_px=1.5, noise_scale=1, occlusion=0.0, occlusion_min_share=0.25,
                flat_contrast=1.0, flat_weight=0.5, flat_sigma_px=2.0, flat_min_noise=0.5,
                normalized_weight=0.0, normalized_contrast=1.0),
            planes=PlaneParams(
                per_side=32, h_min_m=0.3, h_max_m=5.0, bias=4, room_bound=True, bound_margin=0.1, bound_penalty=2.0,
                bound_penalty_min_az=0.2, bound_min_share=0.03, coarse_factor=2,
                wall_labels=9, wall_spread=0.1, wall_min_share=0.01, wall_yaw="normals-or-offsets",
                mirror_tolerance=0.2, room_labels=0, room_spread=0.2),
            sgm=SgmParams(p1=120, p2=800, p3=200, edge=8.0, paths=8),
            post=PostParams(min_confidence=0.1, fill_lambda=200.0, fill_sigma_color=4.0, median_px=5,
                            fill_space="inverse", edge_radius_px=0, edge_sigma_color=10.0, edge_sigma_px=5.0,
                            edge_jump=0.05, edge_reach_px=4),
            corrected_cost=CostParams(
                d_min_m=0.3, d_max_m=30.0, levels=200, blur_px=0.7, gradient_weight=2.0, intensity_weight=0.25,
                truncate=30.0, box_px=1, scale=8.0, pair_power=2.0, feature="intensity", noise_blur=1.0,
                noise_floor=2.0, max_noise_blur_px=1.5, noise_scale=2, occlusion=0.0, occlusion_min_share=0.25,
                flat_contrast=1.0, flat_weight=0.5, flat_sigma_px=2.0, flat_min_noise=0.5,
                normalized_weight=0.0, normalized_contrast=1.0)),
        prior=PriorParams(
            weight=16.0, truncate_levels=16.0, use_confidence=False, contrast_low=0.5, contrast_high=2.0,
            contrast_sigma_px=3.0, contrast_noise=0.0, contrast_blur=0.0, contrast_blur_floor=0.0,
            contrast_max_blur_px=3.0, sweep_confidence_power=1.0, agree_tolerance=0.05,
            frame_agreement_low=0.5, frame_agreement_high=0.7, frame_agreement_contrast=0.0,
            epipole_cone_deg=20.0, epipole_cone_noise_low=0.6, epipole_cone_noise_high=1.2,
            epipole_cone_fb_low=0.0, epipole_cone_fb_high=0.0, epipole_cone_room=0.1),
        quality_flow=FlowMethod(
            flow=dis, rectify=True, limits=limits, photometric=photometric, rig=rig,
            refine=RefineConfig(
                name="gradient", angle_power=2.0, gradient=True, gradient_scale=0.02, gradient_floor=0.05,
                color_weight=0.0, color_saturation=0.1, color_blur_px=1.0, color_rgb=False, color_patch=1,
                color_iters=6, color_min_gradient=0.01, lateral_px=1.0, lateral_max_px=3.0, fb_max_px=1.0,
                fallback_weight=1e-3, outlier_log_ratio=0.5, fill_lambda=1e4, fill_sigma_color=8.0, max_iters=30,
                tol_m=1e-7, description="LM, angle x epipolar-gradient weights (paper eq. 1)")))


def fused_mirror_raw_images() -> PriorSweepMethod:
    """``fused-mirror-raw-images``: ``fused-mirror`` matching the images as they are (no photometric
    self-calibration, the sweep's own cost; its rig self-calibration as it is)."""
    dis = builtin_flow("dis", {
        "preset": "medium", "finest_scale": 0, "patch_size": 8, "patch_stride": 3, "gd_iterations": 25,
        "var_iterations": 10, "var_alpha": 10.0, "spatial_propagation": True})
    limits = TriangulationLimits(min_angle_deg=3.0, min_parallax_rad=2e-4, d_min_m=0.05, d_max_m=100.0)
    # mode "none": the images as they are; the rig self-calibration's pre-pass still reads prepass_factor and
    # prepass_flow
    photometric = PhotometricParams(
        mode="none", degree=2, pixel_degree=0, prepass_factor=2, ridge=0.0, factor=4, dark=0.01, bright=0.9,
        tukey_c=4.685, iterations=8, max_log_gain=2.0, even=False, central=True, common_field=False, min_gain=0.05,
        min_field=0.1, min_common=0.5, flat_log_gradient=0.1, alpha=0.001, agreement=0.05, response=1,
        min_response=0.1, prepass_flow=dis, max_fit_pixels=15000, hemispheres=0.0,
        longitude_blocks=16, min_block_samples=50)
    rig = RigParams(
        mode="rotation", max_fb_px=0.5, texture_quantile=0.7, min_sin=0.3, max_degrees=2.0, alpha=0.01,
        min_degrees=0.072, iterations=6, tukey_c=4.685, max_matches=40000, hemispheres=0.0,
        confirm_factor=1, longitude_blocks=16, min_block_samples=50)
    return PriorSweepMethod(
        label="fused-mirror-raw-images",
        flow=FlowMethod(flow=dis, rectify=True, refine=None, limits=limits, photometric=photometric, rig=rig),
        sweep=SweepMethod(
            pairs=("U", "R"), label="sweep", photometric=photometric, corrected_cost=None,
            refine_planes=PlaneRefineParams(
                select=0.12, search=0.15, steps=61, truncate=20.0, min_gradient=1.0, max_pixels=40000, min_cos=0.1,
                max_se=0.005, longitude_blocks=32, min_block_pixels=50, snap=0.06, rise=0.05, max_basin=0.03,
                far_share=0.05, wall_margin=0.2, wall_max_share=0.06,
                closed_max_share=0.10, closed_ceiling_share=0.04, ceiling_edge=0.99),
            cost=CostParams(
                d_min_m=0.3, d_max_m=30.0, levels=200, blur_px=0.0, gradient_weight=2.0, intensity_weight=1.0,
                truncate=30.0, box_px=1, scale=8.0, pair_power=2.0, feature="intensity", noise_blur=0.0,
                noise_floor=1.0, max_noise_blur_px=1.5, noise_scale=1, occlusion=0.0, occlusion_min_share=0.25,
                flat_contrast=1.0, flat_weight=0.5, flat_sigma_px=2.0, flat_min_noise=0.5,
                normalized_weight=0.0, normalized_contrast=1.0),
            planes=PlaneParams(
                per_side=32, h_min_m=0.3, h_max_m=5.0, bias=4, room_bound=True, bound_margin=0.1, bound_penalty=2.0,
                bound_penalty_min_az=0.2, bound_min_share=0.03, coarse_factor=2,
                wall_labels=9, wall_spread=0.1, wall_min_share=0.01, wall_yaw="normals-or-offsets",
                mirror_tolerance=0.2, room_labels=0, room_spread=0.2),
            sgm=SgmParams(p1=120, p2=800, p3=200, edge=8.0, paths=8),
            post=PostParams(min_confidence=0.1, fill_lambda=200.0, fill_sigma_color=4.0, median_px=5,
                            fill_space="inverse", edge_radius_px=0, edge_sigma_color=10.0, edge_sigma_px=5.0,
                            edge_jump=0.05, edge_reach_px=4)),
        prior=PriorParams(
            weight=16.0, truncate_levels=16.0, use_confidence=False, contrast_low=0.5, contrast_high=2.0,
            contrast_sigma_px=3.0, contrast_noise=0.0, contrast_blur=0.0, contrast_blur_floor=0.0,
            contrast_max_blur_px=3.0, sweep_confidence_power=1.0, agree_tolerance=0.05,
            frame_agreement_low=0.5, frame_agreement_high=0.7, frame_agreement_contrast=0.0,
            epipole_cone_deg=20.0, epipole_cone_noise_low=0.6, epipole_cone_noise_high=1.2,
            epipole_cone_fb_low=0.0, epipole_cone_fb_high=0.0, epipole_cone_room=0.1),
        quality_flow=FlowMethod(
            flow=dis, rectify=True, limits=limits, photometric=photometric, rig=rig,
            refine=RefineConfig(
                name="gradient", angle_power=2.0, gradient=True, gradient_scale=0.02, gradient_floor=0.05,
                color_weight=0.0, color_saturation=0.1, color_blur_px=1.0, color_rgb=False, color_patch=1,
                color_iters=6, color_min_gradient=0.01, lateral_px=1.0, lateral_max_px=3.0, fb_max_px=1.0,
                fallback_weight=1e-3, outlier_log_ratio=0.5, fill_lambda=1e4, fill_sigma_color=8.0, max_iters=30,
                tol_m=1e-7, description="LM, angle x epipolar-gradient weights (paper eq. 1)")))


def fused_mirror_shared_falloff() -> PriorSweepMethod:
    """``fused-mirror-shared-falloff``: ``fused-mirror`` that also removes the fall-off all three cameras share,
    where the frame supports it (``PhotometricParams.common_field``)."""
    dis = builtin_flow("dis", {
        "preset": "medium", "finest_scale": 0, "patch_size": 8, "patch_stride": 3, "gd_iterations": 25,
        "var_iterations": 10, "var_alpha": 10.0, "spatial_propagation": True})
    limits = TriangulationLimits(min_angle_deg=3.0, min_parallax_rad=2e-4, d_min_m=0.05, d_max_m=100.0)
    photometric = PhotometricParams(
        mode="gain-field", degree=2, pixel_degree=0, prepass_factor=2, ridge=0.0, factor=4, dark=0.01, bright=0.9,
        tukey_c=4.685, iterations=8, max_log_gain=2.0, even=False, central=True, min_gain=0.05, min_field=0.1,
        min_common=0.5, flat_log_gradient=0.1, alpha=0.001, agreement=0.05, response=1, min_response=0.1,
        prepass_flow=dis, max_fit_pixels=15000, hemispheres=0.0, longitude_blocks=16, min_block_samples=50,
        # what this ablation switches on
        common_field=True)
    rig = RigParams(
        mode="rotation", max_fb_px=0.5, texture_quantile=0.7, min_sin=0.3, max_degrees=2.0, alpha=0.01,
        min_degrees=0.072, iterations=6, tukey_c=4.685, max_matches=40000, hemispheres=0.0,
        confirm_factor=1, longitude_blocks=16, min_block_samples=50)
    return PriorSweepMethod(
        label="fused-mirror-shared-falloff",
        flow=FlowMethod(flow=dis, rectify=True, refine=None, limits=limits, photometric=photometric, rig=rig),
        sweep=SweepMethod(
            pairs=("U", "R"), label="sweep", photometric=photometric,
            refine_planes=PlaneRefineParams(
                select=0.12, search=0.15, steps=61, truncate=20.0, min_gradient=1.0, max_pixels=40000, min_cos=0.1,
                max_se=0.005, longitude_blocks=32, min_block_pixels=50, snap=0.06, rise=0.05, max_basin=0.03,
                far_share=0.05, wall_margin=0.2, wall_max_share=0.06,
                closed_max_share=0.10, closed_ceiling_share=0.04, ceiling_edge=0.99),
            cost=CostParams(
                d_min_m=0.3, d_max_m=30.0, levels=200, blur_px=0.0, gradient_weight=2.0, intensity_weight=1.0,
                truncate=30.0, box_px=1, scale=8.0, pair_power=2.0, feature="intensity", noise_blur=0.0,
                noise_floor=1.0, max_noise_blur_px=1.5, noise_scale=1, occlusion=0.0, occlusion_min_share=0.25,
                flat_contrast=1.0, flat_weight=0.5, flat_sigma_px=2.0, flat_min_noise=0.5,
                normalized_weight=0.0, normalized_contrast=1.0),
            planes=PlaneParams(
                per_side=32, h_min_m=0.3, h_max_m=5.0, bias=4, room_bound=True, bound_margin=0.1, bound_penalty=2.0,
                bound_penalty_min_az=0.2, bound_min_share=0.03, coarse_factor=2,
                wall_labels=9, wall_spread=0.1, wall_min_share=0.01, wall_yaw="normals-or-offsets",
                mirror_tolerance=0.2, room_labels=0, room_spread=0.2),
            sgm=SgmParams(p1=120, p2=800, p3=200, edge=8.0, paths=8),
            post=PostParams(min_confidence=0.1, fill_lambda=200.0, fill_sigma_color=4.0, median_px=5,
                            fill_space="inverse", edge_radius_px=0, edge_sigma_color=10.0, edge_sigma_px=5.0,
                            edge_jump=0.05, edge_reach_px=4),
            corrected_cost=CostParams(
                d_min_m=0.3, d_max_m=30.0, levels=200, blur_px=0.7, gradient_weight=2.0, intensity_weight=0.25,
                truncate=30.0, box_px=1, scale=8.0, pair_power=2.0, feature="intensity", noise_blur=1.0,
                noise_floor=2.0, max_noise_blur_px=1.5, noise_scale=2, occlusion=0.0, occlusion_min_share=0.25,
                flat_contrast=1.0, flat_weight=0.5, flat_sigma_px=2.0, flat_min_noise=0.5,
                normalized_weight=0.0, normalized_contrast=1.0)),
        prior=PriorParams(
            weight=16.0, truncate_levels=16.0, use_confidence=False, contrast_low=0.5, contrast_high=2.0,
            contrast_sigma_px=3.0, contrast_noise=0.0, contrast_blur=0.0, contrast_blur_floor=0.0,
            contrast_max_blur_px=3.0, sweep_confidence_power=1.0, agree_tolerance=0.05,
            frame_agreement_low=0.5, frame_agreement_high=0.7, frame_agreement_contrast=0.0,
            epipole_cone_deg=20.0, epipole_cone_noise_low=0.6, epipole_cone_noise_high=1.2,
            epipole_cone_fb_low=0.0, epipole_cone_fb_high=0.0, epipole_cone_room=0.1),
        quality_flow=FlowMethod(
            flow=dis, rectify=True, limits=limits, photometric=photometric, rig=rig,
            refine=RefineConfig(
                name="gradient", angle_power=2.0, gradient=True, gradient_scale=0.02, gradient_floor=0.05,
                color_weight=0.0, color_saturation=0.1, color_blur_px=1.0, color_rgb=False, color_patch=1,
                color_iters=6, color_min_gradient=0.01, lateral_px=1.0, lateral_max_px=3.0, fb_max_px=1.0,
                fallback_weight=1e-3, outlier_log_ratio=0.5, fill_lambda=1e4, fill_sigma_color=8.0, max_iters=30,
                tol_m=1e-7, description="LM, angle x epipolar-gradient weights (paper eq. 1)")))


def fused_gated() -> PriorSweepMethod:
    """``fused-gated``: the sweep with wall planes and the unrefined ``dis-rect:average`` distance as prior,
    weighted by C's texture, the sweep's confidence and the frame's agreement (chosen on the suite's dev split,
    docs/matching.md); ``fused-mirror`` without the room bound's mirror test and with the sweep's own cost always."""
    dis = builtin_flow("dis", {
        "preset": "medium", "finest_scale": 0, "patch_size": 8, "patch_stride": 3, "gd_iterations": 25,
        "var_iterations": 10, "var_alpha": 10.0, "spatial_propagation": True})
    limits = TriangulationLimits(min_angle_deg=3.0, min_parallax_rad=2e-4, d_min_m=0.05, d_max_m=100.0)
    photometric = PhotometricParams(
        mode="gain-field", degree=2, pixel_degree=0, prepass_factor=2, ridge=0.0, factor=4, dark=0.01, bright=0.9,
        tukey_c=4.685, iterations=8, max_log_gain=2.0, even=False, central=True, common_field=False, min_gain=0.05,
        min_field=0.1, min_common=0.5, flat_log_gradient=0.1, alpha=0.001, agreement=0.05, response=1,
        min_response=0.1, prepass_flow=dis, max_fit_pixels=15000, hemispheres=0.0,
        longitude_blocks=16, min_block_samples=50)
    rig = RigParams(
        mode="rotation", max_fb_px=0.5, texture_quantile=0.7, min_sin=0.3, max_degrees=2.0, alpha=0.01,
        min_degrees=0.072, iterations=6, tukey_c=4.685, max_matches=40000, hemispheres=0.0,
        confirm_factor=1, longitude_blocks=16, min_block_samples=50)
    return PriorSweepMethod(
        label="fused-gated",
        # the flow pipeline without its LM: about 0.6 s less per 1000x500 frame than fused's
        flow=FlowMethod(flow=dis, rectify=True, refine=None, limits=limits, photometric=photometric, rig=rig),
        sweep=SweepMethod(
            pairs=("U", "R"), label="sweep", photometric=photometric, corrected_cost=None,
            refine_planes=None,
            cost=CostParams(
                d_min_m=0.3, d_max_m=30.0, levels=160, blur_px=0.0, gradient_weight=2.0, intensity_weight=1.0,
                truncate=30.0, box_px=1, scale=8.0, pair_power=2.0, feature="intensity", noise_blur=0.0,
                noise_floor=1.0, max_noise_blur_px=1.5, noise_scale=1, occlusion=0.0, occlusion_min_share=0.25,
                flat_contrast=0.0, flat_weight=1.0, flat_sigma_px=2.0, flat_min_noise=0.5,
                normalized_weight=0.0, normalized_contrast=1.0),
            # the horizontal planes plus 9 labels per wall found by the coarse pass
            planes=PlaneParams(
                per_side=32, h_min_m=0.3, h_max_m=5.0, bias=4, room_bound=True, bound_margin=0.25, bound_penalty=0.0,
                bound_penalty_min_az=0.0, bound_min_share=0.03, coarse_factor=2,
                wall_labels=9, wall_spread=0.1, wall_min_share=0.01, wall_yaw="normals",
                mirror_tolerance=0.0, room_labels=0, room_spread=0.2),
            sgm=SgmParams(p1=120, p2=800, p3=200, edge=8.0, paths=8),
            post=PostParams(min_confidence=0.0, fill_lambda=200.0, fill_sigma_color=8.0, median_px=5,
                            fill_space="inverse", edge_radius_px=0, edge_sigma_color=10.0, edge_sigma_px=5.0,
                            edge_jump=0.05, edge_reach_px=4)),
        # fused's weight (16), times a ramp of C's local contrast (0 below 0.5, full above 2 gray levels), times
        # 1 - c_sweep where the flow and the plain coarse sweep disagree by more than 5 %, times the frame's
        # agreement share ramped from 0 at 50 % to full at 70 % (as fused-mirror's, which took it from here)
        prior=PriorParams(
            weight=16.0, truncate_levels=16.0, use_confidence=False, contrast_low=0.5, contrast_high=2.0,
            contrast_sigma_px=3.0, contrast_noise=0.0, contrast_blur=0.0, contrast_blur_floor=0.0,
            contrast_max_blur_px=3.0, sweep_confidence_power=1.0, agree_tolerance=0.05,
            frame_agreement_low=0.5, frame_agreement_high=0.7, frame_agreement_contrast=0.0,
            epipole_cone_deg=0.0, epipole_cone_noise_low=0.0, epipole_cone_noise_high=0.0,
            epipole_cone_fb_low=0.0, epipole_cone_fb_high=0.0, epipole_cone_room=0.0),
        # fused's refined flow distance, for the quality measures only (docs/real-captures.md)
        quality_flow=FlowMethod(
            flow=dis, rectify=True, limits=limits, photometric=photometric, rig=rig,
            refine=RefineConfig(
                name="gradient", angle_power=2.0, gradient=True, gradient_scale=0.02, gradient_floor=0.05,
                color_weight=0.0, color_saturation=0.1, color_blur_px=1.0, color_rgb=False, color_patch=1,
                color_iters=6, color_min_gradient=0.01, lateral_px=1.0, lateral_max_px=3.0, fb_max_px=1.0,
                fallback_weight=1e-3, outlier_log_ratio=0.5, fill_lambda=1e4, fill_sigma_color=8.0, max_iters=30,
                tol_m=1e-7, description="LM, angle x epipolar-gradient weights (paper eq. 1)")))


def fused_adaptive() -> PriorSweepMethod:
    """``fused-adaptive``: ``fused``'s flow prior in the sweep with wall planes, weighted by the frame's flow/sweep
    agreement only (chosen on the suite's dev split, docs/matching.md)."""
    dis = builtin_flow("dis", {
        "preset": "medium", "finest_scale": 0, "patch_size": 8, "patch_stride": 3, "gd_iterations": 25,
        "var_iterations": 10, "var_alpha": 10.0, "spatial_propagation": True})
    limits = TriangulationLimits(min_angle_deg=3.0, min_parallax_rad=2e-4, d_min_m=0.05, d_max_m=100.0)
    photometric = PhotometricParams(
        mode="gain-field", degree=2, pixel_degree=0, prepass_factor=2, ridge=0.0, factor=4, dark=0.01, bright=0.9,
        tukey_c=4.685, iterations=8, max_log_gain=2.0, even=False, central=True, common_field=False, min_gain=0.05,
        min_field=0.1, min_common=0.5, flat_log_gradient=0.1, alpha=0.001, agreement=0.05, response=1,
        min_response=0.1, prepass_flow=dis, max_fit_pixels=15000, hemispheres=0.0,
        longitude_blocks=16, min_block_samples=50)
    rig = RigParams(
        mode="rotation", max_fb_px=0.5, texture_quantile=0.7, min_sin=0.3, max_degrees=2.0, alpha=0.01,
        min_degrees=0.072, iterations=6, tukey_c=4.685, max_matches=40000, hemispheres=0.0,
        confirm_factor=1, longitude_blocks=16, min_block_samples=50)
    return PriorSweepMethod(
        label="fused-adaptive", quality_flow=None,
        flow=FlowMethod(
            flow=dis, rectify=True, limits=limits, photometric=photometric, rig=rig,
            refine=RefineConfig(
                name="gradient", angle_power=2.0, gradient=True, gradient_scale=0.02, gradient_floor=0.05,
                color_weight=0.0, color_saturation=0.1, color_blur_px=1.0, color_rgb=False, color_patch=1,
                color_iters=6, color_min_gradient=0.01, lateral_px=1.0, lateral_max_px=3.0, fb_max_px=1.0,
                fallback_weight=1e-3, outlier_log_ratio=0.5, fill_lambda=1e4, fill_sigma_color=8.0, max_iters=30,
                tol_m=1e-7, description="LM, angle x epipolar-gradient weights (paper eq. 1)")),
        sweep=SweepMethod(
            pairs=("U", "R"), label="sweep", photometric=photometric, corrected_cost=None,
            refine_planes=None,
            cost=CostParams(
                d_min_m=0.3, d_max_m=30.0, levels=160, blur_px=0.0, gradient_weight=2.0, intensity_weight=1.0,
                truncate=30.0, box_px=1, scale=8.0, pair_power=2.0, feature="intensity", noise_blur=0.0,
                noise_floor=1.0, max_noise_blur_px=1.5, noise_scale=1, occlusion=0.0, occlusion_min_share=0.25,
                flat_contrast=0.0, flat_weight=1.0, flat_sigma_px=2.0, flat_min_noise=0.5,
                normalized_weight=0.0, normalized_contrast=1.0),
            # the horizontal planes plus 9 labels per wall found by the coarse pass
            planes=PlaneParams(
                per_side=32, h_min_m=0.3, h_max_m=5.0, bias=4, room_bound=True, bound_margin=0.25, bound_penalty=0.0,
                bound_penalty_min_az=0.0, bound_min_share=0.03, coarse_factor=2,
                wall_labels=9, wall_spread=0.1, wall_min_share=0.01, wall_yaw="normals",
                mirror_tolerance=0.0, room_labels=0, room_spread=0.2),
            sgm=SgmParams(p1=120, p2=800, p3=200, edge=8.0, paths=8),
            post=PostParams(min_confidence=0.0, fill_lambda=200.0, fill_sigma_color=8.0, median_px=5,
                            fill_space="inverse", edge_radius_px=0, edge_sigma_color=10.0, edge_sigma_px=5.0,
                            edge_jump=0.05, edge_reach_px=4)),
        # fused's weight (16), scaled by the share of pixels where the flow and the plain coarse sweep agree within
        # 5 %: 0 below 60 %, full above 80 %
        prior=PriorParams(
            weight=16.0, truncate_levels=16.0, use_confidence=False, contrast_low=0.0, contrast_high=0.0,
            contrast_sigma_px=3.0, contrast_noise=0.0, contrast_blur=0.0, contrast_blur_floor=0.0,
            contrast_max_blur_px=3.0, sweep_confidence_power=0.0, agree_tolerance=0.05,
            frame_agreement_low=0.6, frame_agreement_high=0.8, frame_agreement_contrast=0.0,
            epipole_cone_deg=0.0, epipole_cone_noise_low=0.0, epipole_cone_noise_high=0.0,
            epipole_cone_fb_low=0.0, epipole_cone_fb_high=0.0, epipole_cone_room=0.0))


# ----------------------------------------------------------------------------------------------- the tables

#: the named built-in methods, the default (:data:`DEFAULT_METHOD`) among them; every flow-pipeline configuration
#: (``<flow>-<rect|plain>:<variant>``) is built in as well (:func:`reconstruction.methods.registry.flow_methods`)
PRESETS = (
    Preset("fused-mirror", fused_mirror,
           "the sweep over spheres, floor/ceiling and wall planes with the unrefined dis-rect distance as SGM prior, "
           "weighted by C's texture, the sweep's confidence and how much of the frame the two agree on; its room "
           "bound tells a polished floor's mirror image of the ceiling from the floor; its cost weighs intensity "
           "0.25 against gradients 2 on images blurred by 0.7 px when the self-calibration corrected them; the "
           "cameras' gains, fall-off and rotations self-calibrated where the frame's evidence supports it"),
    Preset("fused", fused,
           "the sweep over spheres and floor/ceiling planes (no wall planes) with the refined dis-rect:gradient "
           "distance as SGM prior at one constant weight"),
    Preset("sweep", sweep,
           "the trinocular sphere sweep with SGM over spheres and floor/ceiling planes alone: no flow, no prior"),
)

#: the default with one part switched off, and the methods it grew from: each is built in (``--method``), listed
#: by ``tri360 methods`` under "ablations", and measured in the docs
ABLATIONS = (
    Preset("fused-mirror-raw", fused_mirror_raw,
           "fused-mirror matching the images as they are with the told poses (no self-calibration, the sweep's own "
           "cost)"),
    Preset("fused-mirror-told-rig", fused_mirror_told_rig,
           "fused-mirror with the told poses (its photometric self-calibration only)"),
    Preset("fused-mirror-raw-images", fused_mirror_raw_images,
           "fused-mirror matching the images as they are (its rig self-calibration only, the sweep's own cost)"),
    Preset("fused-mirror-shared-falloff", fused_mirror_shared_falloff,
           "fused-mirror that also removes the fall-off all three cameras share, where the frame supports it "
           "(PhotometricParams.common_field)"),
    Preset("fused-gated", fused_gated,
           "fused-mirror without the room bound's mirror test and with the sweep's own cost always"),
    Preset("fused-adaptive", fused_adaptive,
           "the wall-plane sweep with fused's refined dis-rect:gradient distance as prior, weighted by the frame's "
           "flow/sweep agreement only (60-80 %), not by C's texture or the sweep's confidence"),
)

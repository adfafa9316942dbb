"""The method registry: built-in methods plus outside ones (entry-point group ``tri360.methods``).

Built in: the named methods of :data:`PRESETS` (one line each on what it does; ``tri360 methods`` lists them), and
every configuration of the paper's flow pipeline, labelled ``<flow>-<rect|plain>:<variant>`` for each flow backend
(:func:`reconstruction.flow.backends.discover_flows`, plus ``oracle``), rectified and plain, and each of
``average`` and the refinement variants (:func:`reconstruction.refine.lm.discover_variants`).
An outside package declares methods with an entry point that loads to a :class:`Method`, a list of them,
or a function returning them.  Nothing is registered at import time: :func:`discover_methods` builds the
registry each time it is called.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Sequence
from dataclasses import dataclass

from reconstruction.flow.backends import (
    ORACLE,
    RENAMED_FLOWS,
    discover_flows,
    flow_registry,
    refuse_shadowed_flow,
    renamed_flow_note,
)
from reconstruction.methods.base import Method
from reconstruction.methods.flow_pipeline import DEFAULT_FLOW, FlowMethod
from reconstruction.methods.prior_sweep import PriorParams, PriorSweepMethod
from reconstruction.methods.sweep import SweepMethod
from reconstruction.photometry import NO_CALIBRATION, PhotometricParams
from reconstruction.plugins import collect_registry, merge_registry, shadow_message
from reconstruction.refine.lm import refuse_shadowed_variant, variant_registry
from reconstruction.rig_calibration import NO_RIG_CALIBRATION
from reconstruction.sweep.cost import CostParams
from reconstruction.sweep.planes import PlaneParams

__all__ = ["ENTRY_POINT_GROUP", "DEFAULT_CONFIGS", "DEFAULT_METHOD", "DEFAULT_VARIANTS", "PAPER_CONFIG",
           "WALL_PLANES", "ADAPTIVE_PRIOR", "GATED_PRIOR", "builtin_methods", "discover_methods", "get_methods",
           "MIRROR_PLANES", "MIRROR_INTENSITY_WEIGHT", "MIRROR_BLUR_PX",
           "flow_methods", "evaluate_default_methods", "fused_method", "adaptive_method", "gated_method",
           "mirror_method", "Preset", "PRESETS", "ABLATIONS", "former_label_note", "with_photometric",
           "uncalibrated", "told_poses", "images_as_they_are"]

ENTRY_POINT_GROUP = "tri360.methods"
#: the paper's set-up: DeepFlow as published (DeepMatching + the DeepFlow energy) on rectified pairs (the baseline
#: rotated to the polar axis); ``deepflow-plain`` is the ablation on the unrotated images
PAPER_CONFIG = ("deepflow", True)
#: flow configurations evaluated by default: tri360's and the paper's set-up, both on rectified pairs
DEFAULT_CONFIGS = [(DEFAULT_FLOW, True), PAPER_CONFIG]
#: what ``tri360 reconstruct`` runs by default, :func:`mirror_method`: its matching chosen by
#: ``python -m tools.research.select_matching`` on the dev split of suites/tri360-v1.toml (docs/matching.md), its
#: photometric self-calibration and intensity weight by ``python -m tools.research.select_photometric`` on the dev split
#: of suites/tri360-v2.toml under both conditions (docs/photometry.md)
DEFAULT_METHOD = "fused-mirror"
#: the plane labels of ``fused-adaptive`` and ``fused-gated``: the sweep's horizontal planes plus 9 labels per wall
#: found by the coarse pass
WALL_PLANES = PlaneParams(wall_labels=9)
#: ``fused-mirror``'s plane labels: :data:`WALL_PLANES` with the mirror test of the room bound (a floor found by the
#: coarse pass within 20 % of where the ceiling's mirror image in a nearer, well-supported plane would be is that
#: mirror image: the nearer plane is the floor; likewise for the ceiling).  20 % is about two plane-label spacings
#: (the 32 heights per side are 9.5 % apart); on the dev split the mirrored floors it corrects lie 12-14 % off.
MIRROR_PLANES = dataclasses.replace(WALL_PLANES, mirror_tolerance=0.2)
#: ``fused-mirror``'s weight of the intensity difference in the sweep cost (the gradients' is 2): chosen by
#: ``python -m tools.research.select_photometric`` among 1, 0.5 and 0.25 on the dev split under both conditions
#: (docs/photometry.md)
MIRROR_INTENSITY_WEIGHT = 0.25
#: ``fused-mirror``'s Gaussian blur of the sweep's grey images, pixels: what a real camera's noise and JPEG leave
#: on far, weakly textured surfaces weighs less in the gradients; chosen by
#: ``python -m tools.research.select_photometric`` among 0, 0.5, 0.7 and 1 on the dev split under both conditions
#: (docs/photometry.md)
MIRROR_BLUR_PX = 0.7
#: ``fused-mirror``'s sweep, when the self-calibration corrected the images, blurs them by 1 px per gray level of
#: noise above 1 (up to 1.5 px; never less than :data:`MIRROR_BLUR_PX`): rendered frames measure 0.1-0.2 gray
#: levels, the suite's captured cameras 0.3-1.0 and its low-light ones 0.6-6
#: (``reconstruction.sweep.cost.image_noise``, tri360-v3 dev, docs/photometry.md)
MIRROR_NOISE_BLUR = 1.0
#: ``fused-adaptive``'s prior weight: ``fused``'s, scaled by the share of pixels where the flow and the plain coarse
#: sweep agree within 5 %: 0 below 60 %, full above 80 % (:class:`reconstruction.methods.prior_sweep.PriorParams`)
ADAPTIVE_PRIOR = PriorParams(frame_agreement_low=0.6, frame_agreement_high=0.8)
#: ``fused-gated``'s (and the default ``fused-mirror``'s) prior weight: ``fused``'s, times a ramp of C's local
#: contrast (0 below 0.5, full above 2 gray levels: no prior where there is no texture for the flow to follow), times
#: ``1 - c_sweep`` where the flow and the plain coarse sweep disagree by more than 5 % (a confident sweep keeps its
#: answer), times the frame's agreement share ramped from 0 at 50 % to full at 70 %
GATED_PRIOR = PriorParams(contrast_low=0.5, contrast_high=2.0, sweep_confidence_power=1.0, frame_agreement_low=0.5,
                          frame_agreement_high=0.7)
DEFAULT_VARIANTS = ("average", "angle", "gradient", "color")
"""The variants ``tri360 evaluate`` runs by default: the paper's (``color-rgb`` and ``color-patch``, its next steps,
measured no better on classroom frames, run when asked for)."""


def flow_methods(flows: Sequence[str], rectify: Sequence[bool],
                 variants: Sequence[str] | None = None) -> list[FlowMethod]:
    """Flow-pipeline methods for every (flow, rectification, variant) combination, in that order.

    Args:
        flows: flow backend names or ``"oracle"``.
        rectify: rectification settings to combine with every flow.
        variants: ``"average"`` and refinement variant names (default: all).
    Raises:
        ValueError: an unknown flow or variant name (the message lists the known ones).
    """
    flow_reg, variant_reg = flow_registry(), variant_registry()
    known_flows, flow_errors = flow_reg.entries, flow_reg.errors
    known_variants, variant_errors = variant_reg.entries, variant_reg.errors
    variants = ["average", *known_variants] if variants is None else list(variants)
    for name in flows:
        refuse_shadowed_flow(name, flow_reg)
    for name in variants:
        refuse_shadowed_variant(name, variant_reg)
    for name in flows:
        if name != ORACLE and name not in known_flows:
            if name in RENAMED_FLOWS:
                raise ValueError(renamed_flow_note(name))
            raise ValueError(f"unknown flow {name!r} (known: {', '.join(sorted([*known_flows, ORACLE]))})"
                             + _plugin_note(flow_errors))
    for name in variants:
        if name != "average" and name not in known_variants:
            raise ValueError(f"unknown variant {name!r} (known: average, {', '.join(known_variants)})"
                             + _plugin_note(variant_errors))
    out = []
    for name in dict.fromkeys(flows):
        flow = name if name == ORACLE else known_flows[name]
        for rect in dict.fromkeys(rectify):
            for v in dict.fromkeys(variants):
                out.append(FlowMethod(flow, rect, None if v == "average" else known_variants[v]))
    return out


def _plugin_note(errors: dict[str, str]) -> str:
    return ("; plugins that failed to load: " + "; ".join(f"{k}: {v}" for k, v in errors.items())) if errors else ""


def fused_method() -> PriorSweepMethod:
    """``fused``: the sweep with the ``{DEFAULT_FLOW}-rect:gradient`` distance as prior (docs/matching.md)."""
    return PriorSweepMethod(flow=flow_methods([DEFAULT_FLOW], [True], ["gradient"])[0])


def adaptive_method() -> PriorSweepMethod:
    """``fused-adaptive``: ``fused``'s flow prior in the sweep with :data:`WALL_PLANES`,
    weighted by :data:`ADAPTIVE_PRIOR` (chosen on the suite's dev split, docs/matching.md)."""
    base = fused_method()
    return PriorSweepMethod(flow=base.flow, sweep=dataclasses.replace(base.sweep, planes=WALL_PLANES),
                       prior=ADAPTIVE_PRIOR, label="fused-adaptive")


def gated_method() -> PriorSweepMethod:
    """``fused-gated``: the sweep with :data:`WALL_PLANES` and the
    ``{DEFAULT_FLOW}-rect:average`` distance (the flow pipeline without its LM: about 0.6 s less per 1000x500 frame
    than ``fused``'s) as prior, weighted by :data:`GATED_PRIOR` (chosen on the suite's dev split,
    docs/matching.md).  The quality measures compare its distance with ``fused``'s refined flow distance
    (``quality_flow``; computed only when the quality is assessed): on the dev split that ranks pixels by error
    better than the unrefined prior (docs/real-captures.md)."""
    base = fused_method()
    return PriorSweepMethod(flow=flow_methods([DEFAULT_FLOW], [True], ["average"])[0],
                       sweep=dataclasses.replace(base.sweep, planes=WALL_PLANES), prior=GATED_PRIOR,
                       label="fused-gated", quality_flow=base.flow)


def mirror_method() -> PriorSweepMethod:
    """``fused-mirror`` (the default): ``fused-gated`` with :data:`MIRROR_PLANES`, so that the room bound holds on
    polished floors whose mirror image of the ceiling wins the coarse pass, and the sweep cost's intensity term
    weighted :data:`MIRROR_INTENSITY_WEIGHT` (what a gain difference between the cameras leaves after the
    self-calibration weighs less against the gradients) and its images blurred by :data:`MIRROR_BLUR_PX` when the
    self-calibration changed the images (cameras that agree are matched with the sweep's own cost), then more
    (:data:`MIRROR_NOISE_BLUR`) where the images are noisier than the suite's captured cameras; chosen on the dev
    split of suites/tri360-v2.toml under both conditions and of tri360-v3 under its low-light family
    (docs/photometry.md)."""
    gated = gated_method()
    corrected = dataclasses.replace(gated.sweep.cost, intensity_weight=MIRROR_INTENSITY_WEIGHT,
                                    blur_px=MIRROR_BLUR_PX, noise_blur=MIRROR_NOISE_BLUR)
    return dataclasses.replace(gated, sweep=dataclasses.replace(gated.sweep, planes=MIRROR_PLANES,
                                                                corrected_cost=corrected),
                               label="fused-mirror")


def with_photometric(method: PriorSweepMethod, params: PhotometricParams, label: str) -> PriorSweepMethod:
    """``method`` with the photometric self-calibration ``params`` in its flow, its sweep and its quality flow,
    relabelled ``label``."""
    quality = method.quality_flow
    return dataclasses.replace(
        method, flow=dataclasses.replace(method.flow, photometric=params),
        sweep=dataclasses.replace(method.sweep, photometric=params), label=label,
        quality_flow=None if quality is None else dataclasses.replace(quality, photometric=params))


def uncalibrated(method: PriorSweepMethod) -> PriorSweepMethod:
    """``method`` matching the images as they are with the told poses (no photometric or rig self-calibration) and
    the sweep cost's default intensity weight and blur, labelled ``<label>-raw``: the ablation that shows what the
    self-calibration and the weight chosen with it do (on cameras that meter each on their own they are what keeps
    the sweep working)."""
    raw = with_photometric(method, NO_CALIBRATION, f"{method.label}-raw")
    cost = dataclasses.replace(raw.sweep.cost, intensity_weight=CostParams().intensity_weight,
                               blur_px=CostParams().blur_px)
    quality = raw.quality_flow
    return dataclasses.replace(raw, sweep=dataclasses.replace(raw.sweep, cost=cost, corrected_cost=None),
                               flow=dataclasses.replace(raw.flow, rig=NO_RIG_CALIBRATION),
                               quality_flow=None if quality is None else dataclasses.replace(quality,
                                                                                             rig=NO_RIG_CALIBRATION))


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


#: the named built-in methods, the default (:data:`DEFAULT_METHOD`) among them; every flow-pipeline configuration
#: (``<flow>-<rect|plain>:<variant>``) is built in as well (:func:`flow_methods`)
PRESETS = (
    Preset("fused-mirror", mirror_method,
           "the sweep over spheres, floor/ceiling and wall planes with the unrefined dis-rect distance as SGM prior, "
           "weighted by C's texture, the sweep's confidence and how much of the frame the two agree on; its room "
           "bound tells a polished floor's mirror image of the ceiling from the floor; its cost weighs intensity "
           "0.25 against gradients 2 on images blurred by 0.7 px when the self-calibration corrected them; the "
           "cameras' gains, fall-off and rotations self-calibrated where the frame's evidence supports it"),
    Preset("fused", fused_method,
           "the sweep over spheres and floor/ceiling planes (no wall planes) with the refined dis-rect:gradient "
           "distance as SGM prior at one constant weight"),
    Preset("sweep", SweepMethod,
           "the trinocular sphere sweep with SGM over spheres and floor/ceiling planes alone: no flow, no prior"),
)


def told_poses(method: PriorSweepMethod, label: str) -> PriorSweepMethod:
    """``method`` with the told poses (no rig self-calibration, its photometric one as it is), labelled ``label``."""
    quality = method.quality_flow
    return dataclasses.replace(method, label=label, flow=dataclasses.replace(method.flow, rig=NO_RIG_CALIBRATION),
                               quality_flow=None if quality is None else dataclasses.replace(quality,
                                                                                             rig=NO_RIG_CALIBRATION))


def images_as_they_are(method: PriorSweepMethod, label: str) -> PriorSweepMethod:
    """``method`` matching the images as they are (no photometric self-calibration, the sweep's own cost; its rig
    self-calibration as it is), labelled ``label``."""
    m = with_photometric(method, NO_CALIBRATION, label)
    return dataclasses.replace(m, sweep=dataclasses.replace(m.sweep, corrected_cost=None))


#: the default with one part switched off, and the methods it grew from: each is built in (``--method``), listed
#: by ``tri360 methods`` under "ablations", and measured in the docs
ABLATIONS = (
    Preset("fused-mirror-raw", lambda: uncalibrated(mirror_method()),
           "fused-mirror matching the images as they are with the told poses (no self-calibration, the sweep's own "
           "cost)"),
    Preset("fused-mirror-told-rig", lambda: told_poses(mirror_method(), "fused-mirror-told-rig"),
           "fused-mirror with the told poses (its photometric self-calibration only)"),
    Preset("fused-mirror-raw-images", lambda: images_as_they_are(mirror_method(), "fused-mirror-raw-images"),
           "fused-mirror matching the images as they are (its rig self-calibration only, the sweep's own cost)"),
    Preset("fused-mirror-shared-falloff",
           lambda: with_photometric(mirror_method(), dataclasses.replace(PhotometricParams(), common_field=True),
                                    "fused-mirror-shared-falloff"),
           "fused-mirror that also removes the fall-off all three cameras share, where the frame supports it "
           "(PhotometricParams.common_field)"),
    Preset("fused-gated", gated_method,
           "fused-mirror without the room bound's mirror test and with the sweep's own cost always"),
    Preset("fused-adaptive", adaptive_method,
           "the wall-plane sweep with fused's refined dis-rect:gradient distance as prior, weighted by the frame's "
           "flow/sweep agreement only (60-80 %), not by C's texture or the sweep's confidence"),
)


def builtin_methods() -> list[Method]:
    """The :data:`PRESETS`, the :data:`ABLATIONS`, then every configuration of the flow pipeline (all flows incl. the
    oracle, rectified and plain, all variants)."""
    return [*(p.build() for p in (*PRESETS, *ABLATIONS)),
            *flow_methods([*discover_flows()[0], ORACLE], [True, False])]


def discover_methods() -> tuple[dict[str, Method], dict[str, str]]:
    """Every method: the built-ins plus entry points of group ``tri360.methods``.

    Returns:
        ``(methods by label, errors by plugin source)``; an outside method whose label is taken (by a built-in
        or an earlier plugin) is refused and reported in the errors.
    """
    return merge_registry(builtin_methods(), ENTRY_POINT_GROUP, lambda m: isinstance(m, Method), "Method",
                          key=lambda m: m.label)


def former_label_note(label: str) -> str:
    """For a flow-pipeline label whose flow was renamed (:data:`reconstruction.flow.backends.RENAMED_FLOWS`), e.g.
    ``deepflowdm-rect:gradient``: ``"deepflowdm-rect:gradient is now called deepflow-rect:gradient"``; else
    ``""``."""
    for old, new in RENAMED_FLOWS.items():
        for rect in ("rect", "plain"):
            prefix = f"{old}-{rect}:"
            if label.startswith(prefix):
                return f"{label} is now called {new}-{rect}:{label[len(prefix):]}"
    return ""


def get_methods(labels: Sequence[str]) -> list[Method]:
    """Methods by label.

    Raises:
        ValueError: naming the unknown labels (a renamed one with its name now), the named built-in methods and
            ablations, the label pattern of the flow pipeline and the registered plugins' methods
            (each with its plugin); or a label that a refused plugin also provides (naming the plugin: an outside
            method never replaces a built-in or another plugin's).
    """
    reg = collect_registry(builtin_methods(), ENTRY_POINT_GROUP, lambda m: isinstance(m, Method), "Method",
                           key=lambda m: m.label)
    methods, errors = reg.entries, reg.errors
    for x in labels:
        if x in reg.refused:
            raise ValueError(shadow_message("method", x, reg))
    bad = [x for x in labels if x not in methods]
    if bad:
        former = [former_label_note(x) for x in bad if former_label_note(x)]
        if len(former) == len(bad):
            raise ValueError("; ".join(former))
        named = [p.label for p in PRESETS]
        ablations = [p.label for p in ABLATIONS]
        plugins = sorted(f"{k} ({reg.sources[k]})" if k in reg.sources else k for k, m in methods.items()
                         if not isinstance(m, FlowMethod) and k not in named and k not in ablations)
        raise ValueError(f"unknown method(s) {', '.join(bad)} (named methods: {', '.join(named)}; ablations: "
                         f"{', '.join(ablations)}; the flow pipeline: "
                         f"FLOW-rect:VARIANT or FLOW-plain:VARIANT, e.g. dis-rect:gradient; plugins' methods: "
                         f"{', '.join(plugins) or 'none'}; 'tri360 methods' lists them all)"
                         + (f"; {'; '.join(former)}" if former else "") + _plugin_note(errors))
    return [methods[x] for x in dict.fromkeys(labels)]


def evaluate_default_methods() -> list[Method]:
    """What ``tri360 evaluate`` runs by default: the default method (:data:`DEFAULT_METHOD`), the sweep, then
    tri360's flow pipeline and the paper's set-up (:data:`DEFAULT_CONFIGS`, both on rectified pairs), each with the
    paper's variants (:data:`DEFAULT_VARIANTS`)."""
    presets = {p.label: p for p in PRESETS}
    out: list[Method] = [presets[DEFAULT_METHOD].build(), presets["sweep"].build()]
    for flow, rect in DEFAULT_CONFIGS:
        out.extend(flow_methods([flow], [rect], list(DEFAULT_VARIANTS)))
    return out

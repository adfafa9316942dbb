"""The method registry: built-in methods plus outside ones (entry-point group ``tri360.methods``).

Built in: the named methods of :data:`PRESETS` and :data:`ABLATIONS` (one line each on what it does; ``tri360
methods`` lists them), each written out in full in :mod:`reconstruction.methods.presets`, and every configuration
of the paper's flow pipeline, labelled ``<flow>-<rect|plain>:<variant>`` for each flow backend
(:func:`reconstruction.flow.backends.discover_flows`, plus ``oracle``), rectified and plain, and each of
``average`` and the refinement variants (:func:`reconstruction.refine.lm.discover_variants`).
:func:`with_photometric` and :func:`uncalibrated` derive a variation of a flow-prior sweep (the research tools'
candidates, ``tools.bench.sweep``'s ``<label>-raw``); no preset is built with them.
An outside package declares methods with an entry point that loads to a :class:`Method`, a list of them,
or a function returning them.  Nothing is registered at import time: :func:`discover_methods` builds the
registry each time it is called.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence

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
from reconstruction.methods.presets import ABLATIONS, DEFAULT_METHOD, PRESETS, Preset
from reconstruction.methods.prior_sweep import PriorSweepMethod
from reconstruction.photometry import NO_CALIBRATION, PhotometricParams
from reconstruction.plugins import collect_registry, merge_registry, shadow_message
from reconstruction.refine.lm import refuse_shadowed_variant, variant_registry
from reconstruction.rig_calibration import NO_RIG_CALIBRATION
from reconstruction.sweep.cost import CostParams

__all__ = ["ENTRY_POINT_GROUP", "DEFAULT_CONFIGS", "DEFAULT_METHOD", "DEFAULT_VARIANTS", "PAPER_CONFIG",
           "builtin_methods", "discover_methods", "get_methods", "flow_methods", "evaluate_default_methods", "Preset",
           "PRESETS", "ABLATIONS", "former_label_note", "with_photometric", "uncalibrated"]

ENTRY_POINT_GROUP = "tri360.methods"
#: the paper's set-up: DeepFlow as published (DeepMatching + the DeepFlow energy) on rectified pairs (the baseline
#: rotated to the polar axis); ``deepflow-plain`` is the ablation on the unrotated images
PAPER_CONFIG = ("deepflow", True)
#: flow configurations evaluated by default: tri360's and the paper's set-up, both on rectified pairs
DEFAULT_CONFIGS = [(DEFAULT_FLOW, True), PAPER_CONFIG]
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


# ------------------------------------------------------------------------------- variations, for the tools


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
    the sweep cost's default intensity weight and blur always (no ``corrected_cost``), labelled ``<label>-raw``: the
    ablation that shows what the self-calibration and the cost chosen with it do (``uncalibrated(fused_mirror())``
    is the built-in :func:`reconstruction.methods.presets.fused_mirror_raw`).  The pre-pass flow stays ``method``'s
    (it runs only for a self-calibration)."""
    none = dataclasses.replace(NO_CALIBRATION, prepass_flow=method.flow.photometric.prepass_flow)
    raw = with_photometric(method, none, f"{method.label}-raw")
    cost = dataclasses.replace(raw.sweep.cost, intensity_weight=CostParams().intensity_weight,
                               blur_px=CostParams().blur_px)
    quality = raw.quality_flow
    return dataclasses.replace(raw, sweep=dataclasses.replace(raw.sweep, cost=cost, corrected_cost=None),
                               flow=dataclasses.replace(raw.flow, rig=NO_RIG_CALIBRATION),
                               quality_flow=None if quality is None else dataclasses.replace(quality,
                                                                                             rig=NO_RIG_CALIBRATION))


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

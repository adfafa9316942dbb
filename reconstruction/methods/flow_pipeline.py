"""The flow pipeline: flow -> per-pair triangulation -> ``average`` -> LM refinement variants (:func:`reconstruct`),
and each of its configurations as a :class:`Method` (:class:`FlowMethod`, labelled ``<flow>-<rect|plain>:<variant>``)
run with the others of its flow configuration and the methods built on them (:func:`run_flow_group`,
:class:`BuiltOnFlow`).

Its stages are :mod:`reconstruction.methods.self_calibration` (the frame calibrated once),
:mod:`reconstruction.methods.flow_stages` (flow, triangulation, ``average``) and
:mod:`reconstruction.methods.flow_refine` (one refinement variant).

>>> result = reconstruct(frame, flow="dis", rectify=True)        # doctest: +SKIP
>>> result.distance["gradient"]                                  # (H, W) float32 metres, camera C
"""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import asdict, dataclass, field
from typing import Protocol, runtime_checkable

import numpy as np

from reconstruction.flow.backends import ORACLE, FlowBackend
from reconstruction.methods.base import GroupedMethod, MethodOutput
from reconstruction.methods.flow_refine import refine_variant
from reconstruction.methods.flow_stages import PAIRS, flow_confidence, prepare
from reconstruction.methods.self_calibration import Calibration, self_calibrate
from reconstruction.photometry import NO_CALIBRATION, PhotometricParams
from reconstruction.refine.lm import RefineConfig, discover_variants, get_variant
from reconstruction.refine.triangulate import TriangulationLimits
from reconstruction.rig_calibration import NO_RIG_CALIBRATION, RigParams

__all__ = ["DEFAULT_FLOW", "Reconstruction", "reconstruct", "available_variants", "FlowMethod", "config_label",
           "BuiltOnFlow", "run_flow_group"]

DEFAULT_FLOW = "dis"  # chosen by measurement, see docs/refinement.md


def available_variants() -> list[str]:
    """``average`` (no refinement) followed by the registered LM variants."""
    return ["average", *discover_variants()[0]]


@dataclass
class Reconstruction:
    """Output of :func:`reconstruct`.

    Attributes:
        distance: (H, W) float32 distance of camera C per variant, metres (finite everywhere).
        pair_distance: (H, W) float32 per-pair triangulated distance ("U", "R"), metres.
        pair_valid: (H, W) bool per pair: False at the pair's epipoles or where its flow is unusable.
        pair_fb_px: (H, W) float32 per pair, the flow's forward-backward inconsistency at C's pixels, pixels
            (:attr:`reconstruction.flow.matching.PairMatch.fb_error_px`; 0 for the oracle).
        seconds: wall time per stage (``flow_U``, ``flow_R``, ``triangulate``, ``average``, each variant).
        iterations: LM iterations per variant.
        confidence: (H, W) float32 per variant, in [0, 1] (:func:`flow_confidence`).
        calibration: the self-calibration the flow matched with (:class:`Calibration`: the corrected frame and
            the record of what was fitted and applied).
    """

    distance: dict[str, np.ndarray] = field(default_factory=dict)
    pair_distance: dict[str, np.ndarray] = field(default_factory=dict)
    pair_valid: dict[str, np.ndarray] = field(default_factory=dict)
    pair_fb_px: dict[str, np.ndarray] = field(default_factory=dict)
    seconds: dict[str, float] = field(default_factory=dict)
    iterations: dict[str, int] = field(default_factory=dict)
    confidence: dict[str, np.ndarray] = field(default_factory=dict)
    calibration: Calibration | None = None


def reconstruct(frame, flow: str | FlowBackend = DEFAULT_FLOW, rectify: bool = True,
                variants: Sequence[str | RefineConfig] | None = None,
                limits: TriangulationLimits = TriangulationLimits(),
                on_stage: Callable[[str], None] | None = None,
                photometric: PhotometricParams = NO_CALIBRATION,
                rig: RigParams = NO_RIG_CALIBRATION) -> Reconstruction:
    """Reconstruct camera C's per-pixel distance from a frame's three images.

    Args:
        frame: a :class:`harness.data.frame.Frame`.
        flow: a flow backend or its name (:func:`reconstruction.flow.backends.available_flows`), or "oracle".
        rectify: compute each pair's flow on rectified images (default) or plain equirect ones.
        variants: which outputs to produce: "average" and refinement variants, by name or as
            :class:`RefineConfig` (default: all of :func:`available_variants`).
        limits: when a pair's estimate counts as invalid, and the distance clamp.
        on_stage: optional callback called with each stage name before it runs (progress display).
        photometric, rig: the self-calibration (:func:`self_calibrate`; not for the oracle): the flow, the
            triangulation and every variant use its frame (``Reconstruction.calibration``).
    Returns:
        A :class:`Reconstruction`.
    Raises:
        ValueError: unknown flow or variant, or the oracle without ground truth.
    """
    variants = list(available_variants() if variants is None else variants)
    # resolve names before any work (an unknown one fails fast)
    configs = {v.name: v for v in (v if isinstance(v, RefineConfig) else get_variant(v)
                                   for v in variants if v != "average")}
    h, w = frame.height, frame.width
    note = on_stage or (lambda _s: None)
    calibration = self_calibrate(frame, photometric, rig, limits, flow != ORACLE, note)
    frame = calibration.frame
    prep = prepare(frame, flow, rectify, limits, note)
    out = Reconstruction(seconds={**calibration.seconds, **prep.seconds}, calibration=calibration)
    for k in PAIRS:
        out.pair_distance[k] = prep.d_pair[k].reshape(h, w).astype(np.float32)
        out.pair_valid[k] = prep.valid[k].reshape(h, w)
        out.pair_fb_px[k] = np.asarray(prep.matches[k].fb_error_px, np.float32).reshape(h, w)
    if "average" in variants:
        out.distance["average"] = prep.d0.reshape(h, w).astype(np.float32)
        out.confidence["average"] = flow_confidence(out.distance["average"], prep)
    for name, config in configs.items():
        note(name)
        start = time.perf_counter()
        d, iters = refine_variant(frame, prep, config)
        out.seconds[name] = time.perf_counter() - start
        out.iterations[name] = iters
        out.distance[name] = d.astype(np.float32)
        out.confidence[name] = flow_confidence(out.distance[name], prep)
    return out


def config_label(flow: str, rectify: bool) -> str:
    """Label of a flow configuration, e.g. ``dis-rect`` or ``deepflow-plain``."""
    return f"{flow}-{'rect' if rectify else 'plain'}"


@dataclass(frozen=True)
class FlowMethod:
    """One configuration of the paper's flow pipeline (flow, rectification, variant) as a :class:`Method`.

    A :class:`~reconstruction.methods.base.GroupedMethod`: the variants of one flow configuration, and the methods
    built on one of them (:class:`BuiltOnFlow`), share a ``group_key`` and run together (:func:`run_flow_group`).

    Attributes:
        flow: the flow backend, or ``"oracle"`` (exact correspondences from ground truth).
        rectify: flow on rectified pairs (True) or on the plain equirect images (False, the paper).
        refine: the refinement variant, or None for ``average`` (the paper's "before optimisation").
        limits: triangulation validity limits and distance clamp.
        photometric: photometric self-calibration of U and R against C before the flow and the colour terms
            (:class:`reconstruction.photometry.PhotometricParams`; mode ``"none"`` = the images as they are).
        rig: rig self-calibration of U's and R's rotations against C before the flow
            (:class:`reconstruction.rig_calibration.RigParams`; mode ``"none"`` = the told poses as they are).
    """

    flow: FlowBackend | str
    rectify: bool = True
    refine: RefineConfig | None = None
    limits: TriangulationLimits = TriangulationLimits()
    photometric: PhotometricParams = PhotometricParams()
    rig: RigParams = RigParams()

    @property
    def flow_name(self) -> str:
        return self.flow if isinstance(self.flow, str) else self.flow.name

    @property
    def variant(self) -> str:
        return "average" if self.refine is None else self.refine.name

    @property
    def label(self) -> str:
        return f"{config_label(self.flow_name, self.rectify)}:{self.variant}"

    @property
    def group_key(self) -> tuple:
        """Methods with equal keys share the flow, triangulation and ``average`` stages."""
        flow = self.flow if isinstance(self.flow, str) else (self.flow.name, repr(sorted(self.flow.params.items())))
        return ("flow-pipeline", flow, self.rectify, self.limits, self.photometric, self.rig)

    def config(self) -> dict:
        flow = {"name": self.flow} if isinstance(self.flow, str) else self.flow.config()
        return {"kind": "flow-pipeline", "label": self.label, "flow": flow, "rectify": self.rectify,
                "variant": self.variant, "refine": None if self.refine is None else self.refine.config(),
                "triangulation": asdict(self.limits), "photometric": self.photometric.config(),
                "rig": asdict(self.rig)}

    def run(self, frame) -> MethodOutput:
        return self.run_group(frame, [self])[self.label]

    def run_group(self, frame, members: Sequence,
                  on_stage: Callable[[str], None] | None = None) -> dict[str, MethodOutput]:
        """Run several variants of this flow configuration at once (flow and triangulation computed once), and
        the methods built on them (:func:`run_flow_group`)."""
        return run_flow_group(frame, members, on_stage)

    def outputs(self, result: Reconstruction, members: Sequence[FlowMethod]) -> dict[str, MethodOutput]:
        """The outputs of ``members`` (variants of this configuration) from one :func:`reconstruct` result."""
        shared = {k: result.seconds[k] for k in ("rig", "photometric", "flow_U", "flow_R", "triangulate", "average")
                  if k in result.seconds}
        calibration = result.calibration
        outs = {}
        for m in members:
            own = {m.variant: result.seconds[m.variant]} if m.refine is not None else {}
            seconds = {**shared, **own}
            seconds["total"] = sum(seconds.values())
            info = {"lm_iterations": result.iterations[m.variant]} if m.refine is not None else {}
            if calibration is not None and calibration.record:
                info["calibration"] = calibration.record
                info["applied"] = calibration.applied
            outs[m.label] = MethodOutput(distance=result.distance[m.variant], confidence=result.confidence[m.variant],
                                         seconds=seconds, info=info)
        return outs


@runtime_checkable
class BuiltOnFlow(GroupedMethod, Protocol):
    """A method built on a flow-pipeline method's distance (e.g. the flow-prior sweep,
    :class:`reconstruction.methods.prior_sweep.PriorSweepMethod`): it runs in its flow's group
    (:func:`run_flow_group`), which computes the flow along with the group's :class:`FlowMethod` variants.

    Its ``group_key`` is its flow's (``flow.group_key``) and its ``run_group`` is :func:`run_flow_group`.
    """

    @property
    def flow(self) -> FlowMethod:
        """The flow-pipeline method whose output it is built on."""
        ...

    def run_on_flows(self, calibration: Calibration, members: Sequence[BuiltOnFlow],
                     flow_outputs: dict[str, MethodOutput],
                     on_stage: Callable[[str], None] | None = None,
                     fb_error_px: Mapping[str, np.ndarray] | None = None) -> dict[str, MethodOutput]:
        """Run ``members`` (all of this method's type in the group, itself among them) given their flows' outputs
        (``flow_outputs``: by flow label) on the frame their flow matched (``calibration.frame``: self-calibrated
        once, :func:`reconstruction.methods.self_calibration.self_calibrate`) and, per pair, the flow's
        forward-backward inconsistency at C's pixels (``fb_error_px``: (H, W) pixels, :attr:`Reconstruction.
        pair_fb_px`).

        Returns:
            Outputs by member label.
        """
        ...


def run_flow_group(frame, members: Sequence[FlowMethod | BuiltOnFlow],
                   on_stage: Callable[[str], None] | None = None) -> dict[str, MethodOutput]:
    """Run methods that share one flow configuration (one ``group_key``), the flow and triangulation once.

    ``members`` are :class:`FlowMethod` variants of the configuration and methods built on one of them
    (:class:`BuiltOnFlow`, such as the flow-prior sweep): the flow variants those use are computed along with the
    members' own, and each type of them runs once, through its first member's ``run_on_flows``, given the flow
    outputs by label and the flow's :class:`Calibration` (the frame they match: self-calibrated once,
    :func:`self_calibrate`).

    Returns:
        Outputs by member label.
    Raises:
        TypeError: a member that is neither a :class:`FlowMethod` nor :class:`BuiltOnFlow`.
        ValueError: members of different flow configurations.
    """
    own = [m for m in members if isinstance(m, FlowMethod)]
    users = [m for m in members if not isinstance(m, FlowMethod)]
    strangers = [m.label for m in users if not isinstance(m, BuiltOnFlow)]
    if strangers:
        raise TypeError("methods neither of the flow pipeline nor built on it in a flow group: "
                        + ", ".join(strangers))
    needed = {m.label: m for m in own}
    for u in users:
        needed.setdefault(u.flow.label, u.flow)
    flows = list(needed.values())
    head = flows[0]
    if any(m.group_key != head.group_key for m in [*flows, *users]):
        raise ValueError("methods of different flow configurations in one group: "
                         + ", ".join(m.label for m in members))
    wanted = [m.refine if m.refine is not None else "average" for m in flows]
    result = reconstruct(frame, head.flow, head.rectify, wanted, head.limits, on_stage, head.photometric, head.rig)
    flow_outs = head.outputs(result, flows)
    outs = {m.label: flow_outs[m.label] for m in own}
    by_type: dict[type, list] = {}
    for u in users:
        by_type.setdefault(type(u), []).append(u)
    for kind in by_type.values():  # they match the frame the flow matched: one self-calibration per frame
        outs.update(kind[0].run_on_flows(result.calibration, kind, flow_outs, on_stage, result.pair_fb_px))
    return {m.label: outs[m.label] for m in members}

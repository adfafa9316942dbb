"""The flow-prior sweep: the sphere sweep with the flow pipeline's distance as a prior inside SGM
(:class:`PriorSweepMethod`).  The built-in ``fused`` and the default ``fused-mirror`` (presets in
:mod:`reconstruction.methods.presets`) are two; ``fused-mirror`` is tri360's most accurate method.

The flow pipeline (DIS on rectified pairs + the ``gradient`` LM variant) matches large structures well (coarse-
to-fine flow) but blurs edges and is noisy on weak texture; the trinocular sweep is sharp and robust to glossy
reflections (room bound) but locks onto shifted periods of repeating patterns (tiled floors) where only one pair
sees texture.  The flow-prior sweep adds the flow's evidence to the sweep's cost volume before aggregation: every
sphere label ``i`` of pixel p costs ``weight * min(|i - l_flow(p)|, truncate_levels)`` more (``l_flow`` = the flow
distance's fractional label), then the plane labels, SGM, winner, confidence and median run as in ``sweep``.
Measured in docs/matching.md.

The weight can follow where the flow is trustworthy instead of being one constant (:class:`PriorParams`): scaled
by the flow's confidence (pair support), gated by the local contrast of C's image, by the plain sweep's confidence
where it disagrees with the flow, and per frame by how much of the frame flow and sweep agree on (the plain sweep
being the coarse room-bound pass, which runs anyway), so that in rooms and regions where the flow has no evidence
the sweep's own aggregation decides.  A flow-prior sweep shares the flow with the flow-pipeline methods of its
configuration (one ``group_key``), and several flow-prior sweeps of one sweep configuration share the room-bound
pass and the cost volume (:func:`reconstruction.methods.sweep.sweep_distances`).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import asdict, dataclass, field

import numpy as np

from reconstruction.camera.equirect import baseline_cosine
from reconstruction.camera.image_ops import local_contrast
from reconstruction.methods.base import MethodOutput
from reconstruction.methods.flow_pipeline import FlowMethod, run_flow_group
from reconstruction.methods.self_calibration import Calibration
from reconstruction.methods.sweep import Prior, PriorFromSweep, SgmParams, SweepMethod, sweep_distances
from reconstruction.sweep.cost import FLAT_NOISE_SCALE, CostParams, blur_for_noise, gray_float, image_noise

__all__ = ["PriorParams", "PriorSweepMethod", "contrast_above_noise", "cone_floor", "default_sweep", "epipole_cone",
           "prior_weight", "sweep_gate"]


def default_sweep() -> SweepMethod:
    """The sweep configuration of a flow-prior sweep by default (the ``fused`` preset's): the sweep's defaults,
    which were chosen with the prior (over the 4 classroom frames + synthetic_box, docs/matching.md) and also serve
    the plain sweep best: a strong +-1-step penalty (P1 120, P2 800), truncation 30 gray levels, 160 labels and
    pixel-wise costs (no blur, no box filter, gradients weighted 2)."""
    return SweepMethod(cost=CostParams(), sgm=SgmParams())


@dataclass(frozen=True)
class PriorParams:
    """How strongly the flow distance pulls the sweep's labels, per pixel.

    The weight of pixel p is ``weight * conf(p) * gate(p) * sweep(p)``: ``conf`` the flow's confidence when
    ``use_confidence`` (else 1), ``gate`` a ramp of C's local contrast ``c(p)`` (:func:`contrast_above_noise`) from 0
    at ``contrast_low`` to 1 at ``contrast_high`` when ``contrast_high > 0`` (else 1), ``sweep`` the factor from the
    plain sweep's agreement with the flow and its confidence (:func:`sweep_gate`; 1 when both of its options are
    off).  The defaults are ``fused``'s one constant.

    Attributes:
        weight: cost units (see ``CostParams.scale``: 8 per gray level) per sphere label between a hypothesis and
            the flow's distance.
        truncate_levels: label distance beyond which the prior cost stops growing, labels (robust: a wrong flow
            distance costs at most ``weight * truncate_levels``).
        use_confidence: scale the weight per pixel by the flow's confidence (``flow_confidence``) instead of 1.
        contrast_low, contrast_high: local contrast (gray levels, 0-255 scale) below which the prior is off and
            above which it has its full weight; ``contrast_high`` 0 = no gate.
        contrast_sigma_px: Gaussian window of the local contrast, pixels.
        contrast_noise: the gate reads C's contrast above its noise, ``sqrt(max(c^2 - (contrast_noise * n)^2, 0))``
            with ``n`` C's noise in gray levels (:func:`reconstruction.sweep.cost.image_noise` at
            :data:`reconstruction.sweep.cost.FLAT_NOISE_SCALE`, where what JPEG coding leaves of the noise still
            shows): a camera's noise alone opens the gate on a plain wall, where the flow has nothing to follow;
            0 = the contrast as it is.
        contrast_blur, contrast_blur_floor, contrast_max_blur_px: the gate reads the contrast of C's gray image
            blurred (Gaussian sigma) by ``contrast_blur * (n - contrast_blur_floor)`` pixels, at most
            ``contrast_max_blur_px`` (:func:`reconstruction.sweep.cost.blur_for_noise`; ``n`` as above, in gray
            levels): a blur takes more of a camera's noise out of the contrast than of a texture coarser than the
            blur, and where ``n`` is at most the floor (a rendering's residual noise) there is no blur at all;
            ``contrast_blur`` in pixels per gray level, 0 = off.
        sweep_confidence_power: k > 0: where the flow and the plain sweep (the coarse room-bound pass, no prior,
            upsampled: no extra aggregation) disagree by more than ``agree_tolerance`` (relative), the weight is
            scaled by ``(1 - c_sweep)^k``, ``c_sweep`` the plain sweep's confidence: a confident sweep keeps its
            answer, an ambiguous one takes the flow's; 0 = off.
        agree_tolerance: relative difference (|ln(d_flow / d_sweep)|) below which flow and sweep agree.
        frame_agreement_low, frame_agreement_high: the frame's share of pixels where flow and plain sweep agree
            scales the whole prior, from 0 at ``low`` to 1 at ``high`` (a frame whose flow disagrees with the
            sweep almost everywhere gets no prior); ``high`` 0 = off.
        frame_agreement_contrast: that share counts only C's pixels whose local contrast above C's noise
            (:func:`contrast_above_noise`, window ``contrast_sigma_px``) is at least this, gray levels: where C
            shows no texture the flow and the sweep agree by chance, and a camera's noise makes them disagree
            there, so the share over every pixel falls with the noise while the flow is no worse where it has
            texture to follow; 0 = every pixel counts.
        epipole_cone_deg: within this angle (degrees) of the vertical pair's epipoles (C's bearings along the
            baseline C -> U, up or down: the ceiling and the floor below the rig) the frame's agreement factor is
            at least a floor (the next two fields; :func:`cone_floor`), the per-pixel factors still apply: there
            only the other pair has parallax, and the sweep alone locks onto a period of a tiled floor that the
            flow's coarse-to-fine distance keeps, while the frame's share falls with a camera's noise elsewhere;
            0 = the frame's factor everywhere (so too without the frame's gate, ``frame_agreement_high`` 0).
        epipole_cone_noise_low, epipole_cone_noise_high: the cone spares the frame's factor in proportion to the
            rig's noise (the largest of the three images' :func:`reconstruction.sweep.cost.image_noise` at
            :data:`reconstruction.sweep.cost.FLAT_NOISE_SCALE`, gray levels), from not at all at ``low`` to fully
            at ``high`` (the factor there is ``max(frame factor, that share)``): on a rig with noise-free cameras
            a low share says the flow is wrong, not the noise; ``high`` 0 = fully on every frame.
        epipole_cone_fb_low, epipole_cone_fb_high: the cone spares the frame's factor only where the other pair's
            flow (C -> R, the pair with parallax there) is consistent: at each pixel the spare is scaled from 1 at
            ``low`` to 0 at ``high`` of that flow's forward-backward inconsistency, pixels
            (:attr:`reconstruction.flow.matching.PairMatch.fb_error_px`); ``high`` 0 = off (as in every preset: a
            flow that follows a camera's noise on a plain floor can come back to where it started too).
        epipole_cone_room: the cone spares the frame's factor only where the flow's distance lies within this
            relative tolerance (``|ln(d_flow / d_room)|``) of the floor or the ceiling the sweep's coarse pass
            found (``d_room`` along C's bearing, :func:`reconstruction.sweep.planes.room_plane_distance`): there the
            prior can only pull towards the room's plane, so a flow that follows a camera's noise on a plain floor
            is not kept where the sweep and the plane had it right; 0 = off.
    """

    weight: float = 16.0
    truncate_levels: float = 16.0
    use_confidence: bool = False
    contrast_low: float = 0.0
    contrast_high: float = 0.0
    contrast_sigma_px: float = 3.0
    contrast_noise: float = 0.0
    contrast_blur: float = 0.0
    contrast_blur_floor: float = 0.0
    contrast_max_blur_px: float = 3.0
    sweep_confidence_power: float = 0.0
    agree_tolerance: float = 0.05
    frame_agreement_low: float = 0.0
    frame_agreement_high: float = 0.0
    frame_agreement_contrast: float = 0.0
    epipole_cone_deg: float = 0.0
    epipole_cone_noise_low: float = 0.0
    epipole_cone_noise_high: float = 0.0
    epipole_cone_fb_low: float = 0.0
    epipole_cone_fb_high: float = 0.0
    epipole_cone_room: float = 0.0

    def __post_init__(self):
        for low, high in (("contrast_low", "contrast_high"), ("frame_agreement_low", "frame_agreement_high"),
                          ("epipole_cone_noise_low", "epipole_cone_noise_high"),
                          ("epipole_cone_fb_low", "epipole_cone_fb_high")):
            lo, hi = getattr(self, low), getattr(self, high)
            if hi > 0 and not lo < hi:
                raise ValueError(f"{low} {lo} must be below {high} {hi}")
        for name in ("contrast_noise", "frame_agreement_contrast", "contrast_blur", "contrast_blur_floor",
                     "contrast_max_blur_px", "epipole_cone_fb_low", "epipole_cone_room"):
            if not getattr(self, name) >= 0:
                raise ValueError(f"{name} must be >= 0, got {getattr(self, name)}")
        if not 0.0 <= self.epipole_cone_deg < 90.0:
            raise ValueError(f"epipole_cone_deg must be in [0, 90), got {self.epipole_cone_deg}")

    @property
    def needs_plain_sweep(self) -> bool:
        """Whether the weight depends on the plain sweep's result (the coarse pass's, upsampled)."""
        return self.sweep_confidence_power > 0 or self.frame_agreement_high > 0


def contrast_above_noise(image: np.ndarray, sigma_px: float, noise_factor: float = 1.0,
                         blur: tuple[float, float, float] = (0.0, 0.0, 0.0)) -> np.ndarray:
    """C's local contrast above its noise: ``sqrt(max(c^2 - (noise_factor * n)^2, 0))``, ``c`` the local standard
    deviation of the gray image (:func:`reconstruction.camera.image_ops.local_contrast`), blurred first by a width
    that grows with ``n`` (``blur``), and ``n`` the image's noise (:func:`reconstruction.sweep.cost.image_noise` at
    :data:`reconstruction.sweep.cost.FLAT_NOISE_SCALE`, where what JPEG coding leaves of the noise still shows): on
    a plain surface a camera's noise alone is the contrast.

    Args:
        image: (H, W, 3) uint8 image; sigma_px: the contrast's Gaussian window, pixels; noise_factor: ``n``'s
            multiple subtracted (0 = the contrast as it is; ``n`` is the noise before any blur);
        blur: (pixels per gray level, floor in gray levels, largest blur in pixels) of
            :func:`reconstruction.sweep.cost.blur_for_noise` (first 0 = no blur).
    Returns:
        (H, W) float32 gray levels (0-255 scale).
    """
    noise = image_noise(image, FLAT_NOISE_SCALE) if noise_factor > 0 or blur[0] > 0 else 0.0
    c = local_contrast(gray_float(image, blur_for_noise(noise, *blur)), sigma_px)
    if noise_factor > 0:
        n = np.float32(noise_factor * noise)
        c = np.sqrt(np.maximum(c * c - n * n, 0.0))
    return c


def prior_weight(params: PriorParams, image: np.ndarray, confidence: np.ndarray | None) -> np.ndarray:
    """The prior's per-pixel weight (:class:`PriorParams`).

    Args:
        image: (H, W, 3) uint8 image of C; confidence: (H, W) flow confidence in [0, 1], or None.
    Returns:
        (H, W) float32 cost units per label.
    """
    w = np.full(image.shape[:2], params.weight, np.float32)
    if params.use_confidence and confidence is not None:
        w *= np.asarray(confidence, np.float32)
    if params.contrast_high > 0:
        c = contrast_above_noise(image, params.contrast_sigma_px, params.contrast_noise,
                                 (params.contrast_blur, params.contrast_blur_floor, params.contrast_max_blur_px))
        w *= np.clip((c - params.contrast_low) / (params.contrast_high - params.contrast_low), 0.0, 1.0)
    return w


def epipole_cone(width: int, height: int, c_position, c_rotation, other_position, cone_deg: float) -> np.ndarray:
    """C's pixels whose bearing lies within ``cone_deg`` of the baseline C -> other or of its opposite (the pair's
    two epipoles).

    Args:
        width, height: C's image size, pixels; c_position, other_position: (3,) camera centres, metres (world);
        c_rotation: (3, 3) C's world-from-camera rotation; cone_deg: half-angle, degrees (0: no pixel).
    Returns:
        (H, W) bool.
    Raises:
        ValueError: the two centres coincide (:func:`reconstruction.camera.equirect.baseline_cosine`).
    """
    cos_angle = baseline_cosine(width, height, c_rotation, c_position, other_position)
    return np.abs(cos_angle) > np.cos(np.deg2rad(cone_deg)) if cone_deg > 0 else np.zeros((height, width), bool)


def cone_floor(params: PriorParams, frame, fb_error_px: np.ndarray | None = None) -> np.ndarray:
    """The least the frame's agreement factor may be at each of C's pixels (:class:`PriorParams`
    ``epipole_cone_*``): the rig's noise share inside U's epipole cone, scaled down where the C -> R flow is
    inconsistent, 0 outside.

    Args:
        frame: the frame (its cameras C and U placed, its images C, R, U: (H, W, 3) uint8).
        fb_error_px: (H, W) forward-backward inconsistency of the C -> R flow at C's pixels, pixels; needed when
            ``epipole_cone_fb_high`` > 0 (ValueError without it).
    Returns:
        (H, W) float32 in [0, 1].
    """
    c = frame.cameras["C"]
    cone = epipole_cone(frame.width, frame.height, c.position, c.rotation, frame.cameras["U"].position,
                        params.epipole_cone_deg)
    share = 1.0
    lo, hi = params.epipole_cone_noise_low, params.epipole_cone_noise_high
    if hi > 0:
        noise = max(image_noise(frame.images[k], FLAT_NOISE_SCALE) for k in ("C", "R", "U"))
        share = float(np.clip((noise - lo) / (hi - lo), 0.0, 1.0))
    floor = np.where(cone, np.float32(share), np.float32(0.0))
    if params.epipole_cone_fb_high > 0:
        if fb_error_px is None:
            raise ValueError("epipole_cone_fb_high needs the C -> R flow's forward-backward inconsistency")
        lo, hi = params.epipole_cone_fb_low, params.epipole_cone_fb_high
        fb = np.nan_to_num(np.asarray(fb_error_px, np.float32), nan=np.inf)
        floor *= np.clip((hi - fb) / np.float32(hi - lo), 0.0, 1.0)
    return floor.astype(np.float32)


def sweep_gate(params: PriorParams, flow_m: np.ndarray, sweep_m: np.ndarray, sweep_conf: np.ndarray,
               image: np.ndarray | None = None, floor: np.ndarray | None = None,
               room_m: np.ndarray | None = None) -> np.ndarray:
    """The factor of the prior's weight that depends on the plain sweep (:class:`PriorParams`).

    Args:
        flow_m, sweep_m: (H, W) flow and plain-sweep distances, metres; sweep_conf: (H, W) sweep confidence in
            [0, 1]; image: (H, W, 3) uint8 image of C, needed when ``frame_agreement_contrast`` counts only its
            textured pixels in the frame's agreement share (ValueError without it); floor: (H, W) float32 in [0, 1],
            the least the frame's agreement factor may be at each pixel (:func:`cone_floor`), or None (0);
            room_m: (H, W) distance along C's bearings to the floor or the ceiling the sweep's coarse pass found,
            metres (inf: none), needed when ``epipole_cone_room`` > 0 and there is a floor (ValueError without it).
    Returns:
        (H, W) float32 in [0, 1].
    """
    with np.errstate(divide="ignore", invalid="ignore"):
        rel = np.abs(np.log(np.asarray(flow_m, np.float64) / np.asarray(sweep_m, np.float64)))
    agree = np.isfinite(rel) & (rel < params.agree_tolerance)
    g = np.ones(agree.shape, np.float32)
    if params.sweep_confidence_power > 0:
        ambiguous = np.power(1.0 - np.clip(sweep_conf, 0.0, 1.0), params.sweep_confidence_power)
        g = np.where(agree, 1.0, ambiguous).astype(np.float32)
    if params.frame_agreement_high > 0:
        counted = agree
        if params.frame_agreement_contrast > 0:
            if image is None:
                raise ValueError("frame_agreement_contrast needs C's image")
            textured = contrast_above_noise(image, params.contrast_sigma_px) >= params.frame_agreement_contrast
            # a frame without a textured pixel has no evidence for the flow: no prior
            counted = agree[textured] if textured.any() else np.zeros(1, bool)
        lo, hi = params.frame_agreement_low, params.frame_agreement_high
        factor = np.float32(np.clip((counted.mean() - lo) / (hi - lo), 0.0, 1.0))
        if floor is not None and params.epipole_cone_room > 0:
            if room_m is None:
                raise ValueError("epipole_cone_room needs the distance to the room's floor and ceiling")
            with np.errstate(divide="ignore", invalid="ignore"):
                off = np.abs(np.log(np.asarray(flow_m, np.float64) / np.asarray(room_m, np.float64)))
            floor = np.where(np.isfinite(off) & (off < params.epipole_cone_room), floor, np.float32(0.0))
        g *= factor if floor is None else np.maximum(floor, factor)
    return g


@dataclass(frozen=True)
class PriorSweepMethod:
    """The flow-prior sweep: flow pipeline -> prior cost in the sweep's volume -> SGM (a :class:`Method`).

    Built on a flow-pipeline method (:class:`reconstruction.methods.flow_pipeline.BuiltOnFlow`: it runs in its flow's
    group) and naming its quality reference (:class:`reconstruction.methods.base.ReferencingMethod`).

    Its ``config()`` records ``"kind": "fused"`` (the name ``config.json`` files have always held).

    Attributes:
        flow: the flow-pipeline method whose distance is the prior (e.g. ``dis-rect:gradient``).
        sweep: the sweep's parameters (cost, planes, SGM, post; :class:`SweepMethod`).
        prior: prior strength (:class:`PriorParams`).
        label: the method's label.
        quality_flow: the flow-pipeline method whose distance the ground-truth-free quality measures compare this
            method's with (:func:`reconstruction.quality.disagreement`), when it is not ``flow`` (None: ``flow``,
            whose distance :meth:`run` hands back as ``reference``).  :meth:`run` does not compute it, so it costs
            the method no time: whoever assesses the quality runs it (:func:`reconstruction.methods.base.
            reference_distance`).
    """

    flow: FlowMethod
    sweep: SweepMethod = field(default_factory=default_sweep)
    prior: PriorParams = field(default_factory=PriorParams)
    label: str = "fused"
    quality_flow: FlowMethod | None = None

    @property
    def group_key(self) -> tuple:
        """The flow configuration's key: the default ``evaluate`` computes the flow, triangulation and LM variant
        once for this method and the flow-pipeline methods of the same configuration."""
        return self.flow.group_key

    @property
    def reference_method(self) -> FlowMethod:
        """The method whose distance is this one's reference for the quality measures: ``quality_flow`` if set
        (not computed by :meth:`run`), else the flow (handed back as ``reference``, :class:`MethodOutput`)."""
        return self.flow if self.quality_flow is None else self.quality_flow

    def config(self) -> dict:
        out = {"kind": "fused", "label": self.label, "flow": self.flow.config(), "sweep": self.sweep.config(),
               "prior": asdict(self.prior)}
        if self.quality_flow is not None:  # only then: the configurations recorded before it existed still match
            out["quality_flow"] = self.quality_flow.config()
        return out

    def run(self, frame) -> MethodOutput:
        """Run the flow method, then the sweep with its distance as prior; seconds per stage of both (wall; the
        flow's stages summed as ``flow``), ``info["cpu_seconds"]`` the process CPU time of the sweep's stages
        (all threads)."""
        return self.run_group(frame, [self])[self.label]

    def run_group(self, frame, members: Sequence,
                  on_stage: Callable[[str], None] | None = None) -> dict[str, MethodOutput]:
        """Run this method with others of its flow configuration (:func:`run_flow_group`)."""
        return run_flow_group(frame, members, on_stage)

    def run_on_flows(self, calibration: Calibration, members: Sequence[PriorSweepMethod],
                     flow_outputs: dict[str, MethodOutput],
                     on_stage: Callable[[str], None] | None = None,
                     fb_error_px: Mapping[str, np.ndarray] | None = None) -> dict[str, MethodOutput]:
        """Run flow-prior sweep ``members`` given their flows' outputs (by flow label) on the frame their flow
        matched (``calibration``: self-calibrated once); members of one sweep configuration share the room-bound
        pass and the cost volume.  ``fb_error_px``: per pair ("U", "R"), (H, W) forward-backward inconsistency of
        the flow at C's pixels, pixels (needed by ``epipole_cone_fb_high``)."""
        frame = calibration.frame
        by_sweep: dict[str, list[PriorSweepMethod]] = {}
        for m in members:
            by_sweep.setdefault(repr(m.sweep), []).append(m)
        outs = {}
        for batch in by_sweep.values():
            if on_stage is not None:
                on_stage(", ".join(m.label for m in batch))
            priors = []
            for m in batch:
                flow = flow_outputs[m.flow.label]
                weight = prior_weight(m.prior, frame.images["C"], flow.confidence)
                if m.prior.needs_plain_sweep:
                    floor = (cone_floor(m.prior, frame, (fb_error_px or {}).get("R"))
                             if m.prior.epipole_cone_deg > 0 else None)
                    priors.append(PriorFromSweep(lambda d_s, c_s, room, m=m, d=flow.distance, w=weight,
                                                 image=frame.images["C"], floor=floor:
                                                 Prior(d, w * sweep_gate(m.prior, d, d_s, c_s, image, floor, room),
                                                       m.prior.truncate_levels)))
                else:
                    priors.append(Prior(flow.distance, weight, m.prior.truncate_levels))
            results = sweep_distances(frame, batch[0].sweep, priors, calibration)
            for m, (d, conf, seconds, info) in zip(batch, results, strict=True):
                flow = flow_outputs[m.flow.label]
                seconds = {"flow": flow.total_seconds, **{k: v for k, v in seconds.items() if k != "total"}}
                seconds["total"] = sum(seconds.values())
                outs[m.label] = MethodOutput(distance=d, confidence=conf, seconds=seconds,
                                             info={**info, "flow_label": m.flow.label},
                                             reference=flow.distance if m.quality_flow is None else None)
        return outs

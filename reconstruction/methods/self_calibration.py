"""A frame's self-calibration, once for every method that matches it: U's and R's rotations and the cameras'
photometric differences, fitted to the frame's own correspondences and applied only where its evidence supports them
(:func:`self_calibrate` -> :class:`Calibration`), and the reduced frame its pre-pass matches (:func:`reduced_frame`).

The flow pipeline (:func:`reconstruction.methods.flow_pipeline.reconstruct`) and the sweep
(:func:`reconstruction.methods.sweep.sweep_distances`) match the calibrated frame.  The fits themselves are
:mod:`reconstruction.rig_calibration` and :mod:`reconstruction.photometry`.
"""

from __future__ import annotations

import ctypes
import dataclasses
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from types import SimpleNamespace

import cv2
import numpy as np

from reconstruction.camera.equirect import bearing_grid
from reconstruction.camera.image_ops import rotation_vector_matrix
from reconstruction.flow.matching import match_pair
from reconstruction.methods.flow_stages import PAIRS, prepare
from reconstruction.photometry import (
    IDENTITY,
    FrameView,
    PhotometricModel,
    PhotometricParams,
    align_images,
    apply_photometric,
    fit_photometric,
)
from reconstruction.refine.fill import agreed_distance
from reconstruction.refine.triangulate import TriangulationLimits, pair_geometry, triangulate_sines
from reconstruction.rig_calibration import RigParams, corrected_pose, fit_rotation, usable_matches

__all__ = ["Calibration", "self_calibrate", "reduced_frame"]


@dataclass(frozen=True, eq=False)
class Calibration:
    """A frame self-calibrated once, for every method that matches it (:func:`self_calibrate`).

    Attributes:
        frame: what to match: the input frame seen with U's and R's corrected poses and the corrected images (the
            input itself when nothing was applied).
        model: the photometric corrections applied (:class:`reconstruction.photometry.PhotometricModel`).
        record: JSON-able: ``rig`` (per camera the :class:`~reconstruction.rig_calibration.RigFit` with
            ``applied``) and ``photometric`` (:func:`reconstruction.photometry.fit_photometric`'s record), each
            quantity with its evidence and whether it was applied; empty when nothing ran.
        seconds: the stages' wall time: ``rig`` (the fit), ``photometric`` (the pre-pass and the photometric fit).
    """

    frame: object
    model: PhotometricModel = IDENTITY
    record: dict = field(default_factory=dict)
    seconds: dict = field(default_factory=dict)

    @property
    def corrected_images(self) -> bool:
        """Whether any image was changed (a gain, a field or the shared fall-off applied)."""
        return not self.model.is_identity

    @property
    def applied(self) -> list[str]:
        """What was applied, e.g. ``["R rotation", "U gain", "U field", "U response", "common field"]`` (empty:
        nothing)."""
        out = []
        for k, fit in self.record.get("rig", {}).items():
            if fit.get("applied"):
                out.append(f"{k} rotation")
        photo = self.record.get("photometric", {})
        for k in PAIRS:
            for what in ("gain", "field", "response"):
                if photo.get(k, {}).get(what, {}).get("applied"):
                    out.append(f"{k} {what}")
        if photo.get("common", {}).get("field", {}).get("applied"):
            out.append("common field")
        return out


def self_calibrate(frame, photometric: PhotometricParams, rig: RigParams, limits: TriangulationLimits,
                   prepass: bool = True, note: Callable[[str], None] = lambda _s: None) -> Calibration:
    """The frame's self-calibration: U's and R's rotations and the cameras' photometric differences, each applied
    only where the frame's own evidence supports it (:mod:`reconstruction.evidence`).

    A flow pass (``photometric.prepass_flow`` on rectified images reduced by ``photometric.prepass_factor``, after each
    channel's median gain from the same pixels so that it matches across an exposure difference) gives the
    correspondences; the rig fit (:func:`reconstruction.rig_calibration.fit_rotation`) runs on its matches (a
    rotation it would apply is fitted again from a flow pass on images reduced by ``rig.confirm_factor``, 1: full
    resolution, and applied only when that fit supports it too; the record keeps that fit as ``confirm``), the
    matches are triangulated again with the applied poses, and the photometric fit
    (:func:`reconstruction.photometry.fit_photometric`) runs on the correspondences of the pixels whose two pairs
    triangulate alike (:func:`~reconstruction.refine.fill.agreed_distance` within ``photometric.agreement``).

    Args:
        frame: the frame (images and told poses).
        photometric, rig: the fits (mode ``"none"``: not fitted).
        limits: the triangulation limits of the pre-pass.
        prepass: False (the oracle): nothing is fitted.
        note: called with the stage name before it runs.
    Returns:
        A :class:`Calibration`.
    """
    if not prepass or (photometric.mode == "none" and rig.mode == "none"):
        return Calibration(frame)
    h, w = frame.height, frame.width
    note("photometric" if photometric.mode != "none" else "rig")
    start = time.perf_counter()
    seconds, record = {}, {}
    matched = frame
    if photometric.mode != "none":  # for the pre-pass only: each channel's median gain from the same pixels
        quick = dataclasses.replace(photometric, iterations=0)
        matched = FrameView(frame, images=align_images(frame.images, frame.cameras, quick)[0])
    small = reduced_frame(matched, max(photometric.prepass_factor, 1))
    prep = prepare(small, photometric.prepass_flow, True, limits)
    d_pair, valid = [prep.d_pair[k] for k in PAIRS], [prep.valid[k] for k in PAIRS]
    cameras = dict(frame.cameras)
    if rig.mode != "none":
        t_rig = time.perf_counter()
        fits = {k: _fit_pair(prep.bearings, small.images["C"], prep.matches[k], prep.valid[k], rig) for k in PAIRS}
        if rig.confirm_factor and any(fit["applied"] for fit in fits.values()):
            # the rotations the pre-pass would apply, fitted again from matches at another resolution
            fine = reduced_frame(matched, rig.confirm_factor)
            fine_bearings = bearing_grid(fine.width, fine.height, frame.cameras["C"].rotation).reshape(-1, 3)
            for k in (k for k in PAIRS if fits[k]["applied"]):
                m = match_pair(fine, k, photometric.prepass_flow, True)
                _, fine_valid = triangulate_sines(
                    pair_geometry(fine_bearings, m.baseline, m.bearing.reshape(-1, 3)), limits)
                confirm = _fit_pair(fine_bearings, fine.images["C"], m, fine_valid, rig)
                fits[k]["confirm"] = confirm
                fits[k]["applied"] = confirm["applied"]
            del fine, fine_bearings, m, fine_valid
            _release_freed_heap()
        for i, k in enumerate(PAIRS):
            m = prep.matches[k]
            omega = np.asarray(fits[k]["omega"]) if fits[k]["applied"] else np.zeros(3)
            cameras[k] = corrected_pose(frame.cameras[k], omega)
            # the pre-pass's matches seen from the applied pose, triangulated again
            g = pair_geometry(prep.bearings, m.baseline, m.bearing.reshape(-1, 3) @ rotation_vector_matrix(omega).T)
            d_pair[i], valid[i] = triangulate_sines(g, limits)
        record["rig"] = fits
        seconds["rig"] = time.perf_counter() - t_rig
    model = IDENTITY
    if photometric.mode != "none":
        # the pixels both pairs triangulate alike (a wrong match pairs C's pixel with another surface)
        d_small = agreed_distance(d_pair, valid, photometric.agreement)
        d_full = cv2.resize(d_small.reshape(small.height, small.width).astype(np.float32), (w, h),
                            interpolation=cv2.INTER_NEAREST)
        model, record["photometric"] = fit_photometric(frame.images, cameras, d_full, photometric)
    replaced = {}
    if any(fit["applied"] for fit in record.get("rig", {}).values()):
        replaced["cameras"] = cameras
    if not model.is_identity:
        replaced["images"] = apply_photometric(frame.images, model, photometric.max_log_gain)
    seconds["photometric"] = time.perf_counter() - start - seconds.get("rig", 0.0)
    return Calibration(FrameView(frame, **replaced) if replaced else frame, model, record, seconds)


def _release_freed_heap() -> None:
    """Give the C heap's free pages back to the system (glibc's ``malloc_trim``; nothing where there is none).  The
    confirming pass's full-resolution arrays are freed when it ends, but their pages stayed in the heap, where the
    sweep's larger arrays did not reuse them: on office-s1041's captured twin (tri360-v3 dev, 1000x500) the
    default's peak RSS was 1.02 GB with the confirming pass against 0.94-0.98 without; with this, 0.96-1.01 against
    0.96-1.00 GB (five runs each)."""
    try:
        ctypes.CDLL(None).malloc_trim(0)
    except (OSError, AttributeError):
        pass


def _fit_pair(bearings: np.ndarray, image_c: np.ndarray, m, valid: np.ndarray, rig: RigParams) -> dict:
    """One pair's rotation fit (:func:`reconstruction.rig_calibration.fit_rotation`) from its matches ``m`` (a
    :class:`reconstruction.flow.matching.PairMatch`) and C's ``(N, 3)`` bearings and image at their resolution, with
    ``applied``: the test passed, the size within ``rig``'s bounds, and (``rig.hemispheres``) found from each
    hemisphere alone at that share of ``min_degrees``."""
    fit = fit_rotation(bearings, usable_matches(image_c, m.bearing, m.fb_error_px, valid, rig), m.baseline,
                       min_sin=rig.min_sin, iterations=rig.iterations, tukey_c=rig.tukey_c,
                       max_matches=rig.max_matches, alpha=rig.alpha, longitude_blocks=rig.longitude_blocks,
                       min_block_samples=rig.min_block_samples, hemispheres=rig.hemispheres > 0)
    halves_ok = all(h["degrees"] >= rig.hemispheres * rig.min_degrees for h in fit["evidence"].get("hemispheres", []))
    fit["applied"] = bool(fit["evidence"]["supported"] and rig.min_degrees <= fit["degrees"] <= rig.max_degrees
                          and fit["degrees"] > 0 and halves_ok)
    return fit


def reduced_frame(frame, factor: int):
    """A frame-like view of ``frame`` with images ``factor`` times smaller (area averaging; same poses)."""
    w, h = frame.width // factor, frame.height // factor
    images = {k: cv2.resize(v, (w, h), interpolation=cv2.INTER_AREA) for k, v in frame.images.items()}
    return SimpleNamespace(width=w, height=h, cameras=frame.cameras, images=images,
                           baseline_m=getattr(frame, "baseline_m", None),
                           distance={})

"""Rig self-calibration: U's and R's orientation relative to C, fitted to the frame's own correspondences.

A real rig's told poses are off by a fraction of a degree (a calibration is never exact, and a rig flexes).  In a
hall, where most surfaces are 5-15 m away, 0.2 degrees is a tenth of the 1.7-2.3 degrees of parallax a 0.3-0.4 m
baseline gives, so a told rotation that is off by that much moves far distances by tens of percent; no
photometric correction removes it.  C defines the rig's frame: only U and R are corrected.

**Model.** For each C pixel with bearing ``c`` (unit, world) and its match in camera K under K's told pose, the
unit world bearing ``k``, the true bearing is ``Rot(omega) k`` (K's true rotation ``Rot(omega) @ R_told``,
world-from-camera).  The point, C and K lie in one plane (the epipolar constraint), so with the told baseline
``t = K - C``

    r(omega) = n . Rot(omega) k = 0,     n = (c x t) / |c x t|,

``r`` being the sine of the angle between K's bearing and the epipolar plane (radians, for small angles).  A
rotation error moves every match off its plane by about the same angle whatever its distance; a position error of
``delta`` (1-2 mm) moves it by about ``delta / distance``, a twentieth of that at 3 m, and changes distances by at
most ``delta / |t|`` (0.5 %); so only the rotation is fitted.

**Fit** (:func:`fit_rotation`): Gauss-Newton on the three components of ``omega`` (radians, world axes), each step
weighted with Tukey's biweight of the residual over a robust scale (occlusions and failed matches are outliers),
over the matches whose pair is far from its epipoles.  The matches (:func:`usable_matches`) come from a quick
flow pass on reduced rectified images (the self-calibration's pre-pass,
:func:`reconstruction.methods.self_calibration.self_calibrate`); only textured pixels (C's Shi-Tomasi response in its
top ``1 - texture_quantile``) whose flow is forward-backward consistent take part: a flow's smoothness drags the
cross-epipolar component of untextured pixels with it.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from reconstruction.camera.image_ops import grey, robust_scale, rotation_vector_matrix, tukey_weights
from reconstruction.camera.rig import CameraPose
from reconstruction.evidence import (
    ALPHA,
    LONGITUDE_BLOCKS,
    MIN_BLOCK_SAMPLES,
    hemisphere_rows,
    hotelling,
    jackknife_linear,
    sphere_blocks,
)

__all__ = ["RigParams", "NO_RIG_CALIBRATION", "RigFit", "rotation_vector_matrix", "fit_rotation", "usable_matches",
           "corrected_pose"]


@dataclass(frozen=True)
class RigParams:
    """Whether and how U's and R's told rotations are corrected from the frame's correspondences.

    Attributes:
        mode: ``"none"`` (the told poses as they are) or ``"rotation"`` (module doc).
        max_fb_px: matches whose forward-backward inconsistency exceeds this (pixels of the reduced images) are
            not used.
        texture_quantile: only C's pixels whose Shi-Tomasi response (smaller eigenvalue of the 3x3 structure
            tensor of the reduced grey image) is at or above this quantile are used.
        min_sin: see :func:`fit_rotation`.
        max_degrees: a fitted correction larger than this is not applied (the fit is trusted only for the small
            errors of a calibrated rig; a larger one means the matches, not the rig, are wrong).
        alpha: the level of the test a correction must pass to be applied (:func:`fit_rotation`'s ``evidence``):
            a told rotation the frame's matches do not contradict is kept.  0.01, ten times the photometric
            tests' level: a missed rotation of 0.2 degrees costs up to 1.9x the MAE (tri360-v3 dev, captured),
            a false one is at least ``min_degrees`` and none passed on the ideal dev frames that did not at 0.001.
        min_degrees: a smaller correction is not applied however significant: a tenth of a pixel of the pre-pass
            (500 px around at 1000x500), about what its flow resolves.
        hemispheres: a rotation is applied only when the rotations fitted from the matches above the horizon alone
            and from those below alone are each at least this share of ``min_degrees`` (:func:`fit_rotation`'s
            ``hemispheres``); 0 (the default): not asked.  A told rotation that is off turns every match, a scene
            effect of one hemisphere (a polished floor's blurred reflection matched as a surface) only that
            hemisphere's.  Off with the photometric one (:class:`reconstruction.photometry.PhotometricParams`); at 1
            it drops 2 of the 232 rotations applied on the camera families of tri360-v3 dev (vp000), and it keeps
            the false rotations of ideal dev frames, which each hemisphere finds alike (docs/photometry.md).
        confirm_factor: a rotation the pre-pass's matches would apply is fitted again from a flow pass on images
            reduced by this factor (1: full resolution, the default) and applied only when that fit passes the
            same test and bounds too; the pre-pass's rotation is the one applied.  0: not asked.  The pre-pass's
            half-size flow is biased on weak texture by a fraction of its pixel, which its jackknife cannot see (it
            is the same bias in every block): three ideal frames of tri360-v3 dev had a false rotation of 0.11-0.27
            degrees (up to 1.13x the uncalibrated MAE) which the full-resolution fit does not support, while it
            confirms all but 6 of the 530 rotations the pre-pass applies to the camera families' frames, and those
            6 frames' MAE went 0.62-1.09x (docs/photometry.md).  It costs a full-resolution flow pass of each pair
            whose rotation is to be applied.
        iterations, tukey_c, max_matches, longitude_blocks, min_block_samples: the fit's
            (:func:`fit_rotation`).
    """

    mode: str = "rotation"
    max_fb_px: float = 0.5
    texture_quantile: float = 0.7
    min_sin: float = 0.3
    max_degrees: float = 2.0
    alpha: float = 0.01
    min_degrees: float = 0.072
    iterations: int = 6
    tukey_c: float = 4.685
    max_matches: int = 40000
    hemispheres: float = 0.0
    confirm_factor: int = 1
    longitude_blocks: int = LONGITUDE_BLOCKS
    min_block_samples: int = MIN_BLOCK_SAMPLES

    def __post_init__(self):
        if self.mode not in ("none", "rotation"):
            raise ValueError(f"rig calibration mode must be 'none' or 'rotation', got {self.mode!r}")
        if not self.max_fb_px > 0:
            raise ValueError(f"rig calibration max_fb_px must be > 0, got {self.max_fb_px}")
        if not 0.0 <= self.texture_quantile < 1.0:
            raise ValueError(f"rig calibration texture_quantile must be in [0, 1), got {self.texture_quantile}")
        if not 0.0 <= self.min_sin < 1.0:
            raise ValueError(f"rig calibration min_sin must be in [0, 1), got {self.min_sin}")
        if not 0.0 < self.alpha < 1.0:
            raise ValueError(f"rig calibration alpha must be in (0, 1), got {self.alpha}")
        if not 0 <= self.min_degrees < self.max_degrees:
            raise ValueError(f"rig calibration min_degrees {self.min_degrees} must be in [0, max_degrees)")
        if not 0.0 <= self.hemispheres <= 1.0:
            raise ValueError(f"rig calibration hemispheres must be in [0, 1], got {self.hemispheres}")
        if not (isinstance(self.confirm_factor, int) and self.confirm_factor >= 0):
            raise ValueError(f"rig calibration confirm_factor must be an integer >= 0, got {self.confirm_factor!r}")
        if not self.max_degrees > 0:
            raise ValueError(f"rig calibration max_degrees must be > 0, got {self.max_degrees}")
        if not (self.iterations >= 0 and self.tukey_c > 0 and self.max_matches >= 1 and self.longitude_blocks >= 1
                and self.min_block_samples >= 0):
            raise ValueError(f"rig calibration iterations {self.iterations} and min_block_samples "
                             f"{self.min_block_samples} must be >= 0, tukey_c {self.tukey_c} > 0, max_matches "
                             f"{self.max_matches} and longitude_blocks {self.longitude_blocks} >= 1")


NO_RIG_CALIBRATION = RigParams(mode="none")
"""The told poses as they are."""


class RigFit(dict):
    """What :func:`fit_rotation` found (a JSON-able dict): ``omega`` (3,) radians, ``degrees`` its norm,
    ``matches`` used, ``sigma_deg`` the robust scale of the final residuals, ``iterations``, ``evidence`` (the test
    of ``omega`` against the told rotation, :class:`reconstruction.evidence.Evidence`)."""


def fit_rotation(c: np.ndarray, k: np.ndarray, baseline: np.ndarray, *, min_sin: float = 0.3,
                 iterations: int = 6, tukey_c: float = 4.685, max_matches: int = 40000,
                 alpha: float = ALPHA, longitude_blocks: int = LONGITUDE_BLOCKS,
                 min_block_samples: int = MIN_BLOCK_SAMPLES, hemispheres: bool = False) -> RigFit:
    """The rotation that puts K's matched bearings back onto C's epipolar planes (module doc).

    Args:
        c: (N, 3) unit world bearings of C's pixels.
        k: (N, 3) unit world bearings of their matches in K under K's told pose (rows with a non-finite value are
            skipped).
        baseline: (3,) told ``K - C``, metres.
        min_sin: matches whose bearing makes an angle with the baseline of sine below this are skipped (the
            epipolar plane is ill-defined near the epipoles).
        iterations: Gauss-Newton steps.
        tukey_c: Tukey's constant, in robust standard deviations (1.4826 MAD).
        max_matches: at most this many matches are used (an even stride over the valid ones).
        alpha: the level of the test: ``evidence`` is Hotelling's test of ``omega`` over the delete-one-block
            jackknife of the matches' blocks of C's sphere (:mod:`reconstruction.evidence`), the robust weights
            and the linearisation held at the solution; ``supported`` when it rejects "the told rotation" at
            ``alpha``.
        longitude_blocks, min_block_samples: those blocks (:func:`reconstruction.evidence.sphere_blocks`) and the
            fewest matches of one left out on its own (:func:`reconstruction.evidence.jackknife_linear`).
        hemispheres: ``evidence`` also holds ``hemispheres``: for the matches above the horizon and those below,
            each alone, the rotation fitted the same way from them alone (``degrees``) and its test (``p_value``,
            ``blocks``), for the caller's
            decision (the self-calibration applies a rotation only when each is at least ``RigParams.min_degrees``).
    Returns:
        A :class:`RigFit`; ``omega`` is zero and nothing supported when fewer than 100 matches are usable.
    """
    c = np.asarray(c, np.float64).reshape(-1, 3)
    k = np.asarray(k, np.float64).reshape(-1, 3)
    t = np.asarray(baseline, np.float64)
    t = t / np.linalg.norm(t)
    n = np.cross(c, t)
    sin = np.linalg.norm(n, axis=1)
    ok = np.isfinite(k).all(axis=1) & np.isfinite(c).all(axis=1) & (sin >= min_sin)
    idx = np.flatnonzero(ok)
    idx = idx[::max(1, -(-idx.size // max_matches))]
    omega = np.zeros(3)
    if idx.size < 100:
        return RigFit(omega=omega.tolist(), degrees=0.0, matches=int(idx.size), sigma_deg=float("nan"),
                      iterations=0, evidence=hotelling(omega, np.full((3, 3), np.nan), 0, alpha))
    blocks = sphere_blocks(c[idx], longitude_blocks)
    n = n[idx] / sin[idx, None]
    k = k[idx]
    omega, sigma, done, cov, used = _robust_fit(n, k, blocks, iterations, tukey_c, min_block_samples)
    evidence = hotelling(omega, cov, used, alpha)
    if hemispheres:
        evidence["hemispheres"] = []
        for rows in hemisphere_rows(blocks):
            omega_h, _, _, cov_h, used_h = _robust_fit(n[rows], k[rows], blocks[rows], iterations, tukey_c,
                                                       min_block_samples)
            evidence["hemispheres"].append({"degrees": float(np.degrees(np.linalg.norm(omega_h))),
                                            "p_value": hotelling(omega_h, cov_h, used_h, alpha)["p_value"],
                                            "blocks": used_h})
    return RigFit(omega=omega.tolist(), degrees=float(np.degrees(np.linalg.norm(omega))), matches=int(idx.size),
                  sigma_deg=float(np.degrees(sigma)), iterations=done, evidence=evidence)


def _robust_fit(n: np.ndarray, k: np.ndarray, blocks: np.ndarray, iterations: int, tukey_c: float,
                min_block_samples: int) -> tuple[np.ndarray, float, int, np.ndarray, int]:
    """Gauss-Newton with Tukey weights on ``r = n . Rot(omega) k`` ((M, 3) unit normals and bearings), then the
    jackknife over ``blocks`` at the solution: ``(omega, sigma, iterations done, cov, blocks used)``."""
    omega = np.zeros(3)
    sigma = float("nan")
    done = 0
    if n.shape[0] < 100:
        return omega, sigma, done, np.full((3, 3), np.nan), 0
    while done < iterations:
        done += 1
        kk = k @ rotation_vector_matrix(omega).T
        r = np.einsum("ij,ij->i", n, kk)
        jac = np.cross(kk, n)  # d r / d omega for a small extra rotation: n . (w x kk) = w . (kk x n)
        sigma = robust_scale(r, 1e-6, "max")
        wts = tukey_weights(r, tukey_c, sigma)
        a = jac.T @ (jac * wts[:, None])
        b = jac.T @ (wts * r)
        step = -np.linalg.solve(a + 1e-9 * np.trace(a) * np.eye(3), b)
        omega = _compose(step, omega)
        if np.linalg.norm(step) < 1e-7:
            break
    kk = k @ rotation_vector_matrix(omega).T
    r = np.einsum("ij,ij->i", n, kk)
    wts = tukey_weights(r, tukey_c, sigma)
    _, cov, used = jackknife_linear(np.cross(kk, n), -r, wts, blocks, min_samples=min_block_samples)
    return omega, sigma, done, cov, used


def usable_matches(image_c: np.ndarray, bearing: np.ndarray, fb_error_px: np.ndarray, valid: np.ndarray,
                   params: RigParams) -> np.ndarray:
    """K's matched bearings with the matches the fit must not use set to NaN (module doc).

    Args:
        image_c: (H, W, 3) uint8 image of C at the matches' resolution.
        bearing: (H, W, 3) or (N, 3) unit world bearings of the matches in K (told pose), N = H * W.
        fb_error_px: (H, W) or (N,) forward-backward inconsistency, pixels.
        valid: (H, W) or (N,) bool, the pair's triangulation validity.
        params: the thresholds.
    Returns:
        (N, 3) float64 bearings, NaN rows where a match is not used.
    """
    response = cv2.cornerMinEigenVal(grey(image_c).astype(np.float32), 5, 3).reshape(-1)
    out = np.asarray(bearing, np.float64).reshape(-1, 3).copy()
    bad = (np.asarray(fb_error_px).reshape(-1) > params.max_fb_px) | ~np.asarray(valid, bool).reshape(-1)
    if params.texture_quantile > 0:
        bad |= response < np.quantile(response, params.texture_quantile)
    out[bad] = np.nan
    return out


def _compose(step: np.ndarray, omega: np.ndarray) -> np.ndarray:
    """Rotation vector of ``Rot(step) @ Rot(omega)``."""
    m = rotation_vector_matrix(step) @ rotation_vector_matrix(omega)
    angle = float(np.arccos(np.clip((np.trace(m) - 1.0) / 2.0, -1.0, 1.0)))
    if angle < 1e-12:
        return np.zeros(3)
    v = np.array([m[2, 1] - m[1, 2], m[0, 2] - m[2, 0], m[1, 0] - m[0, 1]])
    return v * (angle / (2.0 * np.sin(angle)))


def corrected_pose(pose: CameraPose, omega) -> CameraPose:
    """``pose`` with its rotation turned by ``omega`` (3,) radians about world axes (``Rot(omega) @ R``);
    its position kept."""
    return CameraPose(np.asarray(pose.position, np.float64).copy(),
                      rotation_vector_matrix(np.asarray(omega, np.float64)) @ np.asarray(pose.rotation, np.float64))

"""Photometric self-calibration: bring U's and R's images to C's exposure, white balance, response and lens fall-off
(and, optionally, remove the fall-off all three share), from the frame's own pixels, and only where the frame shows
the cameras to differ.

Real rigs are three cameras that meter exposure and white balance each on their own and whose lenses darken
towards their edges, each a little differently.  A matching cost that compares intensities across cameras reads
such a difference as a distance.  :func:`fit_photometric` fits, for each other camera K, in linear light,

    ln K_c(q) - ln C_c(p) = a_Kc + g_K(b_K) + r_K(ln K_c(q)) [+ f(b_K) - f(b_C)]

between C's pixel p and the pixel q of K that sees the same point (through a distance map of C): ``a_Kc`` per colour
channel (exposure and white balance), ``r_K`` K's response curve relative to C's (:func:`response_basis`), ``g_K``
one achromatic field over K's camera-frame bearing (the monomials of :func:`basis`: with ``central``, those the same
at opposite bearings, and ``|x|, |y|, |z|``, which follow the kink of two back-to-back fisheyes' fall-off at their
seam), and optionally ``f`` the fall-off shared by all three, seen through the parallax. Each quantity is applied
only when a test over the sphere's blocks supports it and it exceeds the fit's error on cameras that agree
(:mod:`reconstruction.evidence`); :func:`apply_photometric` divides the applied ones out.

:func:`align_images` is the cheap form: per-channel gains from the same pixels (the cameras share their orientation
and are 0.3-0.4 m apart, so most pixels see nearly the same surface, and a robust fit ignores the rest); the
self-calibration uses it, with each channel's median gain, only to let its pre-pass flow match across an exposure
difference. Only pixels that are neither dark (noise) nor near saturation count, on images reduced by
:attr:`PhotometricParams.factor` (area averaging in linear light); the fits are iteratively reweighted least squares
with Tukey's biweight.
"""

from __future__ import annotations

import dataclasses
import itertools
from collections.abc import Callable
from dataclasses import dataclass, field

import cv2
import numpy as np

from reconstruction.camera.equirect import bearing_grid, lonlat_to_pixel
from reconstruction.camera.image_ops import grey, periodic_pad, robust_scale, sobel_gradient, tukey_weights
from reconstruction.evidence import (
    ALPHA,
    LONGITUDE_BLOCKS,
    MIN_BLOCK_SAMPLES,
    Evidence,
    hotelling,
    jackknife_hemispheres,
    jackknife_linear,
    sphere_blocks,
)
from reconstruction.flow.backends import ORACLE, FlowBackend, builtin_flows, get_flow

__all__ = ["NO_CALIBRATION", "PhotometricParams", "srgb_to_linear", "linear_to_srgb", "basis", "RESPONSE_MID",
           "response_basis", "fit_gain",
           "align_images", "PhotometricModel", "IDENTITY", "fit_photometric", "apply_photometric",
           "FrameView"]


def _builtin_flow(name: str) -> FlowBackend:
    """The built-in flow backend ``name`` with its built-in parameters (no plugin lookup)."""
    return next(b for b in builtin_flows() if b.name == name)


@dataclass(frozen=True)
class PhotometricParams:
    """How :func:`align_images` estimates each camera's gain relative to C.

    Attributes:
        mode: ``"none"`` (images as they are) or ``"gain-field"`` (per-channel gain and an achromatic field).
        degree: highest degree of the bearing monomials of the field fitted from correspondences given by a
            distance map (0 = one gain per channel only).
        pixel_degree: the same when pixels are compared at the same place (no distance map): parallax biases a
            field fitted that way, so by default only the per-channel gains are.
        prepass_factor: the flow pipeline fits the field from the correspondences of a flow pass on images
            reduced by this factor (after the per-channel gains), then computes its flow on the corrected images;
            1 = no pre-pass (gains only before the flow).
        ridge: weight of the penalty ``ridge * |beta|^2`` per pixel (keeps the field flat where few pixels say
            otherwise; natural-log units).
        factor: images reduced by this factor before the fit (area averaging in linear light).
        dark, bright: linear-light levels in [0, 1] below / above which a pixel (any channel, either camera) is not
            used: noise dominates below, clipping above.
        tukey_c: Tukey biweight constant, in units of the residuals' robust standard deviation (1.4826 MAD).
        iterations: reweighting iterations.
        max_log_gain: the field's |log gain| is clipped to this (natural log; 2.0 = a factor of 7.4).
        even: the field keeps only the monomials even in every coordinate (and ``|x|, |y|, |z|``): a fall-off
            symmetric about the camera's axes, as two like back-to-back lenses give, which a brightness
            difference between one side of the room and the other (a glossy floor's view-dependent reflection)
            cannot move.
        central: the fields keep only the monomials of even total degree (and ``|x|, |y|, |z|``): a fall-off the
            same at a bearing and its opposite, as two like back-to-back lenses give whatever their axis, which a
            brightness difference between the floor and the ceiling (a polished floor's view-dependent reflection)
            cannot move.  Off (the odd monomials too), the fit applies fields on an ideal dev frame and loses up to
            1.13 x on a (condition, room family) cell of tri360-v3 dev while the seams family gains 5 %
            (docs/photometry.md).
        common_field: :func:`fit_photometric` also fits the fall-off all three cameras share (from the parallax:
            the same point is seen at different bearings) and removes it from all three images, C's included.
            Off by default: through a 0.3-0.4 m rig's parallax it is hard to tell from view-dependent reflection
            (on ideal rendered frames it finds "significant" shared fall-offs of up to 0.35 in log range, hence
            ``min_common`` when it is on; on with it, it is applied on 0 of 21 ideal and 7 of 21 captured frames
            of tri360-v2 dev, whose accuracy is not measured yet).
        min_gain, min_field: the smallest corrections applied (natural log: a camera's largest mean channel gain,
            a field's range over the sphere), whatever the test says.  The fit is not exact where nothing differs:
            a surface's view-dependent reflection and the pre-pass's correspondence errors make cameras that agree
            look different by up to 0.023 (gain) and 0.055 (field) on the ideal frames of tri360-v2 dev (docs/
            photometry.md, ``python -m tools.research.calibration_floor``), which no test over the sphere's blocks
            tells from a camera's (they are as consistent across the sphere); a captured camera's median is 0.25
            and 0.09.
        min_common: the same for the shared fall-off (log range over the sphere): above the 0.35 it finds on
            those ideal frames even from their true distance (a lens losing 40 % of the light at its seam).
        flat_log_gradient: only pixels where C's log intensity changes by less than this per pixel of the reduced
            images take part (a flat patch's ratio does not depend on a match's last pixel of accuracy).
        alpha: the level of the test each correction must pass to be applied (:mod:`reconstruction.evidence`).
        agreement: the self-calibration pairs C's pixels with U's and R's only where the pre-pass's two pairs
            triangulate the same distance within this (``|ln(d_U / d_R)|``): two matches along different epipolar
            directions that agree are seldom both wrong.  A pixel matched wrongly is paired with another surface, and
            on weakly textured rooms whose pre-pass distance is off by 30 % at half the pixels, the slow shading
            of walls read through those pairs looks like a camera gain of 5 % and a field of 0.14 (log).
        response: degree of each camera's response relative to C's, a polynomial ``r_K(s)`` without constant term
            in ``s = ln K_c - ln(0.18)`` (K's own log linear level per channel, about mid-grey), added to the model:
            a camera whose tone curve is not C's is not a gain of C's (a gamma of G instead of sRGB's about 2.2 is
            about ``r(s) = (1 - G / 2.2) s``).  1 (a power law): a cubic, which would follow an S-shaped
            curve, found log ranges of up to 4.7 between ``dark`` and ``bright`` on ideal frames of tri360-v3 dev
            (where few pixels are, it extrapolates); 2 follows a gamma curve against an S-shaped one, but on the
            camera families of tri360-v3 dev it trades fields for responses (a cell 1.26 x, a frame 1.67 x;
            ``python -m tools.research.select_response``).  0: none.
        min_response: the smallest response applied: the range of ``r_K`` over the levels of most of the fit's
            pixels (C's 5th to 95th percentile), natural log; above the 0.04 the fit finds on cameras that agree and
            the 0.09 on cameras that differ only by gain, fall-off, noise and JPEG (tri360-v3 dev, ideal and captured).
        prepass_flow: the flow backend of the self-calibration's pre-pass, with its parameters (given by name, the
            registered backend with its own parameters; default: ``dis`` as built in); on rectified images reduced
            by ``prepass_factor``, whatever the method's own flow: it only needs correspondences good enough to fit
            a smooth gain field and the rotations, fast.  :meth:`config` records its name and parameters.
        max_fit_pixels: the fits use at most this many pixels (evenly strided): the field of degree 2 has 11
            coefficients.
        hemispheres: a correction is applied only when it is also at least this share of its floor (``min_gain``,
            ``min_field``, ``min_response``, ``min_common``) as fitted from the pixels above C's horizon alone and
            from those below alone (:func:`reconstruction.evidence.jackknife_hemispheres`; the significance stays
            the whole sphere's test), and the record gives each hemisphere's size and p-value; 0 (the default): not
            asked.  A camera's gain, a central fall-off and a response curve are seen from either hemisphere, a
            scene effect of one hemisphere (a polished floor's view-dependent reflection) from that one only.  Off,
            as measured on tri360-v3 dev (docs/photometry.md): at 1 it drops real corrections on the camera families
            (19 of their 140 fields, 7 of chromatic's 21; up to 1.4x the MAE on single frames, 1.18x pooled over
            the off-axis frames it changes) while no ideal dev frame has a correction it would drop; at 0.5 it
            changes almost nothing, and no longer drops the ray-cast test's gain that only the lower hemisphere
            shows.
        longitude_blocks, min_block_samples: the blocks of the sphere over which each correction is tested
            (:func:`reconstruction.evidence.sphere_blocks`: sectors of longitude, each cut at the horizon) and the
            fewest samples of a block left out on its own (:func:`reconstruction.evidence.jackknife_linear`).
    """

    mode: str = "gain-field"
    degree: int = 2
    pixel_degree: int = 0
    prepass_factor: int = 2
    ridge: float = 0.0
    factor: int = 4
    dark: float = 0.01
    bright: float = 0.9
    tukey_c: float = 4.685
    iterations: int = 8
    max_log_gain: float = 2.0
    even: bool = False
    central: bool = True
    common_field: bool = False
    min_gain: float = 0.05
    min_field: float = 0.10
    min_common: float = 0.5
    flat_log_gradient: float = 0.1
    alpha: float = ALPHA
    agreement: float = 0.05
    response: int = 1
    min_response: float = 0.10
    prepass_flow: FlowBackend = field(default_factory=lambda: _builtin_flow("dis"))
    max_fit_pixels: int = 15000
    hemispheres: float = 0.0
    longitude_blocks: int = LONGITUDE_BLOCKS
    min_block_samples: int = MIN_BLOCK_SAMPLES

    def __post_init__(self):
        if self.mode not in ("none", "gain-field"):
            raise ValueError(f"photometric mode must be 'none' or 'gain-field', got {self.mode!r}")
        for name in ("degree", "pixel_degree"):
            if not 0 <= getattr(self, name) <= 6:
                raise ValueError(f"photometric {name} must be in 0..6, got {getattr(self, name)}")
        if not self.ridge >= 0:
            raise ValueError(f"photometric ridge must be >= 0, got {self.ridge}")
        if self.prepass_factor < 1:
            raise ValueError(f"photometric prepass_factor must be >= 1, got {self.prepass_factor}")
        if self.prepass_flow == ORACLE:
            raise ValueError("photometric prepass_flow must be a flow backend that matches the images, not the oracle")
        if isinstance(self.prepass_flow, str):
            object.__setattr__(self, "prepass_flow", get_flow(self.prepass_flow))
        if not isinstance(self.prepass_flow, FlowBackend):
            raise ValueError(f"photometric prepass_flow must be a flow backend or its name, got {self.prepass_flow!r}")
        if not 0.0 < self.alpha < 1.0:
            raise ValueError(f"photometric alpha must be in (0, 1), got {self.alpha}")
        if not (self.min_gain >= 0 and self.min_field >= 0 and self.min_common >= 0):
            raise ValueError(f"photometric min_gain {self.min_gain}, min_field {self.min_field} and min_common "
                             f"{self.min_common} must be >= 0")
        if not 0.0 <= self.hemispheres <= 1.0:
            raise ValueError(f"photometric hemispheres must be in [0, 1], got {self.hemispheres}")
        if not 0 <= self.response <= 4:
            raise ValueError(f"photometric response must be in 0..4, got {self.response}")
        if not self.min_response >= 0:
            raise ValueError(f"photometric min_response must be >= 0, got {self.min_response}")
        if not self.agreement > 0:
            raise ValueError(f"photometric agreement must be > 0, got {self.agreement}")
        if not self.flat_log_gradient > 0:
            raise ValueError(f"photometric flat_log_gradient must be > 0, got {self.flat_log_gradient}")
        if self.factor < 1:
            raise ValueError(f"photometric factor must be >= 1, got {self.factor}")
        if not 0.0 <= self.dark < self.bright <= 1.0:
            raise ValueError(f"photometric dark {self.dark} and bright {self.bright} must satisfy 0 <= dark < "
                             "bright <= 1")
        if not (self.max_fit_pixels >= 1 and self.longitude_blocks >= 1 and self.min_block_samples >= 0):
            raise ValueError(f"photometric max_fit_pixels {self.max_fit_pixels} and longitude_blocks "
                             f"{self.longitude_blocks} must be >= 1, min_block_samples {self.min_block_samples} >= 0")

    def config(self) -> dict:
        """JSON-able: every field as it is, the pre-pass flow as its name, description and parameters."""
        out = {f.name: getattr(self, f.name) for f in dataclasses.fields(self)}
        out["prepass_flow"] = self.prepass_flow.config()
        return out


NO_CALIBRATION = PhotometricParams(mode="none")
"""The images as they are (no self-calibration)."""


_S = np.arange(256, dtype=np.float64) / 255.0
_SRGB_TABLE = np.where(_S <= 0.04045, _S / 12.92, ((_S + 0.055) / 1.055) ** 2.4)


_SRGB_TABLE32 = _SRGB_TABLE.astype(np.float32)


def srgb_to_linear(img: np.ndarray, dtype=np.float64) -> np.ndarray:
    """(...) uint8 sRGB -> linear light in [0, 1] (IEC 61966-2-1), through a 256-entry table of ``dtype`` (float64
    or float32: the float64 values rounded)."""
    table = _SRGB_TABLE32 if np.dtype(dtype) == np.float32 else _SRGB_TABLE
    return table[np.asarray(img, dtype=np.uint8)]


def linear_to_srgb(linear: np.ndarray, dtype=np.float64) -> np.ndarray:
    """Linear light (..., 3) -> 8-bit sRGB uint8: clip to [0, 1] (NaN -> 0), IEC 61966-2-1, round half up, computed
    in ``dtype`` (float32 is faster; a value within float32 rounding of a step between two codes may land on the
    other one)."""
    x = np.clip(np.nan_to_num(np.asarray(linear, dtype=dtype), nan=0.0), 0.0, 1.0)
    s = np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, dtype(1.0 / 2.4)) - 0.055)
    return np.floor(s * 255.0 + 0.5).astype(np.uint8)


def basis(bearings: np.ndarray, degree: int, even: bool = False, central: bool = False) -> np.ndarray:
    """The field's basis functions at camera-frame bearings.

    Args:
        bearings: (..., 3) unit bearings in the camera's frame.
        degree: highest monomial degree (0: no field).
        even: only the monomials whose every power is even.
        central: only the monomials of even total degree: the functions with ``f(-b) = f(b)``, as the fall-off of
            two like back-to-back lenses is, whatever their axis.
    Returns:
        (..., J) float64: every monomial ``x^i y^j z^k`` with ``1 <= i + j + k <= degree`` whose ``z`` power is at
        most 1 (``z^2 = 1 - x^2 - y^2`` makes the others redundant; with ``even``, ``i``, ``j`` even and no ``z``),
        then ``|x|, |y|, |z|`` (when degree >= 1).
    """
    b = np.asarray(bearings, dtype=np.float64)
    x, y, z = b[..., 0], b[..., 1], b[..., 2]
    cols = []
    for total in range(1, degree + 1):
        for i, j, k in itertools.product(range(total + 1), repeat=3):
            if i + j + k == total and k <= 1 and not (even and (i % 2 or j % 2 or k % 2)) \
                    and not (central and total % 2):
                cols.append(x ** i * y ** j * z ** k)
    if degree >= 1:
        cols += [np.abs(x), np.abs(y), np.abs(z)]
    if not cols:
        return np.zeros((*b.shape[:-1], 0))
    return np.stack(cols, axis=-1)


RESPONSE_MID = float(np.log(0.18))
"""The level about which a camera's response polynomial is written (mid-grey, natural log of linear light)."""


def response_basis(log_level: np.ndarray, degree: int) -> np.ndarray:
    """The response polynomial's terms at log linear levels.

    Args:
        log_level: (...) natural log of a camera's linear level per channel.
        degree: the polynomial's degree (0: no terms).
    Returns:
        (..., degree) float64: ``s, s^2, ..., s^degree`` with ``s = log_level - RESPONSE_MID``.
    """
    s = np.asarray(log_level, np.float64) - RESPONSE_MID
    return np.stack([s ** (i + 1) for i in range(degree)], axis=-1) if degree else np.zeros((*s.shape, 0))


def fit_gain(ratio: np.ndarray, phi: np.ndarray, params: PhotometricParams) -> tuple[np.ndarray, np.ndarray, dict]:
    """Robust fit of ``ratio[n, c] = a_c + phi[n] @ beta``.

    Args:
        ratio: (N, 3) log ratios of K over C per channel (natural log) at N usable pixels.
        phi: (N, J) basis values there (:func:`basis`).
    Returns:
        ``(a, beta, info)``: (3,) per-channel log gains, (J,) field coefficients, and the fit's ``pixels`` and
        robust residual ``sigma`` (natural log).
    """
    n, j = phi.shape
    if n < 10 * (3 + j):
        return np.zeros(3), np.zeros(j), {"pixels": int(n), "sigma": float("nan")}
    # one design matrix for the three channels: rows (n, c), columns a_0, a_1, a_2, beta
    design = np.zeros((n * 3, 3 + j))
    for c in range(3):
        design[c::3, c] = 1.0
        design[c::3, 3:] = phi
    target = ratio.reshape(-1).astype(np.float64)
    # start from the per-channel medians (robust to the parallax outliers)
    a0 = np.median(ratio, axis=0)
    reg = np.full(3 + j, 1e-6)
    reg[3:] += params.ridge * n
    coef, w, sigma = _irls(design, target, np.concatenate([a0, np.zeros(j)]), params, reg, tied=0)
    return coef[:3], coef[3:], {"pixels": int(n), "sigma": sigma, "inliers": float((w > 0).mean())}


def _reduce(lin: np.ndarray, factor: int) -> np.ndarray:
    if factor == 1:
        return lin
    h, w = lin.shape[:2]
    return cv2.resize(lin, (w // factor, h // factor), interpolation=cv2.INTER_AREA)


def _project(rot_k: np.ndarray, pos_k: np.ndarray, points: np.ndarray, width: int, height: int):
    """Where world ``points`` (..., 3) project into camera K (rotation: world-from-camera): pixel column and row
    (..., float64) of a ``width`` x ``height`` equirect image and the unit bearing (..., 3) in K's own frame.  The
    longitude and latitude come from the unit bearing (``arcsin`` of its z); they differ from
    :func:`reconstruction.camera.equirect.project`'s (``arctan2`` of the unnormalised vector) by about 1e-12 pixel."""
    v = (np.asarray(points, np.float64) - pos_k) @ rot_k
    v = v / np.maximum(np.linalg.norm(v, axis=-1, keepdims=True), 1e-12)
    lam = np.arctan2(v[..., 0], v[..., 1])
    phi = np.arcsin(np.clip(v[..., 2], -1.0, 1.0))
    return *lonlat_to_pixel(lam, phi, width, height), v


def _sample(lin_k: np.ndarray, u: np.ndarray, row: np.ndarray) -> np.ndarray:
    """Bilinear samples (..., 3) of the equirect image ``lin_k`` at columns ``u`` in [-0.5, W - 0.5] and rows ``row``
    (two columns wrapped on each side; ``u`` is not reduced modulo W, so a few samples in a million differ by a
    1/32-pixel step from :func:`reconstruction.camera.resample.sample_equirect`'s)."""
    pad = 2
    padded = periodic_pad(lin_k, pad)
    return cv2.remap(padded, (u + pad).astype(np.float32), row.astype(np.float32), cv2.INTER_LINEAR,
                     borderMode=cv2.BORDER_REPLICATE)


def step(n: int, most: int) -> int:
    """Stride that keeps at most ``most`` of ``n`` samples."""
    return max(1, -(-n // most))


def align_images(images: dict, cameras: dict, params: PhotometricParams = PhotometricParams(),
                 others=("U", "R")) -> tuple[dict, dict]:
    """U's and R's images corrected to C's per-channel gains (and a field of ``pixel_degree``) from the same pixels
    (module doc; :func:`fit_photometric` pairs pixels through a distance map).

    Args:
        images: (H, W, 3) uint8 sRGB image per camera name.
        cameras: pose per camera name (unused: the same pixel is compared).
        params: the fit (:class:`PhotometricParams`); mode ``"none"`` returns the images unchanged.
        others: the cameras to correct.
    Returns:
        ``(images, info)``: new dict (C's array and any camera not corrected are the same objects) and per camera
        the fitted ``gain_rgb`` (the mean gain of K relative to C per channel), ``field_range`` (min and max of the
        achromatic field's gain), ``pixels`` and ``sigma``.
    """
    out = dict(images)
    if params.mode == "none":
        return out, {}
    f = params.factor
    lin_c = _reduce(srgb_to_linear(images["C"], np.float32), f)
    h, w = lin_c.shape[:2]
    info = {}
    phi_small = basis(bearing_grid(w, h), params.pixel_degree, params.even, params.central)
    for k in others:
        lin_k_full = srgb_to_linear(images[k], np.float32)
        sample = _reduce(lin_k_full, f)
        usable = np.all((lin_c > params.dark) & (lin_c < params.bright), axis=-1) \
            & np.all((sample > params.dark) & (sample < params.bright), axis=-1)
        ratio = np.log(sample[usable]) - np.log(lin_c[usable])
        stride = step(ratio.shape[0], params.max_fit_pixels)
        a, beta, fit = fit_gain(ratio[::stride], phi_small[usable][::stride], params)
        field = phi_small @ beta if beta.size else np.zeros((h, w))
        field = np.clip(field, -params.max_log_gain, params.max_log_gain)
        mean_field = float(np.mean(field))
        if beta.size:
            full_h, full_w = images[k].shape[:2]
            field_full = cv2.resize(field.astype(np.float32), (full_w, full_h), interpolation=cv2.INTER_LINEAR)
            gain = np.exp(-(field_full[..., None] + a.astype(np.float32)))
            out[k] = linear_to_srgb(lin_k_full * gain, np.float32)
        else:  # one gain per channel: the same arithmetic on each of the 256 codes, looked up
            gain = np.exp(-(np.float32(0.0) + a.astype(np.float32)))
            table = linear_to_srgb(_SRGB_TABLE32[:, None] * gain, np.float32)
            out[k] = cv2.LUT(np.ascontiguousarray(images[k]), table.reshape(256, 1, 3))
        info[k] = {"gain_rgb": np.exp(a + mean_field).tolist(),
                   "field_range": [float(np.exp(field.min() - mean_field)), float(np.exp(field.max() - mean_field))],
                   **fit}
    return out, info


@dataclass(frozen=True)
class PhotometricModel:
    """The photometric corrections :func:`fit_photometric` found supported (natural-log units).

    Attributes:
        gains: per corrected camera (U, R) its (3,) log gain relative to C per channel (the field's intercept).
        fields: per camera with a supported field of its own, the (J,) coefficients of its field over its own
            bearings (:func:`basis` of ``degree``).
        common: (J,) coefficients of the fall-off all three cameras share, or None.
        degree, even, central: the basis (:func:`basis`).
        responses: per camera with a supported response of its own, the coefficients of
            :func:`response_basis` (its log level relative to C's, beyond the gain).
    """

    gains: dict
    fields: dict
    common: np.ndarray | None
    degree: int
    even: bool
    central: bool = False
    responses: dict = dataclasses.field(default_factory=dict)

    @property
    def is_identity(self) -> bool:
        """Nothing to correct."""
        return not self.gains and not self.fields and self.common is None and not self.responses


IDENTITY = PhotometricModel({}, {}, None, 0, False)
"""The model of cameras that agree."""


def _irls(design: np.ndarray, target: np.ndarray, coef: np.ndarray, params: PhotometricParams,
          ridge: np.ndarray, tied: int = 1) -> tuple[np.ndarray, np.ndarray, float]:
    """Tukey-reweighted least squares from ``coef`` (``params.iterations`` steps; none: ``coef`` as it is):
    ``(coef, weights, sigma)``.  ``tied`` > 0: the rows are ``tied`` blocks of the same pixels in the same order
    (each pixel's 3 channels consecutive), and a pixel's weight in every row is its smallest over its rows (a pixel
    whose views do not all agree is left out of all of them); 0: each row its own weight.  The normal equations are
    summed block by block over the columns each block touches (a camera's rows are zero in the other camera's
    columns): the dense solution up to rounding."""
    w = np.ones(target.size)
    sigma = float("nan")
    if not params.iterations:
        return coef, w, sigma
    n_blocks = max(tied, 1)
    rows = target.size // n_blocks
    blocks = []
    for i in range(n_blocks):
        part = design[i * rows:(i + 1) * rows]
        cols = np.flatnonzero(np.any(part != 0, axis=0))
        blocks.append((slice(i * rows, (i + 1) * rows), cols, np.ascontiguousarray(part[:, cols])))
    for _ in range(params.iterations):
        res = target - np.concatenate([narrow @ coef[cols] for _, cols, narrow in blocks])
        sigma = robust_scale(res, 1e-6, "add")
        w = tukey_weights(res, params.tukey_c, sigma)
        if tied:
            per_pixel = w.reshape(tied, -1, 3).min(axis=2).min(axis=0)
            w = np.broadcast_to(per_pixel[None, :, None], (tied, per_pixel.size, 3)).reshape(-1)
        normal, rhs = np.diag(ridge).astype(np.float64), np.zeros(coef.size)
        for part, cols, narrow in blocks:
            root = np.sqrt(w[part])
            weighted = narrow * root[:, None]
            normal[np.ix_(cols, cols)] += weighted.T @ weighted
            rhs[cols] += weighted.T @ (target[part] * root)
        coef = np.linalg.solve(normal, rhs)
    return coef, w, sigma


def _log_gradient(lin: np.ndarray) -> np.ndarray:
    """(h, w) magnitude of the gradient of the log mean intensity, per pixel (wrapping in longitude)."""
    g = np.log(np.maximum(grey(lin, "mean"), 1e-4)).astype(np.float32)
    return np.hypot(*sobel_gradient(g))


def fit_photometric(images: dict, cameras: dict, distance: np.ndarray,
                    params: PhotometricParams = PhotometricParams(),
                    others=("U", "R")) -> tuple[PhotometricModel, dict]:
    """Fit U's and R's gains and fields relative to C and the fall-off the three share, and keep what the frame
    supports.

    Each of C's pixels is paired with where its point (``distance``) projects into U and R; over the pixels that
    are neither dark nor near saturation in any camera and lie in flat patches (``flat_log_gradient``), one robust
    fit (a pixel whose views do not all agree with the model, a view-dependent reflection, is left out of all) of

        ln K_c(q) - ln C_c(p) = a_Kc + g_K(b_K) + r_K(ln K_c(q)) + f(b_K) - f(b_C)

    (``g_K`` K's own field, ``f`` the shared fall-off, both over :func:`basis` of the camera-frame bearings ``b_K``,
    ``b_C``; ``f`` is seen only through parallax, so only with ``common_field``; ``r_K`` K's response, the terms of
    :func:`response_basis` of its own level per channel).  Each quantity (K's mean gains, K's field, K's response,
    the shared fall-off) is then tested (:func:`reconstruction.evidence.hotelling` over the jackknife of
    the sphere's blocks) and kept when the test rejects "no correction" at ``params.alpha`` and the correction is
    at least ``params.min_gain`` (the largest channel's mean log gain), ``params.min_field`` (the field's log
    range over the sphere) or ``params.min_response``; the kept ones are fitted again alone.

    Args:
        images: (H, W, 3) uint8 sRGB image per camera name; cameras: pose per camera (``position`` (3,) metres,
            ``rotation`` (3, 3) world-from-camera); distance: (H, W) distance of C, metres (non-finite or <= 0:
            not used).
        params: the fit; mode ``"none"`` returns :data:`IDENTITY`.
    Returns:
        ``(model, record)``: the supported corrections (:class:`PhotometricModel`) and per camera (and
        ``"common"``) what was fitted, its evidence and whether it is applied (JSON-able).
    """
    if params.mode == "none":
        return IDENTITY, {}
    f = params.factor
    lin_c = _reduce(srgb_to_linear(images["C"], np.float32), f)
    h, w = lin_c.shape[:2]
    b_c = bearing_grid(w, h)
    phi_c = basis(b_c, params.degree, params.even, params.central)
    n_j = phi_c.shape[-1]
    d_small = _reduce(np.asarray(distance, np.float32), f)
    rot_c = np.asarray(cameras["C"].rotation, np.float64)
    world = b_c @ rot_c.T * d_small[..., None] + np.asarray(cameras["C"].position, np.float64)
    blocks_c = sphere_blocks(b_c @ rot_c.T, params.longitude_blocks)
    flat = _log_gradient(lin_c) < params.flat_log_gradient
    ok_c = np.isfinite(d_small) & (d_small > 0) & flat & np.all((lin_c > params.dark) & (lin_c < params.bright),
                                                                 axis=-1)
    n_r = params.response
    cols_per = 3 + n_j + n_r
    common_first = cols_per * len(others)
    n_cols = common_first + (n_j if params.common_field else 0)
    samples, bearings, usable = {}, {}, ok_c
    for k in others:
        lin_k = _reduce(srgb_to_linear(images[k], np.float32), f)
        u, row, bearings[k] = _project(np.asarray(cameras[k].rotation, np.float64),
                                       np.asarray(cameras[k].position, np.float64), world, w, h)
        samples[k] = _sample(lin_k, u, row)
        usable = usable & np.all((samples[k] > params.dark) & (samples[k] < params.bright), axis=-1)
    # the pixels every camera sees well: one sample each, so that the fit can ask all views to agree on it
    idx = np.flatnonzero(usable.reshape(-1))
    idx = idx[::step(idx.size, params.max_fit_pixels)]
    rows, targets = [], []
    log_c = np.log(lin_c.reshape(-1, 3)[idx])
    for i, k in enumerate(others):
        log_k = np.log(samples[k].reshape(-1, 3)[idx])
        ratio = (log_k - log_c).astype(np.float64)
        phi_k = basis(bearings[k].reshape(-1, 3)[idx], params.degree, params.even, params.central)
        design = np.zeros((idx.size, 3, n_cols))
        for c in range(3):
            design[:, c, i * cols_per + c] = 1.0
        design[:, :, i * cols_per + 3:i * cols_per + 3 + n_j] = phi_k[:, None, :]
        design[:, :, i * cols_per + 3 + n_j:(i + 1) * cols_per] = response_basis(log_k, n_r)
        if params.common_field:
            design[:, :, common_first:] = (phi_k - phi_c.reshape(-1, n_j)[idx])[:, None, :]
        rows.append(design.reshape(-1, n_cols))
        targets.append(ratio.reshape(-1))
    blocks = [np.repeat(blocks_c.reshape(-1)[idx], 3)] * len(others)
    design, target, blocks = np.concatenate(rows), np.concatenate(targets), np.concatenate(blocks)
    n_samples = target.size // 3
    if n_samples < 10 * n_cols:
        return IDENTITY, {"pixels": int(n_samples), "applied": False, "reason": "too few usable pixels"}
    ridge = np.full(n_cols, 1e-6)
    for i in range(len(others)):
        ridge[i * cols_per + 3:i * cols_per + 3 + n_j] += params.ridge * n_samples
    coef0 = np.zeros(n_cols)
    for i, t in enumerate(targets):
        coef0[i * cols_per:i * cols_per + 3] = np.median(t.reshape(-1, 3), axis=0)
    coef, weights, sigma = _irls(design, target, coef0, params, ridge, len(others))
    theta, cov, n_blocks = jackknife_linear(design, target, weights, blocks, ridge, params.min_block_samples)
    phi_mean = phi_c.reshape(-1, n_j).mean(axis=0)
    phi_all = phi_c.reshape(-1, n_j)

    halves = jackknife_hemispheres(design, target, weights, blocks, ridge, params.min_block_samples) \
        if params.hemispheres > 0 else []

    def test(lin_map: np.ndarray, size_of: Callable[[np.ndarray], float], floor: float) -> Evidence:
        ev = hotelling(lin_map @ theta, lin_map @ cov @ lin_map.T, n_blocks, params.alpha)
        ev["supported"] = bool(ev["supported"] and size_of(theta) >= floor)
        if halves:  # a share of the floor when fitted from each hemisphere alone (significance: the whole sphere's)
            ev["hemispheres"] = []
            for th, cv, nb in halves:
                size = size_of(th)
                ev["hemispheres"].append({"size": size, "p_value": hotelling(lin_map @ th, lin_map @ cv @ lin_map.T, nb,
                                                                             params.alpha)["p_value"], "blocks": nb})
                ev["supported"] = bool(ev["supported"] and size >= params.hemispheres * floor)
        return ev

    # the levels most of the fit's pixels have (C's 5th to 95th percentile)
    levels = response_basis(np.linspace(*np.quantile(log_c, [0.05, 0.95]), 64), n_r)

    def response_range(coef: np.ndarray) -> float:
        r = levels @ coef
        return float(r.max() - r.min())

    def field_range(beta: np.ndarray) -> tuple[float, float]:
        v = phi_all @ beta
        v = v - v.mean()
        return float(np.exp(v.min())), float(np.exp(v.max()))

    def field_size(beta: np.ndarray) -> float:
        lo, hi = field_range(beta)
        return float(np.log(hi / lo))

    record = {"pixels": int(n_samples), "sigma": sigma, "inliers": float((weights > 0).mean()),
              "blocks": n_blocks}
    keep = np.zeros(n_cols, bool)
    for i, k in enumerate(others):
        a_cols = np.arange(i * cols_per, i * cols_per + 3)
        f_cols = np.arange(i * cols_per + 3, i * cols_per + 3 + n_j)
        r_cols = np.arange(i * cols_per + 3 + n_j, (i + 1) * cols_per)
        mean_gain = np.zeros((3, n_cols))
        mean_gain[np.arange(3), a_cols] = 1.0
        mean_gain[:, f_cols] = phi_mean
        gains = mean_gain @ theta
        gain_ev = test(mean_gain, lambda t, m=mean_gain: float(np.abs(m @ t).max()), params.min_gain)
        lo, hi = field_range(theta[f_cols]) if n_j else (1.0, 1.0)
        field_ev = test(np.eye(n_cols)[f_cols], lambda t, c=f_cols: field_size(t[c]), params.min_field) if n_j else \
            Evidence(statistic=float("nan"), p_value=1.0, blocks=n_blocks, supported=False)
        record[k] = {"gain_rgb": np.exp(gains).tolist(), "gain": {**gain_ev, "applied": gain_ev["supported"]},
                     "field_range": [lo, hi], "field": {**field_ev, "applied": field_ev["supported"]}}
        if n_r:
            size = response_range(theta[r_cols])
            response_ev = test(np.eye(n_cols)[r_cols], lambda t, c=r_cols: response_range(t[c]), params.min_response)
            record[k]["response_range"] = size
            record[k]["response"] = {**response_ev, "applied": response_ev["supported"]}
            keep[r_cols] = response_ev["supported"]
        if gain_ev["supported"] or field_ev["supported"] or keep[r_cols].any():
            keep[a_cols] = True
        if field_ev["supported"]:
            keep[f_cols] = True
    common = None
    if params.common_field and n_j:
        c_cols = np.arange(common_first, n_cols)
        lo, hi = field_range(theta[c_cols])
        ev = test(np.eye(n_cols)[c_cols], lambda t: field_size(t[c_cols]), params.min_common)
        record["common"] = {"field_range": [lo, hi], "field": {**ev, "applied": ev["supported"]}}
        keep[c_cols] = ev["supported"]
    if not keep.any():
        record["applied"] = False
        return IDENTITY, record
    coef, weights, sigma = _irls(design[:, keep], target, np.where(keep, coef, 0.0)[keep], params, ridge[keep],
                                 len(others))
    full = np.zeros(n_cols)
    full[keep] = coef
    gains, fields, responses = {}, {}, {}
    for i, k in enumerate(others):
        if keep[i * cols_per]:
            gains[k] = full[i * cols_per:i * cols_per + 3]
        if n_j and keep[i * cols_per + 3]:
            fields[k] = full[i * cols_per + 3:i * cols_per + 3 + n_j]
        if n_r and keep[i * cols_per + 3 + n_j]:
            responses[k] = full[i * cols_per + 3 + n_j:(i + 1) * cols_per]
    if params.common_field and n_j and keep[-1]:
        common = full[common_first:]
    record["applied"] = True
    record["sigma_applied"] = sigma
    return PhotometricModel(gains, fields, common, params.degree, params.even, params.central, responses), record


def apply_photometric(images: dict, model: PhotometricModel, max_log_gain: float = 2.0) -> dict:
    """The images with ``model``'s corrections divided out in linear light (:func:`fit_photometric`).

    Args:
        images: (H, W, 3) uint8 sRGB image per camera name.
        max_log_gain: each camera's correction field is clipped to +- this (natural log).
    Returns:
        A new dict; a camera with nothing to correct keeps its array (the same object).
    """
    out = dict(images)
    if model.is_identity:
        return out
    for k, img in images.items():
        h, w = img.shape[:2]
        if k not in model.gains and k not in model.fields and k not in model.responses and model.common is None:
            continue
        small_w, small_h = max(w // 4, 8), max(h // 4, 4)
        phi = basis(bearing_grid(small_w, small_h), model.degree, model.even, model.central)
        field = np.zeros((small_h, small_w))
        if model.fields.get(k) is not None:
            field += phi @ model.fields[k]
        if model.common is not None:  # the shared fall-off only brightens: its brightest bearing keeps its level
            common = phi @ model.common
            field += common - common.max()
        field = cv2.resize(np.clip(field, -max_log_gain, max_log_gain).astype(np.float32), (w, h),
                           interpolation=cv2.INTER_LINEAR)
        log_gain = field[..., None] + np.asarray(model.gains.get(k, np.zeros(3)), np.float32)
        lin = srgb_to_linear(img, np.float32)
        if model.responses.get(k) is not None:  # of K's own level: a table of its 256 codes
            coef = np.asarray(model.responses[k], np.float64)
            table = response_basis(np.log(np.maximum(_SRGB_TABLE, 1e-4)), coef.size) @ coef
            log_gain = log_gain + np.clip(table, -max_log_gain, max_log_gain).astype(np.float32)[img]
        out[k] = linear_to_srgb(lin * np.exp(-log_gain), np.float32)
    return out


class FrameView:
    """``frame`` with some attributes replaced (e.g. ``images``, ``cameras``); every other one is read from
    ``frame``, which is unchanged."""

    def __init__(self, frame, **replaced):
        self._frame = frame
        self.__dict__.update(replaced)

    def __getattr__(self, name):
        return getattr(self._frame, name)

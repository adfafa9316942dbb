"""Per-pixel Levenberg-Marquardt refinement of the distance along C's bearings (paper section 3).

The unknown is one scalar per pixel, the distance ``d`` (metres) of the surface seen through that pixel
of C.  All pixels are solved at once: every array is (N,) or (N, m), never a Python loop per pixel.

Residuals, all in *pixel equivalents* (radians x H / pi: one row of a rectified equirect image):

* geometric, per pair k in {U, R}: ``sqrt(w_k) * (beta_k(d) - beta_obs_k) * H/pi`` — the reprojection
  error of X = C + d a into camera k along its epipolar curve (see :mod:`reconstruction.refine.triangulate`);
* colour (``color_weight > 0``), per pair: ``sqrt(color_weight) * s * tanh((I_k(x_k(d)) - I_C(p)) / s)``,
  the intensity difference between C's pixel and camera k's image at the projection x_k(d), with
  intensities in [0, 1] and the saturation ``s`` making it robust to occlusions (paper eq. 2).  The paper's
  next steps: ``color-rgb`` compares the three RGB channels instead of grey, ``color-patch`` compares a small
  patch (``color_patch`` x ``color_patch`` pixels around the pixel and around its projection) instead of one
  pixel ("taking into account the surrounding information").

Weights ``w_k`` (:mod:`reconstruction.refine.weights`): ``angle`` = sin(alpha_k)^p (Yin et al. 2019: trust a pair
less near its epipoles), ``gradient`` = angle weight x the image gradient along pair k's epipolar
direction (paper eq. 1: the confidence of the flow).  A pair invalid at a pixel gets weight 0.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field

import numba
import numpy as np

from reconstruction.camera.equirect import project_rays_camera
from reconstruction.plugins import Registry, collect_registry, shadow_message, unknown_name_message
from reconstruction.refine.triangulate import PairGeometry, beta_of_distance

__all__ = ["RefineConfig", "builtin_variants", "discover_variants", "get_variant", "RefineProblem",
           "levenberg_marquardt", "ColorTerm", "patch_offsets", "patch_reference"]


@dataclass(frozen=True)
class RefineConfig:
    """A refinement variant.  Every field has a unit; defaults were chosen by measurement (docs/refinement.md).

    Attributes:
        name: the ``--variants`` name.
        angle_power: p in the angle weight sin(alpha_k)^p (dimensionless; 0 disables angle weighting).
        gradient: multiply the angle weight by the epipolar-gradient confidence (paper eq. 1).
        gradient_scale: g0, intensity change per pixel (intensity in [0, 1]) at which the gradient
            confidence reaches half of its range.
        gradient_floor: confidence of a texture-less pixel, in [0, 1] (keeps the pair in play).
        color_weight: lambda_c, weight of the colour residual relative to one pixel-equivalent of
            geometric residual, per unit intensity squared (0 disables the colour term).
        color_saturation: s, intensity (in [0, 1]) beyond which a colour difference stops pulling
            (occlusions, specularities).
        color_blur_px: Gaussian sigma, pixels, applied to the images used by the colour term.
        color_rgb: use the three RGB channels instead of grayscale (the paper's future work).
        color_patch: side, pixels (odd), of the patch compared by the colour term: the residual of every pixel
            offset in the patch, taken at the same offset around C's pixel and around its projection in camera k
            (1: the pixel alone, the paper's eq. 2).
        color_iters: LM iterations of the colour stage, which starts from the converged geometric solution
            (the colour cost is non-convex: it refines locally, it does not search).
        color_min_gradient: the colour stage refines only pixels whose blurred image gradient in C exceeds
            this, intensity per pixel (elsewhere the colour residual has no slope and cannot move d).
        lateral_px: sigma, pixel equivalents, of the lateral-flow confidence 1 / (1 + (e / sigma)^2), where e
            is the match's distance from the epipolar curve (0 disables it).
        lateral_max_px: a match farther than this from its epipolar curve, pixel equivalents, fails the
            match checks.
        fb_max_px: likewise for a forward-backward flow inconsistency above this, pixels.
        fallback_weight: weight factor, dimensionless, of a pair whose match failed the checks: at a pixel
            with a checked pair it is all but ignored; where no pair passed, the unchecked pairs still decide.
        outlier_log_ratio: at a pixel where no pair passed the checks, a result differing from the
            edge-aware interpolation of its checked neighbours by more than this in |log(d / d_fill)|
            (0.5: a factor 1.65) is an outlier and takes the interpolated distance.
        fill_lambda, fill_sigma_color: smoothness (dimensionless) and colour-edge scale (8-bit levels) of
            that edge-aware interpolation (OpenCV fast global smoother guided by C's image).
        max_iters: LM iterations of the geometric stage (measured at 1000x500: all pixels done within 21).
        tol_m: stop a pixel when its step is below this, metres.
    """

    name: str
    angle_power: float = 2.0
    gradient: bool = False
    gradient_scale: float = 0.02
    gradient_floor: float = 0.05
    color_weight: float = 0.0
    color_saturation: float = 0.1
    color_blur_px: float = 1.0
    color_rgb: bool = False
    color_patch: int = 1
    color_iters: int = 6
    color_min_gradient: float = 0.01
    lateral_px: float = 1.0
    lateral_max_px: float = 3.0
    fb_max_px: float = 1.0
    fallback_weight: float = 1e-3
    outlier_log_ratio: float = 0.5
    fill_lambda: float = 1e4
    fill_sigma_color: float = 8.0
    max_iters: int = 30
    tol_m: float = 1e-7
    description: str = ""

    def config(self) -> dict:
        """Every field, JSON-able (what ``config.json`` records)."""
        return asdict(self)


ENTRY_POINT_GROUP = "tri360.variants"


def builtin_variants() -> list[RefineConfig]:
    """The paper's refinement variants (section 3), defaults chosen in docs/refinement.md."""
    return [
        RefineConfig("angle", description="LM on reprojection error, angle weights (Yin et al. 2019)"),
        RefineConfig("gradient", gradient=True, description="LM, angle x epipolar-gradient weights (paper eq. 1)"),
        RefineConfig("color", color_weight=30.0,
                     description="LM, angle weights + grayscale intensity consistency (paper eq. 2)"),
        # the paper's next steps; the weight per residual is divided by the residual count, so that a difference
        # shared by every channel / patch pixel pulls as hard as one grey difference under ``color``
        RefineConfig("color-rgb", color_weight=10.0, color_rgb=True,
                     description="LM, angle weights + RGB colour consistency (the paper's future work)"),
        RefineConfig("color-patch", color_weight=30.0 / 9.0, color_patch=3,
                     description="LM, angle weights + grey consistency over a 3x3 patch (the paper's future work)"),
    ]


def discover_variants() -> tuple[dict[str, RefineConfig], dict[str, str]]:
    """Every refinement variant: the built-ins plus entry points of group ``tri360.variants`` (each loads to
    a :class:`RefineConfig` or a list of them).

    Returns:
        ``(variants by name, errors by plugin source)``.
    """
    reg = variant_registry()
    return reg.entries, reg.errors


def variant_registry() -> Registry:
    """The built-in variants plus entry points of group ``tri360.variants`` (an outside variant whose name is taken
    is refused: :attr:`reconstruction.plugins.Registry.refused`)."""
    return collect_registry(builtin_variants(), ENTRY_POINT_GROUP, lambda c: isinstance(c, RefineConfig),
                            "RefineConfig", key=lambda c: c.name)


def refuse_shadowed_variant(name: str, reg: Registry | None = None) -> None:
    """ValueError naming the plugin when a refused outside variant also has ``name`` (asking for it is
    ambiguous)."""
    reg = variant_registry() if reg is None else reg
    if name in reg.refused:
        raise ValueError(shadow_message("variant", name, reg))


def get_variant(name: str) -> RefineConfig:
    """Look up a refinement variant; raises ValueError listing the known names, or naming the plugin when a refused
    outside variant also has ``name``."""
    reg = variant_registry()
    refuse_shadowed_variant(name, reg)
    variants, errors = reg.entries, reg.errors
    if name not in variants:
        raise ValueError(unknown_name_message("variant", name, ["average", *sorted(variants)], errors,
                                              "variant plugins"))
    return variants[name]


@dataclass
class ColorTerm:
    """Data for the colour residual of one pair.

    Attributes:
        image: (H, W, c) float64 intensities of camera k in [0, 1] (sampled with exact bilinear
            interpolation, whose own derivatives give the Jacobian).
        ref: (N, P c) C's intensities at the refined pixels, offset by each of the P ``offsets`` (channels fastest).
        start: (3,) C's centre relative to camera k's centre, in camera k's frame, metres.
        direction: (N, 3) the pixels' bearings in camera k's frame.
        offsets: (P, 2) pixel offsets (du, dv) of the compared patch (None: the pixel alone, P = 1).
    """

    image: np.ndarray
    ref: np.ndarray
    start: np.ndarray
    direction: np.ndarray
    offsets: np.ndarray | None = None


def patch_offsets(size: int) -> np.ndarray:
    """(size * size, 2) float64 pixel offsets (du, dv) of a square patch centred on 0 (``size`` odd, >= 1)."""
    if size < 1 or size % 2 == 0:
        raise ValueError(f"color_patch must be odd and >= 1, got {size}")
    r = np.arange(size) - size // 2
    dv, du = np.meshgrid(r, r, indexing="ij")
    return np.stack([du.ravel(), dv.ravel()], axis=1).astype(np.float64)


def patch_reference(image: np.ndarray, offsets: np.ndarray) -> np.ndarray:
    """C's intensities around every pixel: (H, W, c) equirect image -> (H W, P c) values at each integer offset
    (columns wrap, rows are clamped at the poles), channels fastest."""
    h, w, c = image.shape
    out = []
    rows = np.arange(h)
    for du, dv in offsets.astype(int):
        shifted = np.roll(image, -du, axis=1)[np.clip(rows + dv, 0, h - 1)]
        out.append(shifted.reshape(h * w, c))
    return np.concatenate(out, axis=1)


@dataclass
class RefineProblem:
    """The least-squares problem of all refined pixels.

    Attributes:
        origin: (3,) C's centre, metres.
        bearings: (N, 3) unit world bearings of the pixels.
        pairs: epipolar geometry per pair (arrays (N,)).
        weights: (N,) geometric weight per pair (0 = pair not used at that pixel).
        height: image height H (sets the pixel-equivalent scale H/pi).
        width: image width W.
        color: colour terms per pair (empty: no colour term).
        color_weight, color_saturation: lambda_c and s of :class:`RefineConfig`.
    """

    origin: np.ndarray
    bearings: np.ndarray
    pairs: list[PairGeometry]
    weights: list[np.ndarray]
    height: int
    width: int
    color: list[ColorTerm] = field(default_factory=list)
    color_weight: float = 0.0
    color_saturation: float = 0.1

    @property
    def n(self) -> int:
        return self.bearings.shape[0]

    def residuals(self, d: np.ndarray, idx: np.ndarray | None = None):
        """Residuals and Jacobian at distances ``d``.

        Args:
            d: (M,) distances, metres, for pixels ``idx`` (all pixels if None, M = N).
            idx: optional (M,) integer indices into the problem's pixels.
        Returns:
            ``(r, J)``, each (M, m): residuals (pixel equivalents) and d r / d d (per metre).
        """
        sel = slice(None) if idx is None else idx
        geo_r, geo_j = self._geometric(d, sel)
        if not self._has_color():
            return geo_r, geo_j
        m = d.shape[0]
        cols = sum(t.ref.shape[1] for t in self.color)
        r = np.empty((m, geo_r.shape[1] + cols))
        j = np.empty_like(r)
        r[:, :geo_r.shape[1]], j[:, :geo_j.shape[1]] = geo_r, geo_j
        self._color(d, idx, r, j, np.zeros((m, 3)), geo_r.shape[1])
        return r, j

    def normal_terms(self, d: np.ndarray, idx: np.ndarray | None = None):
        """Per-pixel cost ``sum(r^2)``, gradient ``sum(J r)`` and Gauss-Newton Hessian ``sum(J^2)``, each (M,),
        of :meth:`residuals` without forming the colour residuals' (M, P c) arrays (what the LM needs)."""
        geo_r, geo_j = self._geometric(d, slice(None) if idx is None else idx)
        sums = np.stack(_normal_terms(geo_r, geo_j), axis=1)
        if self._has_color():
            empty = np.empty((0, 0))
            self._color(d, idx, empty, empty, sums, 0)
        return sums[:, 0], sums[:, 1], sums[:, 2]

    def _has_color(self) -> bool:
        return bool(self.color) and self.color_weight > 0

    def _geometric(self, d: np.ndarray, sel):
        """(M, pairs) geometric residuals and their derivatives."""
        scale = self.height / np.pi
        rs, js = [], []
        for g, w in zip(self.pairs, self.weights, strict=True):
            gi = PairGeometry(g.baseline_m, g.cos_alpha[sel], g.sin_alpha[sel], g.beta_obs[sel])
            beta, dbeta = beta_of_distance(gi, d)
            sw = np.sqrt(w[sel]) * scale
            rs.append(sw * (beta - gi.beta_obs))
            js.append(sw * dbeta)
        return np.stack(rs, axis=1), np.stack(js, axis=1)

    def _color(self, d, idx, r_out, j_out, sums, col0):
        """Colour residuals of every term into columns ``col0...`` of ``r_out`` / ``j_out`` (when not empty) and
        their sums added to ``sums`` (M, 3)."""
        rows = np.arange(d.shape[0]) if idx is None else np.asarray(idx, dtype=np.int64)
        sel = slice(None) if idx is None else idx
        for term in self.color:
            u, v, du, dv = project_rays_camera(term.start, term.direction[sel], d, self.width, self.height)
            offsets = np.zeros((1, 2)) if term.offsets is None else np.asarray(term.offsets, np.float64)
            _color_kernel(np.ascontiguousarray(term.image, np.float64), u, v, du, dv, offsets,
                          np.ascontiguousarray(term.ref, np.float64), rows, float(self.color_saturation),
                          float(np.sqrt(self.color_weight)), r_out, j_out, sums, col0)
            col0 += term.ref.shape[1]


@numba.njit(parallel=True, cache=True)
def _color_kernel(image, u, v, du, dv, offsets, ref, rows, s, lam, r_out, j_out, sums, col0):
    """Colour residuals ``lam s tanh((I_k(x + o) - I_C) / s)`` of M pixels and P patch offsets, with their
    derivatives per metre, sampled by exact bilinear interpolation (columns wrap, rows clamp; where clamped the
    row derivative is 0), as :func:`reconstruction.camera.resample.bilinear_with_gradient` does.

    Args:
        image: (H, W, c) float64 intensities in [0, 1] of camera k.
        u, v, du, dv: (M,) projections of the pixels into k (pixels) and their derivatives (pixels per metre).
        offsets: (P, 2) float64 patch offsets (du, dv), pixels.
        ref: (N, P c) C's intensities per pixel of the problem, channels fastest; ``rows`` (M,) int64 picks them.
        s, lam: saturation (intensity) and ``sqrt(color_weight)``.
        r_out, j_out: (M, >= col0 + P c) outputs written at columns ``col0...``, or (0, 0) to skip them.
        sums: (M, 3) float64, ``sum r^2``, ``sum J r``, ``sum J^2`` added in place.
    A pixel whose projection is not finite gets NaN residuals and sums.
    """
    h, w, c = image.shape
    write = r_out.shape[0] > 0
    for i in numba.prange(u.shape[0]):
        row = rows[i]
        cost = 0.0
        grad = 0.0
        hess = 0.0
        for k in range(offsets.shape[0]):
            uu = u[i] + offsets[k, 0]
            v_raw = v[i] + offsets[k, 1]
            if not (np.isfinite(uu) and np.isfinite(v_raw)):  # NaN residuals: never an index from NaN
                for ch in range(c):
                    if write:
                        r_out[i, col0 + k * c + ch] = np.nan
                        j_out[i, col0 + k * c + ch] = np.nan
                cost = grad = hess = np.nan
                continue
            vv = min(max(v_raw, 0.0), h - 1.0)
            u0 = np.floor(uu)
            fu = uu - u0
            i0 = np.int64(u0) % w
            i1 = (i0 + 1) % w
            r0 = min(np.int64(np.floor(vv)), h - 2)
            fv = vv - r0
            inside = v_raw > 0.0 and v_raw < h - 1.0
            for ch in range(c):
                p00 = image[r0, i0, ch]
                p01 = image[r0, i1, ch]
                p10 = image[r0 + 1, i0, ch]
                p11 = image[r0 + 1, i1, ch]
                top = p00 + fu * (p01 - p00)
                bottom = p10 + fu * (p11 - p10)
                value = top + fv * (bottom - top)
                d_du = (p01 - p00) + fv * ((p11 - p10) - (p01 - p00))
                d_dv = bottom - top if inside else 0.0
                th = np.tanh((value - ref[row, k * c + ch]) / s)
                r = lam * s * th
                jac = lam * (1.0 - th * th) * (d_du * du[i] + d_dv * dv[i])
                if write:
                    r_out[i, col0 + k * c + ch] = r
                    j_out[i, col0 + k * c + ch] = jac
                cost += r * r
                grad += jac * r
                hess += jac * jac
        sums[i, 0] += cost
        sums[i, 1] += grad
        sums[i, 2] += hess


def levenberg_marquardt(problem: RefineProblem, d0: np.ndarray, d_min: float = 0.05, d_max: float = 100.0,
                        max_iters: int = 30, tol: float = 1e-7, lam0: float = 1e-3, only: np.ndarray | None = None):
    """Minimise ``sum(r(d)**2)`` for every pixel independently, all pixels at once.

    Marquardt's scaled damping for a scalar unknown: step = -(J.r) / ((J.J)(1 + lambda)); a step that
    does not raise a pixel's cost is taken and its lambda divided by 10, otherwise lambda is multiplied by
    10.  Distances stay inside ``[d_min, d_max]`` (metres).  A pixel stops when its accepted step is below
    ``tol`` metres, its cost stops decreasing (relative change <= 1e-12), or it has no information.
    Only the per-pixel sums (cost, J.r, J.J) are kept, so memory is O(N) whatever the residual count.
    ``only`` (optional (N,) bool) restricts the solve to those pixels; the others keep ``d0``.

    Returns:
        ``(d, iterations)``: (N,) refined distances and the number of iterations run.
    """
    d = np.clip(np.asarray(d0, dtype=np.float64).copy(), d_min, d_max)
    lam = np.full(d.shape, lam0)
    active = np.arange(d.size) if only is None else np.flatnonzero(only)
    cost, g, h = (np.zeros(d.size) for _ in range(3))
    cost[active], g[active], h[active] = problem.normal_terms(d[active], active)
    iterations = 0
    while active.size and iterations < max_iters:
        iterations += 1
        ga, ha, cost_prev, before = g[active], h[active], cost[active], d[active]
        step = -ga / np.maximum(ha * (1.0 + lam[active]), 1e-30)
        trial = np.clip(before + step, d_min, d_max)
        cost_new, g_new, h_new = problem.normal_terms(trial, active)
        better = cost_new <= cost_prev
        acc = active[better]
        d[acc], cost[acc], g[acc], h[acc] = trial[better], cost_new[better], g_new[better], h_new[better]
        lam[acc] = np.maximum(lam[acc] / 10.0, 1e-9)
        rej = active[~better]
        lam[rej] = lam[rej] * 10.0
        # done: accepted step below tol, cost no longer decreasing (flat stretches of the colour cost),
        # damping exploded, or no information (all weights 0)
        stalled = better & (cost_prev - cost_new <= 1e-12 * np.maximum(cost_prev, 1e-30))
        done = (better & (np.abs(trial - before) < tol)) | stalled | (lam[active] > 1e8) | (ha < 1e-30)
        active = active[~done]
    return d, iterations


def _normal_terms(r: np.ndarray, J: np.ndarray):
    """Per-pixel cost sum(r^2), gradient sum(J r) and Gauss-Newton Hessian sum(J^2), each (M,)."""
    return np.einsum("ij,ij->i", r, r), np.einsum("ij,ij->i", J, r), np.einsum("ij,ij->i", J, J)

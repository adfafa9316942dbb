"""Operations on equirectangular images and on rotations that every layer shares (pure numpy + OpenCV).

An equirect image's columns are periodic (the left and right edges are the same meridian); its rows are not (the
top and bottom rows are the poles).  The functions here pad, filter and differentiate such images with the columns
wrapped and the rows handled as the caller says, convert colour to grey, turn axis-angle rotations into matrices
and weight residuals robustly (Tukey's biweight over a MAD scale).

* Padding and filters: :func:`periodic_pad` (columns from the opposite edge, rows ``"edge"``, ``"reflect"``,
  ``"symmetric"`` or ``"constant"``), :func:`periodic_filter` (any filter on the padded image, cropped back),
  :func:`periodic_gaussian_blur`, :func:`periodic_box_filter`, :func:`local_contrast` (the standard
  deviation in a Gaussian window), :func:`dilate_wrapped` (a bool map grown by a square, columns wrapped).
* Differences: :func:`central_differences` (columns periodic), :func:`sobel_gradient` (3x3 Sobel per pixel,
  columns periodic, rows replicated).
* Grey: :func:`grey` (OpenCV's 8-bit BT.601, float BT.601, the channel mean or BT.709 luminance of linear light).
* Rotations: :func:`axis_angle_matrix`, :func:`rotation_vector_matrix` (Rodrigues), :func:`vector_angle_deg`,
  :func:`rotation_angle_deg`.
* Robust fits: :func:`robust_scale` (1.4826 MAD) and :func:`tukey_weights`, the reweighting step of every
  Tukey-reweighted least-squares fit.

Shapes: images are (H, W) or (H, W, C) with W columns of longitude; angles are radians unless a name says degrees.
"""

from __future__ import annotations

import math

import cv2
import numpy as np

__all__ = ["ROW_MODES", "periodic_pad", "periodic_filter", "periodic_gaussian_blur", "periodic_box_filter",
           "local_contrast", "central_differences", "sobel_gradient", "GREY_MODES", "grey", "axis_angle_matrix",
           "rotation_vector_matrix", "vector_angle_deg", "rotation_angle_deg", "MAD_TO_SIGMA", "robust_scale",
           "tukey_weights", "dilate_wrapped"]

ROW_MODES = ("edge", "reflect", "symmetric", "constant")
"""How :func:`periodic_pad` fills the rows beyond the poles (``numpy.pad`` modes): ``edge`` repeats the first/last
row, ``reflect`` mirrors about it (the edge row not repeated), ``symmetric`` mirrors with it repeated, ``constant``
fills zeros."""


def periodic_pad(x: np.ndarray, cols: int, rows: int = 0, row_mode: str = "edge") -> np.ndarray:
    """Pad an equirect image with columns wrapped in longitude and rows filled by ``row_mode``.

    Args:
        x: (H, W) or (H, W, C) array, any dtype.
        cols: columns added on each side, copied from the opposite edge (column ``-k`` is column ``W - k``;
            more than W columns wrap again).
        rows: rows added at the top and the bottom.
        row_mode: one of :data:`ROW_MODES`.
    Returns:
        (H + 2 rows, W + 2 cols[, C]) C-contiguous array of ``x``'s dtype; ``x`` itself when ``cols`` and
        ``rows`` are both 0.
    """
    if cols < 0 or rows < 0:
        raise ValueError(f"padding must be >= 0, got cols={cols}, rows={rows}")
    if row_mode not in ROW_MODES:
        raise ValueError(f"unknown row mode {row_mode!r} (known: {', '.join(ROW_MODES)})")
    if cols == 0 and rows == 0:
        return x
    out = np.asarray(x)
    if rows:
        out = np.pad(out, ((rows, rows),) + ((0, 0),) * (out.ndim - 1), mode=row_mode)
    if cols:
        w = out.shape[1]
        if cols <= w:
            out = np.concatenate([out[:, w - cols:], out, out[:, :cols]], axis=1)
        else:
            out = np.take(out, np.arange(-cols, w + cols) % w, axis=1)
    return np.ascontiguousarray(out)


def periodic_filter(x: np.ndarray, cols: int, filt, rows: int = 0, row_mode: str = "edge") -> np.ndarray:
    """``filt`` applied to ``x`` padded by :func:`periodic_pad`, cropped back to ``x``'s size.

    Args:
        x: (H, W) or (H, W, C) array.
        cols, rows, row_mode: the padding (:func:`periodic_pad`); ``cols`` at least the filter's radius makes the
            result periodic in longitude.
        filt: ``filt(padded) -> array`` of the padded array's (H + 2 rows, W + 2 cols) leading shape.
    Returns:
        (H, W, ...) C-contiguous: ``filt(padded)[rows:rows + H, cols:cols + W]``.
    """
    h, w = x.shape[:2]
    out = filt(periodic_pad(x, cols, rows, row_mode))
    return np.ascontiguousarray(out[rows:rows + h, cols:cols + w])


def periodic_gaussian_blur(x: np.ndarray, sigma_px: float, *, cols: int | None = None, rows: int = 0,
                           row_mode: str = "edge", ksize: int = 0, border: int = cv2.BORDER_REFLECT) -> np.ndarray:
    """Gaussian blur of an equirect image, periodic in longitude.

    ``cv2.GaussianBlur`` of the image padded by :func:`periodic_pad`, cropped back.  OpenCV's own border
    (``border``) fills what lies beyond the padding: the rows when ``rows`` is 0, and the columns the kernel reaches
    past ``cols`` (OpenCV's kernel radius for float images is about 4 sigma).

    Args:
        x: (H, W) or (H, W, C) float32 or float64 (or uint8) array.
        sigma_px: the Gaussian's standard deviation, pixels; <= 0 returns ``x`` itself.
        cols: columns wrapped on each side (default ``ceil(3 sigma)``).
        rows, row_mode: rows padded at each pole and how (:func:`periodic_pad`; default none).
        ksize: the kernel's side, pixels (odd); 0 lets OpenCV choose it from ``sigma_px``.
        border: the OpenCV border type beyond the padding.
    Returns:
        (H, W[, C]) C-contiguous blurred array, ``x``'s dtype.
    """
    if sigma_px <= 0:
        return x
    pad = int(np.ceil(3 * sigma_px)) if cols is None else int(cols)
    return periodic_filter(x, pad, lambda p: cv2.GaussianBlur(p, (ksize, ksize), sigma_px, borderType=border),
                           rows, row_mode)


def local_contrast(gray: np.ndarray, sigma_px: float) -> np.ndarray:
    """Local standard deviation of intensity in a Gaussian window (wrapping in longitude; rows as OpenCV's reflect
    border).

    Args:
        gray: (H, W) float32 gray, 0-255.
        sigma_px: window sigma, pixels (> 0).
    Returns:
        (H, W) float32 contrast, gray levels.
    """
    pad = int(np.ceil(3 * sigma_px))
    # float64 and centred (on the mean of the padded image): E[x^2] - E[x]^2 without cancellation
    g = gray.astype(np.float64) - periodic_pad(gray, pad).astype(np.float64).mean()
    mean = periodic_gaussian_blur(g, sigma_px, cols=pad)
    var = periodic_gaussian_blur(g * g, sigma_px, cols=pad) - mean * mean
    return np.sqrt(np.maximum(var, 0.0)).astype(np.float32)


def periodic_box_filter(x: np.ndarray, window: int, *, normalize: bool = True, rows: int = 0,
                        row_mode: str = "edge", border: int = cv2.BORDER_REFLECT_101) -> np.ndarray:
    """Box filter of side ``window`` of an equirect image, periodic in longitude.

    ``cv2.boxFilter`` of the image padded by ``window // 2`` wrapped columns (and ``rows`` rows), cropped back.

    Args:
        x: (H, W) or (H, W, C) float32 array.
        window: the box's side, pixels (odd).
        normalize: the mean over the box (True) or its sum (False).
        rows, row_mode: rows padded at each pole and how (:func:`periodic_pad`; default none: ``border`` fills them).
        border: the OpenCV border type beyond the padding.
    Returns:
        (H, W[, C]) C-contiguous, ``x``'s dtype: per pixel the box's mean (or sum) of ``x``'s values.
    """
    return periodic_filter(x, window // 2, lambda p: cv2.boxFilter(p, -1, (window, window), normalize=normalize,
                                                                   borderType=border), rows, row_mode)


def central_differences(x: np.ndarray, wrap: bool = True, step: int = 1,
                        scale: float = 0.5) -> tuple[np.ndarray, np.ndarray]:
    """Central differences along columns and rows.

    Args:
        x: (H, W) or (H, W, C) array (float).
        wrap: columns are periodic (equirect longitude); else the first and last ``step`` columns get 0.
        step: half the difference's baseline, pixels.
        scale: factor of the difference (0.5 with ``step`` 1: the derivative per pixel).
    Returns:
        ``(dx, dy)``, each of ``x``'s shape and dtype: ``scale * (x[:, j + step] - x[:, j - step])`` and
        ``scale * (x[i + step] - x[i - step])``; ``dy`` is 0 in the first and last ``step`` rows.
    """
    if wrap:
        dx = scale * (np.roll(x, -step, axis=1) - np.roll(x, step, axis=1))
    else:
        dx = np.zeros_like(x)
        dx[:, step:-step] = scale * (x[:, 2 * step:] - x[:, :-2 * step])
    dy = np.zeros_like(x)
    dy[step:-step] = scale * (x[2 * step:] - x[:-2 * step])
    return dx, dy


def sobel_gradient(x: np.ndarray, wrap: bool = True) -> tuple[np.ndarray, np.ndarray]:
    """The 3x3 Sobel derivatives of an image, divided by 8 (a ramp of slope ``s`` per pixel reads ``s``).

    Args:
        x: (H, W) float32 array.
        wrap: columns are periodic (one column wrapped on each side); else the edge columns are replicated.
            Rows are replicated at the poles.
    Returns:
        ``(dx, dy)``: (H, W) float32 derivatives along columns and rows, ``x``'s units per pixel.
    """
    pad = 1 if wrap else 0
    p = periodic_pad(x, pad)
    w = x.shape[1]
    dx = cv2.Sobel(p, cv2.CV_32F, 1, 0, ksize=3, borderType=cv2.BORDER_REPLICATE)[:, pad:pad + w]
    dy = cv2.Sobel(p, cv2.CV_32F, 0, 1, ksize=3, borderType=cv2.BORDER_REPLICATE)[:, pad:pad + w]
    return dx / 8.0, dy / 8.0


GREY_MODES = ("opencv", "bt601", "mean", "bt709")
"""How :func:`grey` turns colour into grey."""
_BT601 = np.array([0.299, 0.587, 0.114], dtype=np.float32)
_BT709 = np.array([0.2126, 0.7152, 0.0722])


def grey(image: np.ndarray, mode: str = "opencv") -> np.ndarray:
    """The grey image of a colour image.

    Args:
        image: (H, W, 3) RGB, or (H, W) already grey (returned as it is).
        mode: one of :data:`GREY_MODES`:

            * ``"opencv"``: OpenCV's RGB -> grey of a uint8 image (BT.601 weights 0.299, 0.587, 0.114 in fixed
              point, rounded): (H, W) uint8, grey levels 0..255;
            * ``"bt601"``: the same weights in float32 arithmetic, unrounded: (H, W) float32 (of 8-bit input,
              0..255);
            * ``"mean"``: the mean of the three channels in float32: (H, W) float32, the input's units;
            * ``"bt709"``: the BT.709 luminance weights 0.2126, 0.7152, 0.0722 in float64 (meant for linear light):
              (H, W) float64, the input's units.
    Returns:
        (H, W) grey image as above.
    """
    if mode not in GREY_MODES:
        raise ValueError(f"unknown grey mode {mode!r} (known: {', '.join(GREY_MODES)})")
    img = np.asarray(image)
    if img.ndim == 2:
        return img
    if mode == "opencv":
        return cv2.cvtColor(np.ascontiguousarray(img), cv2.COLOR_RGB2GRAY)
    if mode == "bt601":
        return np.asarray(img, dtype=np.float32) @ _BT601
    if mode == "mean":
        return np.asarray(img, dtype=np.float32).mean(axis=-1)
    return np.asarray(img, dtype=np.float64) @ _BT709


def _rodrigues(unit_axis: np.ndarray, angle_rad: float) -> np.ndarray:
    """``I + sin(a) K + (1 - cos(a)) K^2``, K the cross-product matrix of the unit axis."""
    a = unit_axis
    k = np.array([[0.0, -a[2], a[1]], [a[2], 0.0, -a[0]], [-a[1], a[0], 0.0]])
    return np.eye(3) + np.sin(angle_rad) * k + (1.0 - np.cos(angle_rad)) * (k @ k)


def axis_angle_matrix(axis, angle_rad: float) -> np.ndarray:
    """(3, 3) float64 rotation by ``angle_rad`` radians about ``axis``, right-handed.

    Args:
        axis: 0, 1 or 2 (the coordinate axis X, Y or Z: the matrix holds ``cos`` and ``+-sin`` of the angle, ones
            and zeros exactly), or a (3,) vector of any non-zero length (normalised; Rodrigues' formula).
        angle_rad: the angle, radians.
    Returns:
        (3, 3) float64 rotation matrix (applied to column vectors).
    """
    if isinstance(axis, int | np.integer):
        c, s = np.cos(angle_rad), np.sin(angle_rad)
        i, j = ((1, 2), (2, 0), (0, 1))[axis]
        m = np.eye(3)
        m[i, i], m[i, j], m[j, i], m[j, j] = c, -s, s, c
        return m
    a = np.asarray(axis, dtype=np.float64)
    return _rodrigues(a / np.linalg.norm(a), angle_rad)


def rotation_vector_matrix(omega) -> np.ndarray:
    """(3, 3) float64 rotation of the rotation vector ``omega`` (3,) (axis times angle, radians; Rodrigues); the
    identity for the zero vector."""
    omega = np.asarray(omega, np.float64)
    angle = float(np.linalg.norm(omega))
    if angle == 0.0:
        return np.eye(3)
    return _rodrigues(omega / angle, angle)


def vector_angle_deg(a, b) -> float:
    """The angle between two (3,) vectors (any non-zero lengths), degrees in [0, 180]."""
    cos = float(np.dot(a, b) / (np.linalg.norm(a) * np.linalg.norm(b)))
    return math.degrees(math.acos(min(1.0, max(-1.0, cos))))


def rotation_angle_deg(a: np.ndarray, b: np.ndarray) -> float:
    """The angle of the rotation that takes (3, 3) rotation ``a`` to ``b`` (of ``a.T @ b``), degrees in [0, 180]."""
    return math.degrees(math.acos(min(1.0, max(-1.0, (float(np.trace(a.T @ b)) - 1.0) / 2.0))))


MAD_TO_SIGMA = 1.4826
"""The median absolute deviation of normal samples times this is their standard deviation."""


def robust_scale(residuals: np.ndarray, floor: float = 0.0, floor_mode: str = "add") -> float:
    """The robust standard deviation of residuals: ``MAD_TO_SIGMA`` times their median absolute deviation from their
    median, kept off zero by ``floor``.

    Args:
        residuals: (N,) residuals, any units.
        floor: the least scale, the residuals' units.
        floor_mode: ``"add"`` (the scale plus ``floor``) or ``"max"`` (the larger of the two).
    Returns:
        The scale, the residuals' units.
    """
    r = np.asarray(residuals)
    mad = MAD_TO_SIGMA * float(np.median(np.abs(r - np.median(r))))
    if floor_mode == "add":
        return mad + floor
    if floor_mode == "max":
        return max(mad, floor)
    raise ValueError(f"floor_mode must be 'add' or 'max', got {floor_mode!r}")


def tukey_weights(residuals: np.ndarray, c: float, sigma: float) -> np.ndarray:
    """Tukey's biweight of residuals: ``(1 - u^2)^2`` for ``|u| < 1`` and 0 beyond, ``u = r / (c sigma)``.

    Args:
        residuals: (N,) residuals.
        c: Tukey's constant, in units of ``sigma`` (4.685: 95 % efficiency on normal residuals).
        sigma: the residuals' scale (:func:`robust_scale`), their units.
    Returns:
        (N,) weights in [0, 1], the residuals' float dtype.
    """
    u = residuals / (c * sigma)
    return np.where(np.abs(u) < 1.0, (1.0 - u * u) ** 2, 0.0)


def dilate_wrapped(mask, radius_px: int) -> np.ndarray:
    """Dilate a bool map by a (2r+1) x (2r+1) square, wrapping around in longitude (columns), not in rows.

    Args:
        mask: (H, W) bool.
        radius_px: r >= 0, pixels (Chebyshev radius).
    Returns:
        (H, W) bool: True wherever a True pixel of ``mask`` lies within ``r`` rows and ``r`` columns
        (columns counted modulo W).
    """
    mask = np.asarray(mask, dtype=bool)
    r = int(radius_px)
    if r < 0:
        raise ValueError(f"radius_px must be >= 0, got {radius_px}")
    if r == 0 or not mask.any():
        return mask.copy()
    kernel = np.ones((2 * r + 1, 2 * r + 1), np.uint8)

    def dilate(padded):
        return cv2.dilate(padded, kernel, borderType=cv2.BORDER_CONSTANT, borderValue=0)

    return periodic_filter(mask.astype(np.uint8), r, dilate, r, "constant").astype(bool)

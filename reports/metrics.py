"""Error metrics of a predicted distance map against ground truth (pure numpy + OpenCV, no Blender).

Scoring rules (used by every function here; formulas and thresholds in ``docs/metrics.md``):

* Only pixels whose **ground truth** is finite and positive are scored ("scored pixels"); pixels whose
  ray hits nothing (ground truth ``+inf``) are ignored.
* A **prediction** that is NaN, +/-inf or ``<= 0`` at a scored pixel is *invalid*.  It is **not dropped**:
  it is scored as if the prediction were 0, i.e. with absolute error ``|err| = gt``, relative error 1, and
  it fails every ratio threshold (``delta*``) and counts as bad at every bad-pixel threshold.  Every variant
  is therefore scored on exactly the same pixel set, and a method cannot improve its numbers by refusing to
  answer on hard pixels; ``coverage`` reports how often it refused.
* ``valid_px`` is the number of scored pixels (finite ground truth), i.e. the denominator of every
  share and mean below; it is the same for every variant of one frame.

Distances are metres, angles degrees (bin edges only), images ``(H, W, 3)`` uint8 RGB.  Maps are (H, W)
equirectangular images whose left and right edges are the same meridian: neighbourhoods wrap around in
longitude (columns) and not in latitude (rows).
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass

import numpy as np

from reconstruction.camera.equirect import baseline_cosine, pixel_to_lonlat
from reconstruction.camera.image_ops import dilate_wrapped, grey, sobel_gradient

__all__ = [
    "ANGLE_EDGES_DEG",
    "DISTANCE_EDGES_M",
    "TEXTURE_EDGES",
    "DELTA1_RATIO",
    "OUTLIER_FRACTION",
    "PERCENTILES",
    "BAD_FRACTIONS",
    "DELTA_RATIOS",
    "EDGE_LOG_JUMP",
    "BOUNDARY_TOLERANCE_PX",
    "AUSE_STEPS",
    "SOLID_ANGLE_KEYS",
    "SUMMARY_KEYS",
    "scored_pixels",
    "solid_angle_weights",
    "pixel_solid_angle_sr",
    "score_pixels",
    "summary",
    "pooled_summary",
    "ScoredMaps",
    "sparsification_curves",
    "pooled_sparsification_curves",
    "ause",
    "depth_edges",
    "breakdown",
    "angle_to_baseline_deg",
    "texture_magnitude",
    "binned_errors",
]

#: 10-degree bins of the angle between a pixel's bearing and a baseline direction, degrees, 0..180.
ANGLE_EDGES_DEG = np.arange(0.0, 181.0, 10.0)
#: bins of the true distance, metres; the last bin is open (8 m and beyond).
DISTANCE_EDGES_M = np.array([0.0, 1.0, 2.0, 3.0, 5.0, 8.0, np.inf])
#: fixed, roughly logarithmic bins of the Sobel gradient magnitude of C's grey image, in 8-bit grey levels
#: per pixel (see :func:`texture_magnitude`); fixed (not per-frame quantiles) so frames can be pooled.
TEXTURE_EDGES = np.array([0.0, 1.0, 2.0, 4.0, 8.0, 16.0, 32.0, np.inf])
#: ``delta1`` threshold on ``max(pred/gt, gt/pred)`` (strictly below counts as good).
DELTA1_RATIO = 1.25
#: a pixel is an outlier if ``|pred - gt| > OUTLIER_FRACTION * gt``.
OUTLIER_FRACTION = 0.10
#: percentiles of the absolute error reported as ``p<q>_m`` (numpy's default linear interpolation).
PERCENTILES = (50, 90, 95, 99)
#: bad-pixel rates: key -> fraction f; a pixel is bad if ``|pred - gt| > f * gt`` (``outlier_rate`` is f = 0.10).
BAD_FRACTIONS = {"bad_1pct": 0.01, "bad_2pct": 0.02, "bad_5pct": 0.05}
#: tight ratio accuracies: key -> r; share of pixels with ``max(pred/gt, gt/pred) < r`` (``delta1`` is 1.25).
DELTA_RATIOS = {"delta105": 1.05, "delta110": 1.10}
#: a depth edge separates two 4-neighbours whose distances differ by more than this in natural log
#: (ln 1.1: the farther one is more than 10 % farther), see :func:`depth_edges`.
EDGE_LOG_JUMP = math.log(1.10)
#: boundary precision/recall: an edge pixel matches if the other map has an edge within this many pixels
#: (Chebyshev distance, columns wrapping around).
BOUNDARY_TOLERANCE_PX = 1
#: removal fractions of the sparsification curves: ``k / AUSE_STEPS`` for ``k = 0 .. AUSE_STEPS``.
AUSE_STEPS = 20
#: the main metrics again, each pixel weighted by its solid angle (cos latitude, Pano3D), then ``valid_sr``, the
#: solid angle of the scored pixels in steradians (the weight that pools the weighted metrics over frames).
SOLID_ANGLE_KEYS = ("mae_sw_m", "rmse_sw_m", "median_sw_m", "absrel_sw", "delta1_sw", "outlier_rate_sw", "valid_sr")
#: every key of :func:`summary` and :func:`pooled_summary`, in order; ``ause`` follows when a confidence is given.
SUMMARY_KEYS = ("mae_m", "rmse_m", "median_m", "absrel", "delta1", "outlier_rate", "valid_px",
                *(f"p{q}_m" for q in PERCENTILES), *BAD_FRACTIONS, *DELTA_RATIOS, "coverage",
                "boundary_precision", "boundary_recall", "seam_m", *SOLID_ANGLE_KEYS)


def solid_angle_weights(height: int) -> np.ndarray:
    """Relative solid angle of each row of an equirect image: ``cos(latitude)`` of the row's pixel centres.

    Args:
        height: H, rows (latitude of row ``v``: ``pi/2 - pi (v + 0.5) / H``).
    Returns:
        (H,) float64 in (0, 1]: 1 at the equator, -> 0 at the poles.
    """
    _, lat = pixel_to_lonlat(np.zeros(height), np.arange(height), 2 * height, height)
    return np.cos(lat)


def pixel_solid_angle_sr(width: int, height: int) -> float:
    """Steradians per unit weight of :func:`solid_angle_weights`: a pixel covers ``w * (2 pi / W) (pi / H)`` sr
    (the cell's area on the unit sphere at its centre's latitude; over the whole image the weights sum to
    about 4 pi sr)."""
    return (2.0 * np.pi / width) * (np.pi / height)


def _weighted_median(values: np.ndarray, weights: np.ndarray) -> float:
    """The weighted median of ``values`` (N,) with positive ``weights`` (N,): the smallest value whose
    cumulative weight (values sorted ascending) reaches half the total weight (exactly half: the mean of that
    value and the next), so equal weights give numpy's median."""
    order = np.argsort(values, kind="stable")
    v, cw = values[order], np.cumsum(weights[order])
    half = 0.5 * cw[-1]
    i = int(np.searchsorted(cw, half, side="left"))
    i = min(i, v.size - 1)
    if i + 1 < v.size and abs(cw[i] - half) <= 1e-12 * cw[-1]:
        return float(0.5 * (v[i] + v[i + 1]))
    return float(v[i])


def scored_pixels(gt) -> np.ndarray:
    """The scored pixels of a ground-truth map: (H, W) bool, True where ``gt`` is finite and positive."""
    gt = np.asarray(gt)
    return np.isfinite(gt) & (gt > 0)


def score_pixels(pred, gt):
    """Per-pixel absolute error under the scoring rules of this module.

    Args:
        pred: (H, W) predicted distance, metres (NaN / inf / <= 0 = invalid).
        gt: (H, W) true distance, metres (+inf = no surface, not scored).
    Returns:
        ``(mask, abs_err, valid_pred)``: ``mask`` (H, W) bool, scored pixels (finite positive ``gt``);
        ``abs_err`` (N,) float64 metres for the ``N = mask.sum()`` scored pixels in row-major order, equal
        to ``gt`` where the prediction is invalid; ``valid_pred`` (N,) bool, prediction valid.
    Raises:
        ValueError: if the shapes differ or are not 2-D.
    """
    pred = np.asarray(pred, dtype=np.float64)
    gt = np.asarray(gt, dtype=np.float64)
    if pred.ndim != 2 or pred.shape != gt.shape:
        raise ValueError(f"pred and gt must be 2-D arrays of the same shape, got {pred.shape} and {gt.shape}")
    mask = scored_pixels(gt)
    p, g = pred[mask], gt[mask]
    valid = np.isfinite(p) & (p > 0)
    abs_err = np.where(valid, np.abs(np.where(valid, p, 0.0) - g), g)
    return mask, abs_err, valid


def _check_maps(pred, gt, confidence=None, mask=None):
    """float64 copies of the maps after checking their shapes (ValueError naming both shapes otherwise)."""
    pred = np.asarray(pred, dtype=np.float64)
    gt = np.asarray(gt, dtype=np.float64)
    if pred.ndim != 2 or pred.shape != gt.shape:
        raise ValueError(f"pred and gt must be 2-D arrays of the same shape, got {pred.shape} and {gt.shape}")
    if confidence is not None:
        confidence = np.asarray(confidence, dtype=np.float64)
        if confidence.shape != gt.shape:
            raise ValueError(f"confidence and gt must have the same shape, got {confidence.shape} and {gt.shape}")
    if mask is not None:
        mask = np.asarray(mask)
        if mask.shape != gt.shape or mask.dtype != bool:
            raise ValueError(f"mask must be a bool array of the shape of gt, got {mask.dtype} {mask.shape} "
                             f"and {gt.shape}")
    return pred, gt, confidence, mask


def depth_edges(distance, log_jump: float = EDGE_LOG_JUMP) -> np.ndarray:
    """Depth-edge pixels of a distance map: both pixels of every 4-neighbour pair with a large log jump.

    A pair ``(p, q)`` of horizontal (column ``u`` and ``(u + 1) mod W``: the seam is an ordinary neighbour) or
    vertical (rows ``v`` and ``v + 1``, no wrap) neighbours jumps when ``|ln d_p - ln d_q| > log_jump``.
    Values that are NaN, ``-inf`` or ``<= 0`` are unknown and never jump; ``+inf`` (no surface) is
    infinitely far, so it jumps against every finite neighbour but not against another ``+inf``.

    Args:
        distance: (H, W) distance map, metres.
        log_jump: threshold on the natural-log difference (unitless; ln 1.1 by default).
    Returns:
        (H, W) bool, True on both pixels of every jumping pair.
    """
    d = np.asarray(distance, dtype=np.float64)
    with np.errstate(divide="ignore", invalid="ignore"):
        logd = np.log(np.where(d > 0, d, np.nan))
        horiz = np.abs(logd - np.roll(logd, -1, axis=1)) > log_jump  # pair (u, u + 1 mod W) stored at u
        vert = np.abs(logd[:-1] - logd[1:]) > log_jump  # pair (v, v + 1) stored at v
    edges = horiz | np.roll(horiz, 1, axis=1)
    edges[:-1] |= vert
    edges[1:] |= vert
    return edges


@dataclass
class _Pixels:
    """The per-pixel and per-row ingredients of the summary metrics for one frame (and region).

    Arrays over the N selected scored pixels, row-major: ``err`` absolute error (metres, = gt where invalid),
    ``gt`` true distance (metres), ``pred`` prediction with invalid values replaced by 1.0 (metres),
    ``valid`` prediction valid, ``conf`` confidence or None, ``weight`` solid-angle weight (cos latitude),
    ``sr`` steradians per unit weight.  Counts of edge pixels: ``pred_edges`` /
    ``pred_hits`` (predicted edge pixels, and those with a true edge within the tolerance), ``gt_edges`` /
    ``gt_hits`` likewise; ``seam`` (M,) per-row seam disagreement, metres.
    """

    err: np.ndarray
    gt: np.ndarray
    pred: np.ndarray
    valid: np.ndarray
    conf: np.ndarray | None
    pred_edges: int
    pred_hits: int
    gt_edges: int
    gt_hits: int
    seam: np.ndarray
    weight: np.ndarray | None = None
    sr: float = float("nan")


class ScoredMaps:
    """One prediction scored against its ground truth once, to be summarised over any number of masks.

    ``ScoredMaps(pred, gt, confidence).summary(mask)`` equals ``summary(pred, gt, confidence, mask)``; use it to
    summarise many regions of one frame without recomputing the edge maps.

    Args:
        pred: (H, W) predicted distance, metres (NaN / inf / <= 0 = invalid).
        gt: (H, W) true distance, metres (+inf = no surface, not scored).
        confidence: optional (H, W), higher = more trustworthy (any unit; NaN = least trustworthy).
    Attributes (all (H, W) unless noted): ``scored`` bool, finite positive gt; ``err`` float64 absolute error,
    metres (NaN off the scored pixels); ``valid`` bool, prediction valid; ``pred`` / ``gt`` float64 metres
    (invalid predictions NaN); ``pred_edges`` / ``gt_edges`` bool (:func:`depth_edges`); ``near_pred_edge`` /
    ``near_gt_edge`` bool, within :data:`BOUNDARY_TOLERANCE_PX` of those; ``seam_rows`` (H,) bool and ``seam``
    (H,) float64 metres, the seam disagreement per row (used where ``seam_rows``); ``confidence`` or None.
    Raises:
        ValueError: shapes differ (the message names both) or are not 2-D.
    """

    def __init__(self, pred, gt, confidence=None):
        pred, gt, confidence, _ = _check_maps(pred, gt, confidence)
        self.shape = gt.shape
        self.confidence = confidence
        self.scored, err, valid = score_pixels(pred, gt)
        self.err = np.full(gt.shape, np.nan)
        self.err[self.scored] = err
        self.valid = np.isfinite(pred) & (pred > 0)
        self.gt = gt
        self.pred = np.where(self.valid, pred, np.nan)
        # depth boundaries: edges of the prediction (invalid values are unknown) vs edges of the truth
        self.pred_edges = depth_edges(self.pred)
        self.gt_edges = depth_edges(gt)
        self.near_pred_edge = dilate_wrapped(self.pred_edges, BOUNDARY_TOLERANCE_PX)
        self.near_gt_edge = dilate_wrapped(self.gt_edges, BOUNDARY_TOLERANCE_PX)
        # seam: the prediction's jump across the left/right image edge minus the truth's own jump there
        self.seam_rows = self.scored[:, 0] & self.scored[:, -1] & self.valid[:, 0] & self.valid[:, -1]
        with np.errstate(invalid="ignore"):
            self.seam = np.abs((self.pred[:, 0] - self.pred[:, -1]) - (gt[:, 0] - gt[:, -1]))

    def pixels(self, mask=None) -> _Pixels:
        """The ingredients of the metrics over the scored pixels inside ``mask`` ((H, W) bool, None = all)."""
        if mask is not None:
            mask = np.asarray(mask)
            if mask.shape != self.shape or mask.dtype != bool:
                raise ValueError(f"mask must be a bool array of the shape of gt, got {mask.dtype} {mask.shape} "
                                 f"and {self.shape}")
        sel = self.scored if mask is None else self.scored & mask
        valid = self.valid[sel]
        pe, ge = self.pred_edges & sel, self.gt_edges & sel
        rows = self.seam_rows & sel[:, 0] & sel[:, -1]
        return _Pixels(err=self.err[sel], gt=self.gt[sel], pred=np.where(valid, self.pred[sel], 1.0), valid=valid,
                       conf=None if self.confidence is None else self.confidence[sel],
                       pred_edges=int(pe.sum()), pred_hits=int((pe & self.near_gt_edge).sum()),
                       gt_edges=int(ge.sum()), gt_hits=int((ge & self.near_pred_edge).sum()),
                       seam=self.seam[rows],
                       weight=np.broadcast_to(solid_angle_weights(self.shape[0])[:, None], self.shape)[sel],
                       sr=pixel_solid_angle_sr(self.shape[1], self.shape[0]))

    def summary(self, mask=None) -> dict:
        """:func:`summary` over the scored pixels inside ``mask`` ((H, W) bool, None = all scored pixels)."""
        return _summarise([self.pixels(mask)])


def _ratio(num: int, den: int) -> float:
    return num / den if den > 0 else float("nan")


def _sparsification(err: np.ndarray, conf: np.ndarray, steps: int):
    """Sparsification curve of ``err`` ordered by ``conf`` and its oracle; see :func:`sparsification_curves`."""
    steps = int(steps)
    if steps < 1:
        raise ValueError(f"steps must be >= 1, got {steps}")
    n = err.size
    fractions = np.arange(steps + 1) / steps
    if n == 0:
        nan = np.full(steps + 1, np.nan)
        return fractions, nan, nan.copy()
    kept = np.maximum(n - (np.arange(steps + 1) * n) // steps, 1)  # pixels kept after removing floor(f N)
    # oracle: keep the `kept` smallest errors
    oracle_sum = np.concatenate([[0.0], np.cumsum(np.sort(err))])
    oracle = oracle_sum[kept] / kept
    # method: keep the most confident pixels (NaN confidence = least confident); within a run of equal
    # confidences the pixels kept are a random subset, so such a run contributes its mean error (expectation)
    c = np.where(np.isnan(conf), -np.inf, conf)
    order = np.argsort(-c, kind="stable")
    c, e = c[order], err[order]
    csum = np.concatenate([[0.0], np.cumsum(e)])
    starts_here = np.concatenate([[True], c[1:] != c[:-1]])
    starts = np.flatnonzero(starts_here)
    ends = np.append(starts[1:], n)
    group = (np.cumsum(starts_here) - 1)[kept - 1]  # tie run holding the last kept pixel
    s0, s1 = starts[group], ends[group]
    partial = csum[s0] + (kept - s0) * (csum[s1] - csum[s0]) / (s1 - s0)
    curve = np.where(kept == s1, csum[kept], partial) / kept
    return fractions, curve, oracle


def ause(fractions, curve, oracle) -> float:
    """Area under the sparsification error curve minus the oracle's: ``trapezoid(curve - oracle, fractions)``.

    Args:
        fractions: (K,) removal fractions, increasing, 0..1.
        curve, oracle: (K,) MAE of the kept pixels (method / oracle), metres.
    Returns:
        The area, metres (NaN if a curve value is NaN).
    """
    f = np.asarray(fractions, dtype=np.float64)
    d = np.asarray(curve, dtype=np.float64) - np.asarray(oracle, dtype=np.float64)
    return float(np.sum(0.5 * (d[1:] + d[:-1]) * np.diff(f)))


def _summarise(parts: Sequence[_Pixels]) -> dict:
    """Summary metrics over the union of the pixels (and seam rows) of ``parts``; see :func:`summary`."""
    err = np.concatenate([p.err for p in parts])
    n = int(err.size)
    nan = float("nan")
    confs = [p.conf for p in parts]
    if any(c is None for c in confs) and not all(c is None for c in confs):
        raise ValueError("either every frame has a confidence map or none has")
    if n == 0:
        out = {k: nan for k in SUMMARY_KEYS}
        out["valid_px"] = 0
        out["valid_sr"] = 0.0
        if confs[0] is not None:
            out["ause"] = nan
        return out
    g = np.concatenate([p.gt for p in parts])
    pred = np.concatenate([p.pred for p in parts])
    valid = np.concatenate([p.valid for p in parts])
    ratio = np.maximum(pred / g, g / pred)
    out = {
        "mae_m": float(err.mean()),
        "rmse_m": float(np.sqrt(np.mean(err * err))),
        "median_m": float(np.median(err)),
        "absrel": float(np.mean(err / g)),
        "delta1": float(np.mean(valid & (ratio < DELTA1_RATIO))),
        "outlier_rate": float(np.mean(err > OUTLIER_FRACTION * g)),
        "valid_px": n,
    }
    out.update({f"p{q}_m": float(v) for q, v in zip(PERCENTILES, np.percentile(err, PERCENTILES), strict=True)})
    out.update({k: float(np.mean(err > f * g)) for k, f in BAD_FRACTIONS.items()})
    out.update({k: float(np.mean(valid & (ratio < r))) for k, r in DELTA_RATIOS.items()})
    out["coverage"] = float(valid.mean())
    out["boundary_precision"] = _ratio(sum(p.pred_hits for p in parts), sum(p.pred_edges for p in parts))
    out["boundary_recall"] = _ratio(sum(p.gt_hits for p in parts), sum(p.gt_edges for p in parts))
    seam = np.concatenate([p.seam for p in parts])
    out["seam_m"] = float(seam.mean()) if seam.size else nan
    out.update(_solid_angle_weighted(parts, err, g, valid, ratio))
    if confs[0] is not None:
        out["ause"] = ause(*_sparsification(err, np.concatenate(confs), AUSE_STEPS))
    return out


def _solid_angle_weighted(parts: Sequence[_Pixels], err, g, valid, ratio) -> dict:
    """The :data:`SOLID_ANGLE_KEYS` over the pixels of ``parts`` (``err, g, valid, ratio``: their concatenated
    arrays); each pixel weighs its solid angle in steradians (so frames of different sizes pool correctly)."""
    w = np.concatenate([p.weight * p.sr for p in parts])
    total = float(w.sum())
    out = {"mae_sw_m": float(np.sum(w * err) / total),
           "rmse_sw_m": float(np.sqrt(np.sum(w * err * err) / total)),
           "median_sw_m": _weighted_median(err, w),
           "absrel_sw": float(np.sum(w * err / g) / total),
           "delta1_sw": float(np.sum(w * (valid & (ratio < DELTA1_RATIO))) / total),
           "outlier_rate_sw": float(np.sum(w * (err > OUTLIER_FRACTION * g)) / total),
           "valid_sr": total}
    return out


def summary(pred, gt, confidence=None, mask=None) -> dict:
    """Summary metrics of one predicted distance map (definitions and formulas: ``docs/metrics.md``).

    Args:
        pred: (H, W) predicted distance of camera C, metres (NaN / inf / <= 0 = invalid).
        gt: (H, W) ground-truth distance, metres, +inf where nothing is hit.
        confidence: optional (H, W) confidence of ``pred``, higher = more trustworthy (NaN = least); only
            ``ause`` uses it.
        mask: optional (H, W) bool region; the metrics are then over the scored pixels inside it (edge pixels
            and seam rows inside it for the boundary and seam metrics).  None = every scored pixel.
    Returns:
        dict with the keys :data:`SUMMARY_KEYS` in that order, plus ``ause`` when ``confidence`` is given, all
        over the scored pixels (invalid predictions scored as described in the module doc):

        * ``mae_m``: mean ``|pred - gt|``, metres;
        * ``rmse_m``: root mean squared error, metres;
        * ``median_m``: median ``|pred - gt|``, metres;
        * ``absrel``: mean ``|pred - gt| / gt`` (unitless);
        * ``delta1``: share of pixels with ``max(pred/gt, gt/pred) < 1.25`` (0..1);
        * ``outlier_rate``: share of pixels with ``|pred - gt| > 0.1 * gt`` (0..1);
        * ``valid_px``: number of scored pixels (int);
        * ``p50_m p90_m p95_m p99_m``: percentiles of ``|pred - gt|`` (numpy's linear interpolation), metres;
        * ``bad_1pct bad_2pct bad_5pct``: share with ``|pred - gt| > f * gt``, f = 0.01, 0.02, 0.05;
        * ``delta105 delta110``: share with ``max(pred/gt, gt/pred) < 1.05`` / ``< 1.10``;
        * ``coverage``: share of scored pixels whose prediction is valid;
        * ``boundary_precision``: share of the prediction's depth-edge pixels (:func:`depth_edges`) that have a
          true depth edge within :data:`BOUNDARY_TOLERANCE_PX`; ``boundary_recall``: share of the true
          depth-edge pixels with a predicted edge that near (both over scored pixels; NaN with no edge pixel);
        * ``seam_m``: mean over the rows where both seam pixels are scored and validly predicted of
          ``|(pred[v, 0] - pred[v, W-1]) - (gt[v, 0] - gt[v, W-1])|``, metres (NaN with no such row);
        * ``mae_sw_m rmse_sw_m median_sw_m absrel_sw delta1_sw outlier_rate_sw``: the first six metrics with
          every pixel weighted by its solid angle, ``cos(latitude)`` of its row (:func:`solid_angle_weights`;
          Pano3D's recommendation: equirect pixels near the poles cover less of the sphere); the median is the
          weighted median; ``valid_sr``: the solid angle of the scored pixels, steradians;
        * ``ause``: area under the sparsification error curve (MAE, :data:`AUSE_STEPS` steps) minus the
          oracle's, metres (:func:`sparsification_curves`); only when ``confidence`` is given.

        With no scored pixel at all every metric is NaN and ``valid_px`` is 0.
    Raises:
        ValueError: the shapes of ``pred``, ``gt`` (and ``confidence``, ``mask``) differ; the message names them.
    """
    pred, gt, confidence, mask = _check_maps(pred, gt, confidence, mask)
    return ScoredMaps(pred, gt, confidence).summary(mask)


def pooled_summary(items: Iterable[Sequence]) -> dict:
    """Summary metrics over the union of the scored pixels of several frames.

    Every pixel of every frame counts once: the pooled MAE is the pixel-weighted mean of the frames' MAEs,
    percentiles and shares are over all pixels together, boundary precision/recall pool the edge-pixel counts,
    ``seam_m`` pools the seam rows, and ``ause`` sorts all pixels of all frames by their confidence together.

    Args:
        items: sequence of ``(pred, gt)``, ``(pred, gt, confidence)`` or ``(pred, gt, confidence, mask)``
            tuples, one per frame (frames may differ in size); ``confidence`` and ``mask`` may be None.
    Returns:
        dict with the keys :data:`SUMMARY_KEYS` (definitions as :func:`summary`), plus ``ause`` when every item has
        a confidence; ``valid_px`` is the total.
    Raises:
        ValueError: shapes differ within an item, an item has not 2 to 4 entries, or some items have a
            confidence and others not.
    """
    parts = []
    for i, item in enumerate(items):
        if not 2 <= len(item) <= 4:
            raise ValueError(f"item {i} must be (pred, gt[, confidence[, mask]]), got {len(item)} entries")
        pred, gt, conf, mask = (*item, None, None)[:4]
        pred, gt, conf, mask = _check_maps(pred, gt, conf, mask)
        parts.append(ScoredMaps(pred, gt, conf).pixels(mask))
    if not parts:
        raise ValueError("pooled_summary needs at least one frame")
    return _summarise(parts)


def sparsification_curves(pred, gt, confidence, mask=None, steps: int = AUSE_STEPS):
    """Sparsification curve of the MAE (pixels removed least confident first) and its oracle, for plotting.

    For removal fractions ``f_k = k / steps`` (k = 0 .. steps) the ``n_k = max(N - floor(f_k N), 1)`` pixels
    kept are the most confident ones (method curve) or the ones with the smallest absolute error (oracle); the
    curve value is their MAE.  Pixels of equal confidence are removed in random order, in expectation: a run of
    ties that is only partly kept contributes its mean error per kept pixel.  NaN confidence counts as the
    lowest.  :func:`ause` of the three is ``summary``'s ``ause``.

    Args:
        pred, gt: (H, W) metres, scored as in :func:`summary` (invalid predictions have error = gt).
        confidence: (H, W), higher = more trustworthy.
        mask: optional (H, W) bool region.
        steps: number of removal steps (>= 1).
    Returns:
        ``(fractions, curve, oracle)``, each (steps + 1,): removal fraction (0..1), MAE of the kept pixels
        (metres), oracle MAE (metres); NaN curves when no pixel is scored.
    """
    if confidence is None:
        raise ValueError("sparsification_curves needs a confidence map")
    pred, gt, confidence, mask = _check_maps(pred, gt, confidence, mask)
    px = ScoredMaps(pred, gt, confidence).pixels(mask)
    return _sparsification(px.err, px.conf, steps)


def pooled_sparsification_curves(frames: Iterable[Sequence]) -> dict:
    """Sparsification curves of one method pooled over frames: the pixel-weighted mean of the per-frame curves.

    The area between the mean curve and the mean oracle (:func:`ause`) is the pixel-weighted mean of the
    frames' ``ause``: the area is linear in the curves.

    Args:
        frames: per frame ``(fractions, curve, oracle, n_px)``: :func:`sparsification_curves` of the frame (the
            same fractions for every frame) and its number of scored pixels (the weight; frames with none are
            left out).
    Returns:
        ``{"fractions", "curve", "oracle"}`` ((K,) each: removal fractions, MAE of the kept pixels in metres, the
        oracle's), ``"ause"`` (metres), ``"frames"`` (frames pooled) and ``"pixels"`` (scored pixels summed).
    Raises:
        ValueError: no frame with a scored pixel, or frames with different removal fractions.
    """
    fractions = None
    curve = oracle = 0.0
    weight = count = 0
    for f, c, o, n_px in frames:
        if not n_px:
            continue
        f = np.asarray(f, dtype=np.float64)
        if fractions is not None and not np.array_equal(f, fractions):
            raise ValueError("pooled_sparsification_curves: frames with different removal fractions")
        fractions = f
        curve = curve + n_px * np.asarray(c, dtype=np.float64)
        oracle = oracle + n_px * np.asarray(o, dtype=np.float64)
        weight += int(n_px)
        count += 1
    if not weight:
        raise ValueError("pooled_sparsification_curves needs at least one frame with a scored pixel")
    curve, oracle = curve / weight, oracle / weight
    return {"fractions": fractions, "curve": curve, "oracle": oracle, "ause": ause(fractions, curve, oracle),
            "frames": count, "pixels": weight}


# --------------------------------------------------------------------------------------------- breakdown


def angle_to_baseline_deg(frame, other: str) -> np.ndarray:
    """Angle between each pixel's bearing of camera C and the baseline C -> ``other``, degrees.

    Args:
        frame: a :class:`harness.data.frame.Frame`.
        other: "U" or "R"; the baseline direction is ``other.position - C.position`` (world frame).
    Returns:
        (H, W) float64 degrees in [0, 180]; 0 = looking straight at camera ``other`` (its epipole).
    """

    c = frame.cameras["C"]
    return np.degrees(np.arccos(baseline_cosine(frame.width, frame.height, c.rotation, c.position,
                                                frame.cameras[other].position, other)))


def texture_magnitude(image) -> np.ndarray:
    """Sobel gradient magnitude of an image's grey levels, in 8-bit grey levels per pixel.

    The grey image is OpenCV's RGB->grey (Rec. 601 weights on the sRGB-encoded values, 0..255).  The 3x3
    Sobel responses are divided by 8 so a linear ramp of slope ``s`` grey levels per pixel reads ``s``;
    columns wrap around (the equirect seam is not an edge), rows replicate at the poles.

    Args:
        image: (H, W, 3) uint8 RGB (or (H, W) grey).
    Returns:
        (H, W) float64 gradient magnitude, grey levels per pixel (>= 0).
    """
    return np.hypot(*sobel_gradient(grey(image).astype(np.float32))).astype(np.float64)


def binned_errors(values, abs_err, edges) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Mean and median of ``abs_err`` per bin of ``values`` (vectorised, no loop over bins).

    Args:
        values: (N,) the quantity binned (degrees, metres, ...); NaN values are dropped.
        abs_err: (N,) absolute errors, metres.
        edges: (K + 1,) increasing bin edges; bin ``k`` is ``[edges[k], edges[k+1])`` and the last bin also
            holds values equal to its upper edge; values outside ``[edges[0], edges[-1]]`` are dropped.
    Returns:
        ``(mae, median, count)``, each (K,): metres, metres, pixels; NaN means where ``count == 0``.
    """
    values = np.asarray(values, dtype=np.float64).ravel()
    abs_err = np.asarray(abs_err, dtype=np.float64).ravel()
    edges = np.asarray(edges, dtype=np.float64)
    k = edges.size - 1
    idx = np.searchsorted(edges, values, side="right") - 1
    idx = np.where(values == edges[-1], k - 1, idx)
    keep = (idx >= 0) & (idx < k) & np.isfinite(abs_err) & ~np.isnan(values)
    idx, err = idx[keep], abs_err[keep]
    count = np.bincount(idx, minlength=k)
    total = np.bincount(idx, weights=err, minlength=k)
    with np.errstate(invalid="ignore", divide="ignore"):
        mae = np.where(count > 0, total / np.maximum(count, 1), np.nan)
    # medians: sort by (bin, error), then read the middle element(s) of each bin's run
    order = np.lexsort((err, idx))
    sorted_err = err[order]
    start = np.cumsum(count) - count
    lo = start + np.maximum(count - 1, 0) // 2
    hi = start + count // 2
    safe = count > 0
    median = np.full(k, np.nan)
    if sorted_err.size:
        median[safe] = 0.5 * (sorted_err[lo[safe]] + sorted_err[np.minimum(hi[safe], sorted_err.size - 1)])
    return mae, median, count


def breakdown(frame, pred) -> list[dict]:
    """Error of camera C's predicted distance broken down by geometry, distance and texture.

    Args:
        frame: a :class:`harness.data.frame.Frame` with ground truth (``frame.distance["C"]``).
        pred: (H, W) predicted distance of camera C, metres (invalid values scored as in the module doc).
    Returns:
        One dict per bin (empty bins included, with ``n_px == 0`` and NaN errors), keys
        ``kind, bin_lo, bin_hi, mae_m, median_m, n_px``, in this order of kinds:

        * ``angle_U`` / ``angle_R``: angle (degrees) between the pixel's bearing (camera C, world frame) and
          the baseline direction ``U.position - C.position`` / ``R.position - C.position``; 18 bins of 10
          degrees over 0..180 (:data:`ANGLE_EDGES_DEG`);
        * ``distance``: true distance, metres, bins :data:`DISTANCE_EDGES_M` (0-1, 1-2, 2-3, 3-5, 5-8, 8+);
        * ``texture``: :func:`texture_magnitude` of C's image, grey levels per pixel, fixed bins
          :data:`TEXTURE_EDGES` (0-1, 1-2, 2-4, 4-8, 8-16, 16-32, 32+).

        ``bin_hi`` of the last distance/texture bin is ``inf``.
    Raises:
        ValueError: if the frame has no ground truth for C or ``pred`` has the wrong shape.
    """
    if "C" not in frame.distance:
        raise ValueError(f"frame {frame.scene}/{frame.viewpoint} has no ground truth for camera C")
    gt = frame.distance["C"]
    pred = np.asarray(pred)
    if pred.shape != gt.shape:
        raise ValueError(f"pred has shape {pred.shape}, frame {frame.scene}/{frame.viewpoint} is {gt.shape}")
    mask, err, _ = score_pixels(pred, gt)
    quantities = (
        ("angle_U", angle_to_baseline_deg(frame, "U")[mask], ANGLE_EDGES_DEG),
        ("angle_R", angle_to_baseline_deg(frame, "R")[mask], ANGLE_EDGES_DEG),
        ("distance", np.asarray(gt, dtype=np.float64)[mask], DISTANCE_EDGES_M),
        ("texture", texture_magnitude(frame.images["C"])[mask], TEXTURE_EDGES),
    )
    rows = []
    for kind, values, edges in quantities:
        mae, median, count = binned_errors(values, err, edges)
        for k in range(edges.size - 1):
            rows.append({"kind": kind, "bin_lo": float(edges[k]), "bin_hi": float(edges[k + 1]),
                         "mae_m": float(mae[k]), "median_m": float(median[k]), "n_px": int(count[k])})
    return rows

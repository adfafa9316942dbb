"""Whether a fitted correction is a property of the cameras or of the scene: a test over independent parts of the
frame.

A self-calibration fits a few numbers (a camera's gains, its fall-off field, its rotation) to tens of thousands of
pixels.  Their formal standard errors are meaningless: neighbouring pixels are not independent (a flow's
smoothness, a surface's texture), and a scene effect (a polished floor's view-dependent reflection, a misjudged
wall) biases every pixel of its region the same way.  What tells a camera's property from a scene's is that the
camera's is the same whichever part of the scene it is measured from.  So the sphere of C's bearings is cut into
:data:`BLOCKS` parts (``LONGITUDE_BLOCKS`` longitude sectors, above and below the horizon), the fit is repeated with
each part left out (the delete-one-block jackknife), and the spread of those fits is the estimate's covariance.  A
correction is *supported* when Hotelling's test rejects "no correction" at level :data:`ALPHA` (F distribution with
``p`` and ``B - p`` degrees of freedom, ``B`` the blocks that hold data, ``p`` the parameters tested): a model
selection between the cameras as told and the cameras corrected, decided by the frame's own evidence.

The jackknife cannot tell a camera's property from a scene effect that is the same in every block of one
hemisphere: a polished floor's view-dependent reflection fills every block below the horizon.  A camera's property
(its gain, a fall-off symmetric about its centre, its rotation) is seen as well from either hemisphere alone, so a
correction can also be asked to be as large when fitted from each hemisphere alone
(:func:`jackknife_hemispheres`).
"""

from __future__ import annotations

import numpy as np
from scipy import stats

__all__ = ["LONGITUDE_BLOCKS", "BLOCKS", "ALPHA", "MIN_BLOCK_SAMPLES", "sphere_blocks", "jackknife_linear", "Evidence",
           "hotelling", "hemisphere_rows", "jackknife_hemispheres"]

LONGITUDE_BLOCKS = 16
BLOCKS = 2 * LONGITUDE_BLOCKS
ALPHA = 1e-3
"""The test's level: the chance that a frame of cameras that agree is corrected anyway (for one tested quantity)."""
MIN_BLOCK_SAMPLES = 50
"""A block with fewer samples is not left out on its own (its samples stay in every fit)."""


def sphere_blocks(bearings: np.ndarray, longitude_blocks: int = LONGITUDE_BLOCKS) -> np.ndarray:
    """Block index of each bearing.

    Args:
        bearings: (..., 3) unit bearings (x, y, z; z up).
        longitude_blocks: sectors of equal longitude; each is cut at the horizon.
    Returns:
        (...) int64 in ``[0, 2 * longitude_blocks)``.
    """
    b = np.asarray(bearings, np.float64)
    lon = np.arctan2(b[..., 0], b[..., 1])
    sector = np.clip(((lon + np.pi) / (2 * np.pi) * longitude_blocks).astype(np.int64), 0, longitude_blocks - 1)
    return sector * 2 + (b[..., 2] < 0)


def jackknife_linear(design: np.ndarray, target: np.ndarray, weights: np.ndarray, blocks: np.ndarray,
                     ridge: np.ndarray | None = None,
                     min_samples: int = MIN_BLOCK_SAMPLES) -> tuple[np.ndarray, np.ndarray, int]:
    """Weighted least squares and its delete-one-block jackknife covariance.

    The weights are held fixed (those of a robust fit's last iteration), so every leave-one-block-out solution
    comes from the full normal equations minus the block's: B solves of a (P, P) system.

    Args:
        design: (N, P) rows; target: (N,) values; weights: (N,) non-negative row weights.
        blocks: (N,) block index per row (:func:`sphere_blocks` of the row's bearing).
        ridge: (P,) added to the normal matrix's diagonal (None: 1e-9 of its trace, for a rank-deficient design).
        min_samples: blocks with fewer rows of non-zero weight are never left out (they stay in every fit).
    Returns:
        ``(theta, cov, used)``: (P,) the full-data solution, (P, P) the jackknife covariance
        ``(B - 1) / B * sum_b (t_b - mean)(t_b - mean)^T`` and ``B`` the blocks left out (NaN covariance and 0 when
        fewer than 2 qualify).
    """
    design = np.asarray(design, np.float64)
    p = design.shape[1]
    w = np.asarray(weights, np.float64)
    # the rows grouped by block (stable: each block's rows in their order), each block's normal equations from its
    # contiguous slice of the rows scaled by the weights' square roots
    order = np.argsort(np.asarray(blocks), kind="stable")
    sorted_blocks = np.asarray(blocks)[order]
    ids, starts = np.unique(sorted_blocks, return_index=True)
    ends = np.append(starts[1:], sorted_blocks.size)[:starts.size]
    root = np.sqrt(w[order])
    scaled = design[order] * root[:, None]
    scaled_target = np.asarray(target, np.float64)[order] * root
    spans = list(zip(starts, ends, strict=True))
    ata_b = np.stack([scaled[s:e].T @ scaled[s:e] for s, e in spans]) if spans else np.zeros((0, p, p))
    atb_b = np.stack([scaled[s:e].T @ scaled_target[s:e] for s, e in spans]) if spans else np.zeros((0, p))
    ata, atb = ata_b.sum(axis=0), atb_b.sum(axis=0)
    reg = np.full(p, 1e-9 * max(float(np.trace(ata)), 1e-12)) if ridge is None else np.asarray(ridge, np.float64)
    theta = np.linalg.solve(ata + np.diag(reg), atb)
    counts = np.add.reduceat((w[order] > 0).astype(np.int64), starts) if ids.size else np.zeros(0, np.int64)
    leave = [i for i in range(ids.size) if counts[i] >= min_samples]
    if len(leave) < 2:
        return theta, np.full((p, p), np.nan), 0
    est = np.stack([np.linalg.solve(ata - ata_b[i] + np.diag(reg), atb - atb_b[i]) for i in leave])
    dev = est - est.mean(axis=0)
    cov = (len(leave) - 1) / len(leave) * dev.T @ dev
    return theta, cov, len(leave)


def hemisphere_rows(blocks: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(N,) bool masks of the rows whose :func:`sphere_blocks` block lies above the horizon and below it."""
    b = np.asarray(blocks)
    return b % 2 == 0, b % 2 == 1


def jackknife_hemispheres(design: np.ndarray, target: np.ndarray, weights: np.ndarray, blocks: np.ndarray,
                          ridge: np.ndarray | None = None,
                          min_samples: int = MIN_BLOCK_SAMPLES) -> list[tuple[np.ndarray, np.ndarray, int]]:
    """:func:`jackknife_linear` of the rows above the horizon alone and of those below it alone (same arguments).

    Returns:
        ``[(theta, cov, used) above, (theta, cov, used) below]``; a hemisphere without rows gives zeros, a NaN
        covariance and 0 blocks (no evidence).
    """
    design = np.asarray(design, np.float64)
    target, weights, blocks = np.asarray(target), np.asarray(weights), np.asarray(blocks)
    out = []
    for rows in hemisphere_rows(blocks):
        if not rows.any():
            p = design.shape[1]
            out.append((np.zeros(p), np.full((p, p), np.nan), 0))
            continue
        out.append(jackknife_linear(design[rows], target[rows], weights[rows], blocks[rows], ridge, min_samples))
    return out


class Evidence(dict):
    """A JSON-able dict: ``statistic`` (Hotelling's T^2), ``p_value``, ``blocks`` (B), ``supported`` (the test
    rejects "no correction")."""


def hotelling(theta: np.ndarray, cov: np.ndarray, blocks: int, alpha: float = ALPHA) -> Evidence:
    """Hotelling's test of ``theta = 0`` given its jackknife covariance over ``blocks`` blocks.

    Args:
        theta: (P,) the full-data estimate.
        cov: (P, P) its covariance (:func:`jackknife_linear`).
        blocks: B, the blocks the covariance came from.
        alpha: the test's level.
    Returns:
        :class:`Evidence` (``supported``: the test rejects at ``alpha``); never supported when ``B <= P`` (too few
        blocks for P quantities) or the covariance is not finite.
    """
    theta = np.asarray(theta, np.float64).reshape(-1)
    p = theta.size
    if p == 0 or blocks <= p or not np.all(np.isfinite(cov)) or not np.all(np.isfinite(theta)):
        return Evidence(statistic=float("nan"), p_value=1.0, blocks=int(blocks), supported=False)
    # a pseudo-inverse: a direction the blocks do not vary in at all (a parameter no data constrains) carries no
    # evidence rather than infinite evidence
    scale = np.sqrt(np.maximum(np.diag(cov), 1e-300))
    corr = cov / np.outer(scale, scale)
    t2 = float((theta / scale) @ np.linalg.pinv(corr, rcond=1e-10, hermitian=True) @ (theta / scale))
    f = t2 * (blocks - p) / (p * (blocks - 1))
    p_value = float(stats.f.sf(f, p, blocks - p))
    return Evidence(statistic=t2, p_value=p_value, blocks=int(blocks), supported=bool(p_value < alpha))

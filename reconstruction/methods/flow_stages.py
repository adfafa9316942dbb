"""The flow pipeline's shared stages: each pair's flow, the per-pair triangulation and the ``average`` fusion
(:func:`prepare` -> :class:`Prepared`), and the confidence of a distance from them (:func:`flow_confidence`).

Every refinement variant (:mod:`reconstruction.methods.flow_refine`), the pipeline (:func:`reconstruction.methods.
flow_pipeline.reconstruct`) and the self-calibration's pre-pass (:mod:`reconstruction.methods.self_calibration`)
start from them.

>>> prep = prepare(frame, "dis", rectify=True)                   # doctest: +SKIP
>>> prep.d0                                                      # (H * W,) float64 metres, the ``average`` fusion
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from reconstruction.camera.equirect import bearing_grid
from reconstruction.flow.backends import FlowBackend
from reconstruction.flow.matching import PairMatch, match_pair
from reconstruction.refine.fill import fuse_average
from reconstruction.refine.triangulate import PairGeometry, TriangulationLimits, pair_geometry, triangulate_sines

__all__ = ["PAIRS", "Prepared", "prepare", "flow_confidence"]

#: the pairs of camera C: C-U (vertical) and C-R (horizontal), by the other camera's name
PAIRS = ("U", "R")


@dataclass
class Prepared:
    """Everything the refinement variants share: matches, per-pair geometry and the ``average`` start.

    Attributes:
        bearings: (N, 3) world bearings of C's pixels (N = H * W, row-major).
        matches: per pair, the :class:`PairMatch`.
        geoms: per pair, the :class:`~reconstruction.refine.triangulate.PairGeometry` (arrays (N,)).
        d_pair: per pair, (N,) triangulated distances, metres; valid: per pair, (N,) bool.
        d0: (N,) the ``average`` distances, metres (every variant starts from them).
        limits: the triangulation limits used.
        seconds: wall time of ``flow_U``, ``flow_R``, ``triangulate`` and ``average``.
    """

    bearings: np.ndarray
    matches: dict[str, PairMatch]
    geoms: dict[str, PairGeometry]
    d_pair: dict[str, np.ndarray]
    valid: dict[str, np.ndarray]
    d0: np.ndarray
    limits: TriangulationLimits
    seconds: dict[str, float] = field(default_factory=dict)


def prepare(frame, flow: str | FlowBackend, rectify: bool = True,
            limits: TriangulationLimits = TriangulationLimits(),
            on_stage: Callable[[str], None] | None = None) -> Prepared:
    """Flow for both pairs, triangulation and the ``average`` fusion, each timed.

    Args:
        frame: the frame (images and poses); flow: a flow backend or its name, or ``"oracle"``
            (:func:`reconstruction.flow.matching.match_pair`); rectify: flow on rectified pairs (True) or on the
            plain equirect images; limits: the triangulation limits; on_stage: called with each stage name before it
            runs.
    """
    note = on_stage or (lambda _s: None)
    h, w = frame.height, frame.width
    seconds = {}
    bearings = bearing_grid(w, h, frame.cameras["C"].rotation).reshape(-1, 3)
    matches = {}
    for k in PAIRS:
        note(f"flow_{k}")
        matches[k] = match_pair(frame, k, flow, rectify)
        seconds[f"flow_{k}"] = matches[k].seconds
    note("triangulate")
    start = time.perf_counter()
    geoms, d_pair, valid = {}, {}, {}
    for k in PAIRS:
        geoms[k] = pair_geometry(bearings, matches[k].baseline, matches[k].bearing.reshape(-1, 3))
        d_pair[k], valid[k] = triangulate_sines(geoms[k], limits)
    seconds["triangulate"] = time.perf_counter() - start
    start = time.perf_counter()
    d0 = fuse_average([d_pair[k] for k in PAIRS], [valid[k] for k in PAIRS], (h, w))
    seconds["average"] = time.perf_counter() - start
    return Prepared(bearings, matches, geoms, d_pair, valid, d0, limits, seconds)


def flow_confidence(d: np.ndarray, prep: Prepared, tolerance: float = 0.05) -> np.ndarray:
    """Per-pixel confidence of a flow-pipeline distance, in [0, 1]: the best pair's support.

    For each pair k, ``valid_k * sin(alpha_k)^2 * exp(-|ln(d_k / d)| / tolerance)``: high where a pair far from
    its epipole triangulates (alone) to the final distance; the maximum over the pairs.

    Args:
        d: (H, W) or (N,) final distances, metres; prep: the shared stages (per-pair distances and geometry).
        tolerance: relative disagreement that lowers the support by a factor e (dimensionless).
    Returns:
        float32 array of ``d``'s shape.
    """
    dd = np.maximum(np.asarray(d, np.float64).reshape(-1), 1e-9)
    conf = np.zeros(dd.shape)
    for k in PAIRS:
        ratio = np.abs(np.log(np.maximum(prep.d_pair[k], 1e-9) / dd))
        c = np.where(prep.valid[k], prep.geoms[k].sin_alpha ** 2 * np.exp(-ratio / tolerance), 0.0)
        conf = np.maximum(conf, c)
    return np.clip(conf, 0.0, 1.0).astype(np.float32).reshape(np.shape(d))

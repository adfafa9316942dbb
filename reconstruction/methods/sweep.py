"""The trinocular sphere sweep with semi-global matching over sphere and horizontal-plane labels, as a Method.

Stages (timed in ``MethodOutput.seconds``): ``cost`` (rectified features, sphere cost volume), ``planes``
(plane-label costs from the same volume), ``sgm`` (8-path aggregation), ``wta`` (winner, sub-level
refinement, confidence), ``post`` (fill of unreliable pixels, median), ``refine_planes`` (the floor and the ceiling
searched again from the images, when ``SweepMethod.refine_planes`` asks).  See docs/matching.md.
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass, field

import cv2
import numpy as np
from scipy import ndimage

from reconstruction.camera.equirect import bearing_grid
from reconstruction.camera.image_ops import periodic_filter
from reconstruction.methods.base import MethodOutput
from reconstruction.methods.self_calibration import Calibration, reduced_frame, self_calibrate
from reconstruction.photometry import PhotometricParams
from reconstruction.refine.edges import snap_depth_edges
from reconstruction.refine.fill import check_fill_space, fill_edge_aware
from reconstruction.refine.planes import (
    PlaneRefineParams,
    onto_enclosing_walls,
    refine_plane,
    resolved_range,
    snap_to_planes,
)
from reconstruction.refine.triangulate import TriangulationLimits
from reconstruction.rig_calibration import NO_RIG_CALIBRATION
from reconstruction.sweep.cost import (
    CostParams,
    build_cost_volume,
    gray_float,
    image_noise,
    inverse_distances,
    noise_blur_px,
)
from reconstruction.sweep.planes import (
    UP,
    PlaneParams,
    add_prior,
    bound_costs,
    bound_wall_costs,
    dominant_planes,
    dominant_walls,
    fill_plane_costs,
    onto_room_planes,
    plane_heights,
    room_plane_distance,
    room_planes,
    room_walls,
    wall_normals,
)
from reconstruction.sweep.sgm import aggregate, winner_take_all

__all__ = ["SgmParams", "PostParams", "SweepMethod", "Prior", "PriorFromSweep", "labels_to_distance",
           "sweep_distance", "sweep_distances"]


@dataclass(frozen=True)
class SgmParams:
    """Semi-global matching parameters (cost units are those of :class:`CostParams`: ``scale`` per gray level).

    Attributes:
        p1: penalty of a +-1 label step within a family, cost units.
        p2: penalty of a larger jump within a family (before edge adaptation), cost units.
        p3: extra penalty of switching family (sphere <-> plane), cost units.
        edge: gray-level difference between neighbours that halves P2 and P3, gray levels.
        paths: 8 or 4 aggregation paths.
    """

    p1: int = 120
    p2: int = 800
    p3: int = 200
    edge: float = 8.0
    paths: int = 8


@dataclass(frozen=True)
class PostParams:
    """Post-processing.

    Attributes:
        min_confidence: pixels with confidence below this are refilled from confident neighbours (0 = none;
            :func:`reconstruction.refine.fill.fill_edge_aware`).
        fill_lambda, fill_sigma_color: edge-aware fill smoothness and edge scale (8-bit gray levels).
        fill_space: what the fill interpolates: ``"inverse"`` distance or ``"log"`` distance
            (:data:`reconstruction.refine.fill.FILL_SPACES`).
        median_px: median filter side, pixels (0 or 1: none; an odd side >= 3; wraps in longitude).
        edge_radius_px: after the median, the pixels near the estimate's depth edges take the joint weighted
            median of the log distances within this half side, pixels (0 = none;
            :func:`reconstruction.refine.edges.snap_depth_edges`).
        edge_sigma_color, edge_sigma_px: its weights' colour scale (C's 0-255 levels) and spatial scale (pixels).
        edge_jump, edge_reach_px: the pixels it changes: within ``edge_reach_px`` pixels of one whose 3 x 3 log
            distances span more than ``edge_jump``.
    """

    min_confidence: float = 0.0
    fill_lambda: float = 200.0
    fill_sigma_color: float = 8.0
    median_px: int = 5
    fill_space: str = "inverse"
    edge_radius_px: int = 0
    edge_sigma_color: float = 10.0
    edge_sigma_px: float = 5.0
    edge_jump: float = 0.05
    edge_reach_px: int = 4

    def __post_init__(self) -> None:
        check_fill_space(self.fill_space)
        k = self.median_px
        if type(k) is not int or not (k in (0, 1) or (k >= 3 and k % 2)):
            raise ValueError(f"median_px must be 0, 1 or an odd side >= 3, got {self.median_px!r}")
        if self.edge_radius_px < 0 or self.edge_reach_px < 0:
            raise ValueError(f"edge_radius_px and edge_reach_px must be >= 0, got {self.edge_radius_px} and "
                             f"{self.edge_reach_px}")
        for name in ("edge_sigma_color", "edge_sigma_px", "edge_jump"):
            if not getattr(self, name) > 0:
                raise ValueError(f"{name} must be > 0, got {getattr(self, name)}")


@dataclass(frozen=True, eq=False)
class Prior:
    """A prior on camera C's distance, added to the sweep's sphere labels before aggregation: every sphere label
    ``i`` of pixel p costs ``weight(p) * min(|i - l(p)|, truncate_levels)`` more, ``l(p)`` the fractional label of
    ``distance(p)`` (:func:`reconstruction.sweep.planes.add_prior`).

    Attributes:
        distance: (H, W) prior distances of C, metres (e.g. the flow pipeline's).
        weight: (H, W) float32 weight, cost units per label.
        truncate_levels: label distance beyond which the prior cost stops growing, labels.
    """

    distance: np.ndarray
    weight: np.ndarray
    truncate_levels: float


@dataclass(frozen=True, eq=False)
class PriorFromSweep:
    """A prior that depends on the plain sweep, at no extra aggregation: ``make(distance, confidence, room)`` of the
    sweep's coarse room-bound pass ((H, W) float32 each, upsampled to the frame; ``room`` the distance along C's
    bearings to the floor or the ceiling that pass found, inf where none: :func:`reconstruction.sweep.planes.
    room_plane_distance`, metres) returns the :class:`Prior`.  Needs the plane family (``PlaneParams.per_side >
    0``), whose coarse pass it reads."""

    make: Callable[[np.ndarray, np.ndarray, np.ndarray], Prior]


def _clock() -> tuple[float, float]:
    """(wall, process CPU) seconds now."""
    return time.perf_counter(), time.process_time()


def _lap(seconds: dict, key: str, start: tuple[float, float]) -> None:
    """Record a stage's wall time as ``seconds[key]`` and its process CPU time (all threads) as
    ``seconds[key + "_cpu"]``, seconds."""
    seconds[key] = time.perf_counter() - start[0]
    seconds[key + "_cpu"] = time.process_time() - start[1]


def _wall_distance(p: np.ndarray, offsets: np.ndarray, axis: np.ndarray, d_max_m: float) -> np.ndarray:
    """Distance of fractional labels ``p`` (0 .. Q - 1) of one wall family with signed ``offsets`` (metres, one
    side, ascending |o|) along bearing components ``axis``; ``d_max_m`` where the wall is not in front."""
    idx = np.arange(offsets.size, dtype=np.float64)
    o = np.exp(np.interp(np.clip(p, 0.0, offsets.size - 1.0), idx, np.log(np.abs(offsets)))) * np.sign(offsets[0])
    with np.errstate(divide="ignore", invalid="ignore"):
        dp = o / axis
    return np.where(np.isfinite(dp) & (dp > 0), dp, d_max_m)


def labels_to_distance(label: np.ndarray, inv_d: np.ndarray, heights: np.ndarray, a_z: np.ndarray,
                       d_min_m: float, d_max_m: float, walls: list[tuple[np.ndarray, np.ndarray]] = ()
                       ) -> np.ndarray:
    """Fractional labels -> distance, metres.

    Args:
        label: (H, W) fractional label (sphere labels ``0..D-1``, then plane labels, then each wall's labels).
        inv_d: (D,) uniform inverse distances of the sphere labels, 1/m.
        heights: (P,) plane heights relative to C, metres (below first, ascending |h|, then above).
        a_z: (H, W) world Z of C's unit bearings.
        d_min_m, d_max_m: clamp, metres.
        walls: per wall family ``(a_n, offsets)``: (H, W) bearing components along its normal and its (Q,) signed
            offsets, metres (:func:`reconstruction.sweep.planes.dominant_walls`).
    Returns:
        (H, W) float64 distance, metres.
    """
    n_d = inv_d.size
    q = inv_d[0] + np.clip(label, 0, n_d - 1) * (inv_d[1] - inv_d[0])
    d = 1.0 / np.maximum(q, 1e-9)
    first = n_d
    if heights.size:
        per = heights.size // 2
        inside = (label >= first - 0.5 + 1e-9) & (label < first + heights.size - 0.5 + 1e-9)
        p = np.clip(label - first, 0.0, heights.size - 1.0)
        side = (p >= per - 0.5).astype(np.int64)  # 0: below, 1: above
        local = np.clip(p - side * per, 0.0, per - 1.0)
        log_mag = np.log(np.abs(heights[:per]))
        idx = np.arange(per, dtype=np.float64)
        h = np.exp(np.interp(local, idx, log_mag)) * np.where(side == 1, 1.0, -1.0)
        with np.errstate(divide="ignore", invalid="ignore"):
            dp = h / a_z
        dp = np.where(np.isfinite(dp) & (dp > 0), dp, d_max_m)
        d = np.where(inside, dp, d)
        first += heights.size
    for a_n, offsets in walls:
        inside = (label >= first - 0.5 + 1e-9) & (label < first + offsets.size - 0.5 + 1e-9)
        d = np.where(inside, _wall_distance(label - first, offsets, a_n, d_max_m), d)
        first += offsets.size
    return np.clip(d, d_min_m, d_max_m)


def _median_wrap(d: np.ndarray, k: int) -> np.ndarray:
    """Median filter of odd side ``k`` wrapping in longitude, the rows beyond the poles repeating the edge row;
    (H, W) float -> float32 (``k`` <= 1: unfiltered).  OpenCV's filter up to 5 (it filters float maps at 3 and 5
    only), SciPy's above (the same answer at 5; about 0.5 s at 9 on a 1000x500 map)."""
    if k <= 1:
        return d.astype(np.float32)
    if k <= 5:
        return periodic_filter(d.astype(np.float32), k // 2, lambda x: cv2.medianBlur(x, k))
    return periodic_filter(d.astype(np.float32), k // 2, lambda x: ndimage.median_filter(x, size=k, mode="nearest"))


def _sphere_costs(frame, sweep: SweepMethod, seconds, prefix="", wall_labels: int = 0, estimate=None):
    """The sphere cost volume of ``sweep`` with room for the plane family and ``wall_labels`` wall labels (stage
    ``cost``).

    Returns:
        ``(cost, heights, inv_d)``: (H, W, levels + P + wall_labels) uint16 costs (plane labels not yet filled),
        plane heights (metres) and sphere inverse distances (1/m).
    """
    t = _clock()
    heights = plane_heights(sweep.planes)
    cost, _ = build_cost_volume(frame, sweep.cost, extra_labels=heights.size + wall_labels, pairs=sweep.pairs,
                                estimate=estimate)
    _lap(seconds, prefix + "cost", t)
    return cost, heights, inverse_distances(sweep.cost)


def _aggregate(frame, cost, heights, inv_d, sweep: SweepMethod, seconds, bounds=(-np.inf, np.inf), prefix="",
               prior: Prior | None = None, walls=()):
    """Prior, plane and wall labels, (room bound), SGM and winner-take-all of ``sweep`` on a sphere cost volume
    (consumed: changed in place and freed).

    Args:
        walls: per wall ``(normal, offsets)`` (:func:`reconstruction.sweep.planes.dominant_walls`); the volume
            must have room for their labels.
    Returns:
        ``(label, conf, a_z, wall_families)``: (H, W) fractional labels and confidence, (H, W) world Z of C's
        bearings, and per wall ``(a_n, offsets)`` (its normal's bearing components, (H, W)).
    """
    cost_params, plane_params, sgm = sweep.cost, sweep.planes, sweep.sgm
    n_d = cost_params.levels
    t = _clock()
    if prior is not None:
        add_prior(cost, n_d, inv_d, prior.distance, prior.weight, prior.truncate_levels, cost_params.max_cost())
        _lap(seconds, prefix + "prior", t)
        t = _clock()
    bearings = bearing_grid(frame.width, frame.height, frame.cameras["C"].rotation)
    a_z = bearings[..., 2]
    families = [(bearings @ normal, offsets) for normal, offsets in walls]
    bias = plane_params.bias if heights.size or families else 0
    max_cost = cost_params.max_cost()
    fill_plane_costs(cost, n_d, a_z, heights, inv_d, max_cost, bias, families)
    max_cost += bias
    if np.isfinite(bounds[0]) or np.isfinite(bounds[1]):
        bound_costs(cost, n_d, a_z, inv_d, heights, bounds[0], bounds[1], max_cost,
                    int(round(plane_params.bound_penalty * cost_params.scale)), plane_params.bound_penalty_min_az)
        first = n_d + heights.size
        for a_n, offsets in families:
            bound_wall_costs(cost, first, a_z, a_n, offsets, bounds[0], bounds[1], max_cost)
            first += offsets.size
    family = np.concatenate([np.zeros(n_d, np.int64), np.ones(heights.size, np.int64),
                             *(np.full(o.size, 2 + k, np.int64) for k, (_, o) in enumerate(families))])
    _lap(seconds, prefix + "planes", t)
    t = _clock()
    gray = gray_float(frame.images["C"], 0.0)
    agg = aggregate(cost, family, gray, sgm.p1, sgm.p2, sgm.p3, sgm.edge, max_cost, sgm.paths)
    del cost
    _lap(seconds, prefix + "sgm", t)
    t = _clock()
    label, conf = winner_take_all(agg, family)
    _lap(seconds, prefix + "wta", t)
    return label, conf, a_z, families


def room_bounds(frame, sweep: SweepMethod, seconds):
    """From a coarse pass of ``sweep`` (the plain sweep on images ``coarse_factor`` times smaller, its cost without
    ``normalized_weight``'s mix): floor and ceiling heights relative to C (metres, -inf / inf if not found or
    without ``room_bound``; widened by ``bound_margin``), the walls' yaw (radians or None), the label families of the
    walls found (:func:`reconstruction.sweep.planes.dominant_walls`; none without ``wall_labels``) followed by those
    of the floor and ceiling found (:func:`reconstruction.sweep.planes.room_planes`; none without ``room_labels``),
    and the coarse pass's (distance (m), confidence) maps, and the floor's and ceiling's heights as found (metres,
    -inf / inf if not found; no margin)."""
    if sweep.cost.normalized_weight > 0:  # the room is read from the cost of the feature alone (CostParams)
        sweep = dataclasses.replace(sweep, cost=dataclasses.replace(sweep.cost, normalized_weight=0.0))
    cost_params, plane_params = sweep.cost, sweep.planes
    coarse = reduced_frame(frame, plane_params.coarse_factor)
    cost, heights, inv_d = _sphere_costs(coarse, sweep, seconds, prefix="coarse_")
    label, conf, a_z, _ = _aggregate(coarse, cost, heights, inv_d, sweep, seconds, prefix="coarse_")
    z_floor, z_ceil = dominant_planes(label, cost_params.levels, heights, plane_params.bound_min_share,
                                      plane_params.mirror_tolerance)
    d = labels_to_distance(label, inv_d, heights, a_z, cost_params.d_min_m, cost_params.d_max_m)
    yaw, walls = None, []
    if plane_params.wall_labels > 0:
        bearings = bearing_grid(coarse.width, coarse.height, coarse.cameras["C"].rotation)
        yaw, walls = dominant_walls(d[..., None] * bearings, plane_params)
    walls = [*walls, *room_planes(z_floor, z_ceil, plane_params)]
    m = 1.0 + plane_params.bound_margin
    found = (z_floor, z_ceil)
    if not plane_params.room_bound:
        z_floor, z_ceil, m = -np.inf, np.inf, 1.0
    return z_floor * m, z_ceil * m, yaw, walls, (d, conf), found


class _PlaneRefiner:
    """The floor and the ceiling of a frame refined on a distance map, and what lies beyond its enclosing walls put
    on them (``sweep.refine_planes``): the gray images (blurred by the sweep's cost's ``blur_px``) and C's world
    bearings made once for every prior's map."""

    def __init__(self, frame, sweep: SweepMethod, found: tuple[float, float]):
        self.frame, self.sweep = frame, sweep
        self.starts = [z for z in found if np.isfinite(z) and z != 0]
        params = sweep.refine_planes
        self.active = params is not None and (bool(self.starts) or params.wall_margin > 0)
        self._gray = self._bearings = None

    def __call__(self, d: np.ndarray) -> tuple[np.ndarray, list[dict]]:
        """(H, W) distance (m) -> the distance with the refined planes' pixels on them, then the pixels beyond an
        enclosing wall on it (:func:`reconstruction.refine.planes.onto_enclosing_walls`: the walls found and, where
        none encloses a side, the ceiling's edge), and each plane's record
        (:meth:`reconstruction.refine.planes.PlaneFit.record`, then one per wall)."""
        frame, params = self.frame, self.sweep.refine_planes
        if self._gray is None:
            # the images as the sweep's cost saw them (blurred where a camera's noise asked for it)
            self._gray = {k: gray_float(frame.images[k], self.sweep.cost.blur_px) for k in ("C", *self.sweep.pairs)}
            self._bearings = bearing_grid(frame.width, frame.height, frame.cameras["C"].rotation)
        fits = [refine_plane(self._gray, frame.cameras, self._bearings, d, UP, z, params, self.sweep.pairs)
                for z in self.starts]
        cost = self.sweep.cost
        d = snap_to_planes(d, self._bearings, fits, params, (cost.d_min_m, cost.d_max_m))
        records = [f.record() for f in fits]
        if params.wall_margin > 0:  # the walls of the map as it now is
            yaw, walls = room_walls(d[..., None] * self._bearings, self.sweep.planes.wall_min_share,
                                    self.sweep.planes.wall_yaw)
            ceiling = [f.offset for f in fits if f.offset > 0]
            baseline = min(float(np.linalg.norm(frame.cameras[k].position - frame.cameras["C"].position))
                           for k in self.sweep.pairs)
            d, wall_records = onto_enclosing_walls(d, self._bearings, walls,
                                                   None if yaw is None else wall_normals(yaw),
                                                   ceiling[0] if ceiling else None, params,
                                                   resolved_range(baseline, frame.width, params.snap))
            records += wall_records
        return d, records


def sweep_distances(frame, sweep: SweepMethod, priors: Sequence[Prior | PriorFromSweep | None] = (None,),
                    calibration: Calibration | None = None):
    """Run the sweep configured by ``sweep`` on a frame once per prior, sharing the room-bound pass and the sphere
    cost volume.

    Args:
        sweep: the sweep's configuration (cost, planes, SGM, post, pairs, photometric self-calibration).
        priors: each None (the plain sweep), a :class:`Prior` (added to the sphere labels before aggregation; not
            used in the coarse room-bound pass) or a :class:`PriorFromSweep` (made from the coarse pass's distance
            and confidence).
        calibration: the frame's self-calibration when another stage made it (a flow-prior sweep matches the
            frame its flow matched; its seconds are the flow's); None: the sweep's own
            (:func:`reconstruction.methods.self_calibration.self_calibrate` with ``sweep.photometric`` and the told
            poses; stage ``photometric``).  When it changed the images, the sweep's cost is ``corrected_cost``; a
            cost with ``noise_blur`` then blurs as much as the images' noise asks (``CostParams.noise_blur``).
    Returns:
        One ``(distance, confidence, seconds, info)`` per prior: (H, W) float32 metres, (H, W) float32 in [0, 1],
        wall time per stage (the shared ``coarse_*`` and ``cost`` stages in every one, as they would take alone),
        details (plane share, room bounds, ``beyond_share``: the share of pixels put on the floor or the ceiling
        from beyond the room bound, ``PlaneParams.bound_penalty``; ``cpu_seconds``: process CPU time per stage;
        ``copy_seconds``: the wall time of copying the shared volume for this prior, 0 for the last, which takes
        the volume itself;
        ``blur_px``: the images' blur; ``noise_grey_levels``: their noise, when the cost asks for it;
        ``calibration``: what the self-calibration applied, when it ran).
    """
    shared = {}
    if calibration is None:
        calibration = self_calibrate(frame, sweep.photometric, NO_RIG_CALIBRATION, TriangulationLimits())
        shared.update(calibration.seconds)
    frame = calibration.frame
    if calibration.corrected_images and sweep.corrected_cost is not None:
        sweep = dataclasses.replace(sweep, cost=sweep.corrected_cost)
    noise = None
    if sweep.cost.noise_blur > 0:  # noisier images than the cost's blur was chosen for: blur more
        noise = max(image_noise(frame.images[k], sweep.cost.noise_scale) for k in ("C", *sweep.pairs))
        sweep = dataclasses.replace(sweep, cost=dataclasses.replace(sweep.cost,
                                                                    blur_px=noise_blur_px(sweep.cost, noise)))
    cost_params, plane_params, post = sweep.cost, sweep.planes, sweep.post
    bounds, yaw, walls, coarse, found = (-np.inf, np.inf), None, [], None, (-np.inf, np.inf)
    from_sweep = any(isinstance(p, PriorFromSweep) for p in priors)
    if ((plane_params.room_bound or plane_params.wall_labels > 0 or plane_params.room_labels > 0 or from_sweep
         or sweep.refine_planes is not None) and plane_params.per_side > 0):
        z_floor, z_ceil, yaw, walls, coarse, found = room_bounds(frame, sweep, shared)
        bounds = (z_floor, z_ceil)
        if from_sweep:  # only the priors made from the plain sweep read the coarse maps
            size = (frame.width, frame.height)
            coarse = (*(cv2.resize(np.asarray(a, np.float32), size, interpolation=cv2.INTER_LINEAR) for a in coarse),
                      room_plane_distance(bearing_grid(frame.width, frame.height,
                                                       frame.cameras["C"].rotation)[..., 2], found))
    estimate = None
    if cost_params.occlusion > 0 and coarse is not None:  # the coarse pass's distances decide what each pair sees
        # (upsampled bilinearly, as the priors read them: a no-op when they already did)
        estimate = cv2.resize(np.asarray(coarse[0], np.float32), (frame.width, frame.height),
                              interpolation=cv2.INTER_LINEAR)
    cost, heights, inv_d = _sphere_costs(frame, sweep, shared, wall_labels=sum(o.size for _, o in walls),
                                         estimate=estimate)
    out = []
    refine = _PlaneRefiner(frame, sweep, found)
    for i, prior in enumerate(priors):
        seconds = dict(shared)
        copy_seconds = 0.0  # the price of sharing, not of the method: kept out of its stages and total
        if i < len(priors) - 1:
            t = time.perf_counter()
            work = cost.copy()
            copy_seconds = time.perf_counter() - t
        else:  # the last prior consumes the shared volume itself
            work, cost = cost, None
        if isinstance(prior, PriorFromSweep):
            if coarse is None:
                raise ValueError("a prior that depends on the coarse pass needs the plane family (per_side > 0)")
            prior = prior.make(*coarse)
        label, conf, a_z, families = _aggregate(frame, work, heights, inv_d, sweep, seconds, bounds, prior=prior,
                                                walls=walls)
        del work
        t = _clock()
        d = labels_to_distance(label, inv_d, heights, a_z, cost_params.d_min_m, cost_params.d_max_m, families)
        beyond = 0.0
        if plane_params.bound_penalty > 0:  # a winner beyond the room bound is a reflection in the floor (ceiling)
            d, beyond = onto_room_planes(d, a_z, bounds, found, plane_params.bound_penalty_min_az)
        if post.min_confidence > 0:
            ok = conf >= post.min_confidence
            if ok.any() and not ok.all():
                d = np.where(ok, d, fill_edge_aware(d, ok, frame.images["C"], post.fill_lambda,
                                                    post.fill_sigma_color, post.fill_space))
        d = _median_wrap(d, post.median_px)
        if post.edge_radius_px > 0:
            d = snap_depth_edges(d, conf, frame.images["C"], post.edge_radius_px, post.edge_sigma_color,
                                 post.edge_sigma_px, post.edge_jump, post.edge_reach_px)
        _lap(seconds, "post", t)
        planes = []
        if refine.active:
            t = _clock()
            d, planes = refine(d)
            _lap(seconds, "refine_planes", t)
        cpu = {k[:-4]: seconds.pop(k) for k in [k for k in seconds if k.endswith("_cpu")]}
        seconds["total"] = sum(seconds.values())
        cpu["total"] = sum(cpu.values())
        n_h = cost_params.levels + heights.size
        info = {"plane_share": float(((label >= cost_params.levels - 0.5) & (label < n_h - 0.5)).mean()),
                "wall_share": float((label >= n_h - 0.5).mean()), "beyond_share": beyond,
                "wall_yaw_deg": None if yaw is None else float(np.degrees(yaw)),
                "walls_m": [float(np.median(o)) for n, o in walls if n[2] == 0],
                "room_planes_m": [float(np.median(o)) for n, o in walls if n[2] != 0],
                "floor_m": float(bounds[0]), "ceiling_m": float(bounds[1]), "cpu_seconds": cpu,
                "copy_seconds": copy_seconds, "blur_px": float(cost_params.blur_px),
                **({"planes": planes} if refine.active else {}),
                **({"noise_grey_levels": noise} if noise is not None else {}),
                **({"calibration": calibration.record, "applied": calibration.applied} if calibration.record else {})}
        out.append((d.astype(np.float32), np.clip(conf, 0.0, 1.0).astype(np.float32), seconds, info))
    return out


def sweep_distance(frame, sweep: SweepMethod, prior: Prior | PriorFromSweep | None = None):
    """Run the sweep configured by ``sweep`` on a frame (:func:`sweep_distances` with one prior; None = the plain
    sweep).

    Returns:
        ``(distance, confidence, seconds, info)``: (H, W) float32 metres, (H, W) float32 in [0, 1], wall time
        per stage, details (plane share, room bounds).
    """
    return sweep_distances(frame, sweep, [prior])[0]


@dataclass(frozen=True)
class SweepMethod:
    """Trinocular sphere sweep + SGM over sphere and horizontal-plane labels (a :class:`Method`).

    Attributes:
        cost: matching cost and distance hypotheses (:class:`CostParams`: metres, gray levels, pixels).
        planes: horizontal-plane family (:class:`PlaneParams`: metres, cost units).
        sgm: aggregation penalties (:class:`SgmParams`: cost units, gray levels).
        post: fill and median (:class:`PostParams`).
        pairs: the pairs used ("U", "R"); one pair only is an ablation.
        label: the method's label.
        photometric: photometric self-calibration before matching
            (:class:`reconstruction.photometry.PhotometricParams`; mode ``"none"`` = the images as they are).
        corrected_cost: the cost used instead of ``cost`` when the self-calibration changed the images (what a
            corrected gain leaves can weigh less); None: ``cost`` always.
        refine_planes: after the post-processing, the floor and the ceiling the coarse pass found are searched
            again at sub-label precision from the images and the pixels near them put on them, where the search is
            sure (:mod:`reconstruction.refine.planes`); None: not.
    """

    cost: CostParams = field(default_factory=CostParams)
    planes: PlaneParams = field(default_factory=PlaneParams)
    sgm: SgmParams = field(default_factory=SgmParams)
    post: PostParams = field(default_factory=PostParams)
    pairs: tuple[str, ...] = ("U", "R")
    label: str = "sweep"
    photometric: PhotometricParams = PhotometricParams()
    corrected_cost: CostParams | None = None
    refine_planes: PlaneRefineParams | None = None

    def config(self) -> dict:
        out = {"kind": "sweep", "label": self.label, "cost": asdict(self.cost), "planes": asdict(self.planes),
               "sgm": asdict(self.sgm), "post": asdict(self.post), "pairs": list(self.pairs),
               "photometric": self.photometric.config()}
        if self.corrected_cost is not None:
            out["corrected_cost"] = asdict(self.corrected_cost)
        if self.refine_planes is not None:
            out["refine_planes"] = asdict(self.refine_planes)
        return out

    def run(self, frame) -> MethodOutput:
        d, conf, seconds, info = sweep_distances(frame, self, [None])[0]
        return MethodOutput(distance=d, confidence=conf, seconds=seconds, info=info)

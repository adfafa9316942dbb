"""A room's floor and ceiling at the distance the images give them, not the one a label grid does.

A sweep's plane labels are a grid: a floor whose height falls between two labels is put on one of them, or between
them by the winner's sub-label interpolation of costs sampled a label apart, and a plain floor is then a few per
cent off everywhere (on vp000 of the ideal dev frames of tri360-v3: floors 0.3-7.5 % and ceilings up to 6.3 % from
their true heights).  A plane's offset is one number that tens of thousands of pixels see.  :func:`refine_plane`
finds it by a one-dimensional search: for each candidate offset ``o`` every selected pixel ``p`` of C is put on the
plane (distance ``o / (b_p . n)``, ``b_p`` its world bearing, ``n`` the plane's unit normal), projected into U and R
and compared with what they see there (gray levels, truncated); the least mean cost wins, of two alike the farther
from C (what else lies near a room's plane lies on C's side of it), and a parabola through it and its two
neighbours gives the sub-step.  The offset is applied only where the images fix it: its delete-one-block jackknife
over sectors of the sphere (:func:`reconstruction.evidence.sphere_blocks`) is small (a plain carpet, or other
surfaces that pull the minimum their way, give estimates that differ from block to block) and its basin narrow.
:func:`snap_to_planes` then puts the pixels the estimate places near an applied plane onto it.  Walls are not
searched: the sweep's wall labels are four times finer, and furniture against a wall pulls its minimum (measured,
docs/edges.md).  :func:`onto_walls` puts what the estimate places well beyond an enclosing wall on it: nothing is
seen through a room's wall, but a glossy one shows mirror images that match beyond it.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

from reconstruction.camera.equirect import pixel_to_lonlat, project
from reconstruction.camera.image_ops import sobel_gradient
from reconstruction.camera.resample import sample_equirect
from reconstruction.evidence import sphere_blocks

__all__ = ["PlaneRefineParams", "PlaneFit", "plane_offsets", "refine_plane", "snap_to_planes", "onto_walls",
           "on_ceiling", "ceiling_walls", "EDGE_RESOLUTION_PX", "resolved_range", "onto_enclosing_walls"]


@dataclass(frozen=True)
class PlaneRefineParams:
    """How :func:`refine_plane` searches a plane's offset and when it is applied.

    Attributes:
        search: the candidate offsets span ``o_b * exp(+-search)``, ``o_b`` where the estimate has the plane: the
            mode (0.2 % bins) of its pixels' offsets within ``search`` of the offset the search is given.
        select: the pixels searched are those whose estimate lies within this relative distance of ``o_b``
            (``|ln(d (b . n) / o_b)|``), on its side, seen at more than ``min_cos`` from it.
        steps: candidate offsets, evenly spaced in ``ln o``.
        truncate: each pair's absolute gray-level difference is truncated here (a pixel of another surface costs
            at most this).
        min_gradient: only pixels where C's gray gradient (Sobel, gray levels per pixel) exceeds this take part:
            a flat pixel's cost does not depend on the offset.
        max_pixels: at most this many pixels (evenly strided).
        min_cos: pixels whose bearing makes an angle with the plane whose sine is below this are not used or
            snapped (grazing: a small offset error is a large distance error there).
        far_share: of the mean cost's local minima (after a [1, 2, 1] smoothing) within this share of the least,
            the farthest from C is the plane.
        max_se: a refined offset is applied only when its jackknife standard error is at most this (natural log
            of the offset, 0.005: half a per cent) ...
        rise, max_basin: ... and when the candidates whose cost is within ``rise`` (a share) of its own, contiguous
            with it, reach at most ``max_basin`` (natural log) from it on either side.
        longitude_blocks: the jackknife's sectors of longitude (each cut at the horizon); a block with fewer than
            ``min_block_pixels`` pixels stays in every fit.
        snap: after a plane is refined, the pixels whose estimate lies within this relative distance of it, or of
            ``o_b``, are put on it.
        wall_margin: > 0: the pixels more than this (relative) beyond an enclosing wall are put on it
            (:func:`onto_walls`); 0: walls are left alone.
        wall_max_share: a wall encloses when at most this share of the pixels facing it lie beyond it.
        closed_max_share, closed_ceiling_share: a wall with more than ``wall_max_share`` but at most
            ``closed_max_share`` of its facing pixels beyond it still encloses when the ceiling does not go on past
            it: at most ``closed_ceiling_share`` of the ceiling's pixels facing it lie beyond it (a glossy screen or
            cabinet on a wall shows little of the ceiling in its mirror images, while the room's ceiling goes on
            behind a shelf or a partition that does not reach it); 0 (``closed_max_share``): not asked.
        ceiling_edge: > 0 (with ``wall_margin``): on each side of C along each wall normal where no wall found
            encloses but one encloses the opposite side, the wall is also looked for at the ceiling's edge, the
            offset within which this share of the ceiling's area seen on that side lies (:func:`ceiling_walls`; not
            farther than the rig resolves the ceiling), and what lies well beyond it is put on it when it encloses
            (:func:`onto_enclosing_walls`); 0: not looked for.
    """

    select: float = 0.12
    search: float = 0.15
    steps: int = 61
    truncate: float = 20.0
    min_gradient: float = 1.0
    max_pixels: int = 40000
    min_cos: float = 0.1
    max_se: float = 0.005
    longitude_blocks: int = 32
    min_block_pixels: int = 50
    snap: float = 0.06
    rise: float = 0.05
    max_basin: float = 0.03
    far_share: float = 0.05
    wall_margin: float = 0.0
    wall_max_share: float = 0.03
    closed_max_share: float = 0.0
    closed_ceiling_share: float = 0.0
    ceiling_edge: float = 0.0

    def __post_init__(self) -> None:
        if not (self.wall_margin >= 0 and 0 <= self.wall_max_share <= 1):
            raise ValueError(f"plane refinement wall_margin must be >= 0 and wall_max_share in [0, 1], got "
                             f"{self.wall_margin} and {self.wall_max_share}")
        if not (0 <= self.closed_max_share <= 1 and 0 <= self.closed_ceiling_share <= 1):
            raise ValueError(f"plane refinement closed_max_share and closed_ceiling_share must be in [0, 1], got "
                             f"{self.closed_max_share} and {self.closed_ceiling_share}")
        if not 0 <= self.ceiling_edge <= 1:
            raise ValueError(f"plane refinement ceiling_edge must be in [0, 1], got {self.ceiling_edge}")
        for name in ("select", "search", "truncate", "max_se", "snap", "rise", "max_basin", "far_share"):
            if not getattr(self, name) > 0:
                raise ValueError(f"plane refinement {name} must be > 0, got {getattr(self, name)}")
        if self.steps < 5 or self.max_pixels < 100 or self.longitude_blocks < 2 or self.min_block_pixels < 1:
            raise ValueError(f"plane refinement steps {self.steps} must be >= 5, max_pixels {self.max_pixels} >= 100, "
                             f"longitude_blocks {self.longitude_blocks} >= 2, min_block_pixels "
                             f"{self.min_block_pixels} >= 1")
        if not 0 < self.min_cos < 1 or self.min_gradient < 0:
            raise ValueError(f"plane refinement min_cos must be in (0, 1) and min_gradient >= 0, got {self.min_cos} "
                             f"and {self.min_gradient}")


@dataclass(frozen=True)
class PlaneFit:
    """One plane's refinement (:func:`refine_plane`).

    Attributes:
        normal: (3,) world unit normal; offset_start: where the search started (metres along ``normal``, signed).
        offset_before: where the estimate had the plane: the mode of its selected pixels' offsets (metres).
        offset: the refined offset (metres; ``offset_before`` when not applied).
        se: the jackknife standard error of ``ln |offset|`` (inf when it could not be computed).
        pixels: the pixels searched; blocks: the jackknife's blocks.
        applied: whether :func:`snap_to_planes` uses it.
    """

    normal: tuple
    offset_start: float
    offset_before: float
    offset: float
    se: float
    pixels: int
    blocks: int
    applied: bool

    def record(self) -> dict:
        """JSON-able."""
        return {k: (list(v) if isinstance(v, tuple) else v) for k, v in asdict(self).items()}


def plane_offsets(distance: np.ndarray, bearings: np.ndarray, normal) -> np.ndarray:
    """(H, W) signed offset ``d (b . n)`` of each pixel's point from C along ``normal`` (metres; NaN where the
    distance is not finite)."""
    with np.errstate(invalid="ignore"):
        return np.asarray(distance, np.float64) * (bearings @ np.asarray(normal, np.float64))


def _pick(curve: np.ndarray, far_share: float) -> int:
    """The sample of ``curve`` (costs over offsets ascending in ``|offset|``) taken as the plane: of its local minima
    (after a [1, 2, 1] smoothing) within ``far_share`` of the least cost, the farthest.  Other surfaces near a room's
    plane lie on C's side of it (chair bases and mats above a floor, lamps below a ceiling, furniture before a wall),
    so a second minimum nearer than the plane is theirs."""
    c = np.convolve(np.pad(curve, 1, mode="edge"), [0.25, 0.5, 0.25], mode="valid")
    interior = np.flatnonzero((c[1:-1] <= c[:-2]) & (c[1:-1] <= c[2:])) + 1
    good = interior[c[interior] <= c.min() * (1.0 + far_share)]
    if good.size == 0:
        return int(np.argmin(curve))
    j = int(good.max())
    return max(j - 1, 0) + int(np.argmin(curve[max(j - 1, 0):j + 2]))


def _para(curve: np.ndarray, j: int) -> float:
    """Sub-step position of the minimum at sample ``j`` of ``curve`` (a parabola through it and its neighbours)."""
    if not 0 < j < curve.size - 1:
        return float(j)
    a, m, c = curve[j - 1:j + 2]
    den = a - 2.0 * m + c
    return float(j + (0.5 * (a - c) / den if den > 0 else 0.0))


def refine_plane(gray: dict, cameras: dict, bearings: np.ndarray, distance: np.ndarray, normal, offset_start: float,
                 params: PlaneRefineParams = PlaneRefineParams(), pairs=("U", "R")) -> PlaneFit:
    """Search one plane's offset from the images (see the module's docstring).

    Where the estimate has the plane (``offset_before``) is the mode of its pixels' offsets (0.2 % bins) within
    ``params.search`` of ``offset_start``; the search spans ``params.search`` either side of that mode, over the
    pixels within ``params.select`` of it whose gray gradient exceeds ``params.min_gradient`` (each pair's gray gain
    relative to C, the ratio of their medians there, is divided out).  Of the mean cost's local minima within
    ``params.far_share`` of the least, the farthest from C is the plane (surfaces near a room's plane lie on C's
    side of it: chair bases and mats above a floor, lamps below a ceiling).  It is applied when its jackknife
    standard error (each block of ``params.longitude_blocks`` sectors left out in turn, the same rule) is at most
    ``params.max_se`` and the candidates within ``params.rise`` of its cost reach at most ``params.max_basin`` from
    it on either side (a shallow basin: the images do not fix the offset, or two surfaces share it).

    Args:
        gray: (H, W) float32 gray image (0-255) per camera name (C and ``pairs``).
        cameras: pose per camera name (``position`` (3,) metres, ``rotation`` (3, 3) world-from-camera).
        bearings: (H, W, 3) C's unit bearings in world coordinates.
        distance: (H, W) C's current estimate, metres (non-finite: not used).
        normal: (3,) the plane's world unit normal; offset_start: its signed offset from C along it, metres, as
            another stage found it (non-zero).
    Returns:
        A :class:`PlaneFit` (``offset`` is ``offset_before`` when not applied).
    """
    normal = np.asarray(normal, np.float64)
    sign = 1.0 if offset_start > 0 else -1.0
    a_n = bearings @ normal
    with np.errstate(invalid="ignore", divide="ignore"):
        off = plane_offsets(distance, bearings, normal) * sign
        rel = np.log(np.where(off > 0, off, np.nan) / abs(offset_start))
    facing = (a_n * sign) > params.min_cos
    within = facing & (np.abs(rel) < params.search)
    mode = 0.0  # ln(offset_before / offset_start)
    if within.any():
        r = rel[within]
        edges = np.arange(-params.search, params.search + 0.002, 0.002)
        k = int(np.argmax(np.histogram(r, edges)[0]))
        mode = float(np.median(r[(r >= edges[k]) & (r < edges[k + 1])]))
    before = float(offset_start * np.exp(mode))
    g_c = gray["C"]
    gx, gy = sobel_gradient(g_c)
    near = facing & (np.abs(rel - mode) < params.select) & (np.hypot(gx, gy) > params.min_gradient)
    idx = np.flatnonzero(near.ravel())
    idx = idx[::max(1, -(-idx.size // params.max_pixels))]
    unapplied = PlaneFit(tuple(normal.tolist()), float(offset_start), before, before, float("inf"), int(idx.size), 0,
                         False)
    if idx.size < 10 * params.min_block_pixels:
        return unapplied
    b = bearings.reshape(-1, 3)[idx]
    along = a_n.reshape(-1)[idx]
    ref = g_c.reshape(-1)[idx].astype(np.float32)
    centre = np.asarray(cameras["C"].position, np.float64)
    grid = np.linspace(-params.search, params.search, params.steps)  # ln(offset / offset_before)
    ids, block = np.unique(sphere_blocks(b, params.longitude_blocks), return_inverse=True)
    sums = np.zeros((params.steps, ids.size))  # each block's summed cost per candidate
    counts = np.bincount(block, minlength=ids.size).astype(np.float64)
    gains = {}
    for i, x in enumerate(grid):
        points = centre + b * (before * np.exp(x) / along)[:, None]
        cost = np.zeros(idx.size, np.float32)
        for k in pairs:
            u, v = project(points, cameras[k].position, cameras[k].rotation, g_c.shape[1], g_c.shape[0])
            seen = sample_equirect(gray[k], u, v)
            if k not in gains:
                gains[k] = float(np.clip(np.median(ref) / max(float(np.median(seen)), 1e-3), 0.5, 2.0))
            cost += np.minimum(np.abs(seen * gains[k] - ref), params.truncate)
        sums[i] = np.bincount(block, weights=cost, minlength=ids.size)
    total = sums.sum(axis=1) / counts.sum()
    j = _pick(total, params.far_share)
    leave = np.flatnonzero(counts >= params.min_block_pixels)
    if not 1 <= j <= params.steps - 2 or leave.size < 4:  # at the search's edge, or too few blocks to judge
        return unapplied
    steps = np.arange(params.steps, dtype=np.float64)
    x_hat = float(np.interp(_para(total, j), steps, grid))
    est = np.array([float(np.interp(_para(c, _pick(c, params.far_share)), steps, grid))
                    for c in ((sums.sum(axis=1) - sums[:, q]) / (counts.sum() - counts[q]) for q in leave)])
    se = float(np.sqrt((est.size - 1) / est.size * np.sum((est - est.mean()) ** 2)))
    low = total <= total[j] * (1.0 + params.rise)  # the basin: contiguous with j, within ``rise`` of its cost
    first = j - int(np.argmin(low[j::-1])) if not low[:j + 1].all() else 0
    last = j + int(np.argmin(low[j:])) if not low[j:].all() else params.steps - 1
    applied = se <= params.max_se and max(grid[j] - grid[first], grid[last] - grid[j]) <= params.max_basin
    offset = before * float(np.exp(x_hat)) if applied else before
    return PlaneFit(tuple(normal.tolist()), float(offset_start), before, offset, se, int(idx.size), int(leave.size),
                    bool(applied))


def snap_to_planes(distance: np.ndarray, bearings: np.ndarray, fits, params: PlaneRefineParams = PlaneRefineParams(),
                   d_range=(0.0, np.inf)) -> np.ndarray:
    """Put the pixels the estimate places near each applied plane onto it.

    Args:
        distance: (H, W) C's estimate, metres.
        bearings: (H, W, 3) C's unit world bearings.
        fits: :class:`PlaneFit` per plane (those not applied are skipped), in order: a pixel near two planes takes
            the first's distance.
        d_range: (min, max) distances a snapped pixel may take, metres (others keep theirs).
    Returns:
        (H, W) float32: ``distance`` with the pixels within ``params.snap`` (relative) of a refined plane's offset or
        of its ``offset_before`` at ``offset / (b . n)``.
    """
    out = np.asarray(distance, np.float32).copy()
    done = np.zeros(out.shape, bool)
    for fit in fits:
        if not fit.applied:
            continue
        normal = np.asarray(fit.normal, np.float64)
        sign = 1.0 if fit.offset > 0 else -1.0
        a_n = (bearings @ normal) * sign
        off = plane_offsets(distance, bearings, normal) * sign
        with np.errstate(invalid="ignore", divide="ignore"):
            lo = np.log(np.where(off > 0, off, np.nan))
            new = abs(fit.offset) / a_n
        near = (np.abs(lo - np.log(abs(fit.offset))) < params.snap) | (np.abs(lo - np.log(abs(fit.offset_before)))
                                                                          < params.snap)
        take = near & (a_n > params.min_cos) & ~done & (new >= d_range[0]) & (new <= d_range[1])
        out[take] = new[take]
        done |= take
    return out


def onto_walls(distance: np.ndarray, bearings: np.ndarray, walls, params: PlaneRefineParams,
               ceiling: float | None = None) -> tuple[np.ndarray, list[dict]]:
    """Put the pixels the estimate places well beyond an enclosing wall on it.

    Nothing is seen through a room's wall, but a glossy one (a screen, a whiteboard, a lacquered door, a lab's
    cabinets) shows mirror images, and they match where the mirrored surfaces would be: beyond it.  A wall encloses
    when at most ``params.wall_max_share`` of the pixels facing it (the sine of their bearing's angle with it above
    ``params.min_cos``) lie more than ``params.wall_margin`` (relative) beyond it; those pixels are then put on it (a
    pixel beyond two walls on the nearer).  A wall with more beyond it (shelves in a library, a corridor's side
    wall with its openings) is left alone, unless it has at most ``params.closed_max_share`` beyond it and the
    ceiling stops at it: at most ``params.closed_ceiling_share`` of the ceiling's pixels facing it (their height
    within ``params.snap`` of ``ceiling``) lie beyond it.

    Args:
        distance: (H, W) C's estimate, metres (non-finite: left alone).
        bearings: (H, W, 3) C's unit world bearings.
        walls: per wall ``(normal, offset)``: (3,) world unit normal and signed offset from C along it, metres
            (:func:`reconstruction.sweep.planes.room_walls`).
        ceiling: the ceiling's height relative to C's centre, metres (None or <= 0: not known; only
            ``wall_max_share`` decides).
    Returns:
        The (H, W) float32 distance and per wall a record (``normal``, ``offset``, ``beyond_share``: the share of
        its facing pixels beyond it, ``applied``; ``ceiling_beyond_share``, the share of the ceiling's facing pixels
        beyond it, when it was asked).
    """
    d = np.asarray(distance, np.float64)
    out = d.copy()
    records = []
    ask_ceiling = ceiling is not None and ceiling > 0 and params.closed_max_share > params.wall_max_share
    ceiling_pixels = None  # made when a wall first asks for them
    for normal, offset in walls:
        normal = np.asarray(normal, np.float64)
        a_n = bearings @ normal
        with np.errstate(divide="ignore", invalid="ignore"):
            on_wall = offset / a_n
            facing = (on_wall > 0) & (np.abs(a_n) > params.min_cos)
            beyond = facing & (d > on_wall * (1.0 + params.wall_margin))
        share = float(beyond.sum() / max(int(facing.sum()), 1))
        applied = share <= params.wall_max_share
        record = {"normal": normal.tolist(), "offset": float(offset), "beyond_share": share}
        if not applied and ask_ceiling and share <= params.closed_max_share:
            if ceiling_pixels is None:
                ceiling_pixels = on_ceiling(d, bearings, ceiling, params.snap)
            ceiling_facing = ceiling_pixels & facing
            ceiling_share = float((ceiling_facing & beyond).sum() / max(int(ceiling_facing.sum()), 1))
            applied = ceiling_facing.any() and ceiling_share <= params.closed_ceiling_share
            record["ceiling_beyond_share"] = ceiling_share
        if applied:
            out = np.where(beyond & (on_wall < out), on_wall, out)
        records.append({**record, "applied": bool(applied)})
    return out.astype(np.float32), records


def on_ceiling(distance: np.ndarray, bearings: np.ndarray, height: float, tolerance: float) -> np.ndarray:
    """(H, W) bool: the pixels whose point lies at the ceiling's height, within ``tolerance`` of ``height`` (relative;
    ``height`` the ceiling's height relative to C's centre, metres, > 0; non-finite distances: not)."""
    d = np.asarray(distance, np.float64)
    with np.errstate(invalid="ignore"):
        return np.isfinite(d) & (np.abs(d * bearings[..., 2] - height) <= tolerance * abs(height))


def ceiling_walls(distance: np.ndarray, bearings: np.ndarray, height: float, normals: np.ndarray, quantile: float,
                  tolerance: float = 0.02, min_share: float = 0.001) -> list[tuple[np.ndarray, float]]:
    """Walls at the ceiling's edge: on each side of C along each normal, the offset within which ``quantile`` of the
    area of the ceiling seen on that side lies.

    Furniture hides a room's walls and a glossy cabinet's mirror images match beyond them, but the ceiling reaches
    the walls above both.  Its pixels are counted by the area they cover (a far pixel covers more of it: the
    pixel's solid angle times ``d^2 / |b_z|``), so that a long room's far ceiling, seen in a few pixels near the
    horizon, counts as much as its near ceiling: in a rectangular room whose ceiling is all seen the ``quantile``
    of its area along a normal lies ``1 - quantile`` of its length short of the wall.  Where the ceiling goes on
    through an opening the wall is put too far, which puts less on it.

    Args:
        distance: (H, W) C's estimate on an equirect grid, metres (non-finite: none).
        bearings: (H, W, 3) C's unit world bearings (z up).
        height: the ceiling's height relative to C's centre, metres (> 0).
        normals: (K, 3) horizontal world unit normals of the walls.
        quantile: in (0, 1].
        tolerance: a pixel is on the ceiling when its height is within this share of ``height``.
        min_share: a side needs at least this share of all pixels on the ceiling.
    Returns:
        Per side with enough ceiling pixels ``(normal, offset)``: (3,) the normal and the signed offset along it,
        metres, as :func:`reconstruction.sweep.planes.room_walls` gives walls.
    """
    d = np.asarray(distance, np.float64)
    b = np.asarray(bearings, np.float64)
    h, w = d.shape
    _, lat = pixel_to_lonlat(np.zeros((h, 1)), np.arange(h)[:, None], w, h)
    solid = np.broadcast_to(np.cos(lat), d.shape)  # each row's pixel solid angle, relative
    on = on_ceiling(d, b, height, tolerance)
    points = d[on][:, None] * b[on]
    area = solid[on] * d[on] ** 2 / np.abs(b[on][:, 2])
    need = max(1, int(np.ceil(min_share * d.size)))
    walls = []
    for normal in np.asarray(normals, np.float64):
        o = points @ normal
        for sign in (-1.0, 1.0):
            side = o * sign > 0
            if side.sum() >= need:
                order = np.argsort(o[side] * sign)
                cum = np.cumsum(area[side][order])
                k = min(int(np.searchsorted(cum, quantile * cum[-1])), order.size - 1)
                walls.append((normal, sign * float((o[side] * sign)[order][k])))
    return walls


#: the angular error, in pixels of the equirect map, that the ceiling's edge must be resolved to (a quarter pixel:
#: the accuracy the floor of tri360's reports assumes of an ideal matcher)
EDGE_RESOLUTION_PX = 0.25


def resolved_range(baseline_m: float, width: int, band: float) -> float:
    """The distance (m) within which an angular error of :data:`EDGE_RESOLUTION_PX` across a baseline of
    ``baseline_m`` (seen square on) moves a point by at most half of ``band`` (relative): ``band / 2 * baseline /
    (EDGE_RESOLUTION_PX * 2 pi / width)``; 7.6 m for 0.4 m, 1000 px and a 6 % band."""
    return 0.5 * band * baseline_m / (EDGE_RESOLUTION_PX * 2.0 * np.pi / width)


def onto_enclosing_walls(distance: np.ndarray, bearings: np.ndarray, walls, normals: np.ndarray | None,
                         ceiling: float | None, params: PlaneRefineParams,
                         max_edge_m: float = np.inf) -> tuple[np.ndarray, list[dict]]:
    """:func:`onto_walls` of the walls found and then, on each side of C along each wall normal where none of them
    encloses but one encloses the opposite side, of the wall at the ceiling's edge (:func:`ceiling_walls`,
    ``params.ceiling_edge``; a room's dominant surface on a side is often furniture in front of its wall, a bench's
    front, which encloses nothing).  Where neither side along a normal is enclosed (a corridor's two ends) the
    room's length is unknown; and a far ceiling, seen in a few pixels near the horizon, leaves the height band that
    counts its pixels where the rig no longer resolves it, so that its edge is found short of a far wall and would put
    that wall on it: an edge farther from C than ``max_edge_m`` (:func:`resolved_range`) is not used.

    Args:
        distance, bearings: as :func:`onto_walls`.
        walls: the walls found (:func:`reconstruction.sweep.planes.room_walls`), along ``normals``.
        normals: (2, 3) the walls' horizontal unit normals (None: no wall direction found, no ceiling's edge).
        ceiling: the ceiling's height relative to C's centre, metres (None: not found, no ceiling's edge, and only
            ``wall_max_share`` decides whether a wall found encloses).
        params: ``wall_margin`` (> 0), ``wall_max_share``, ``closed_max_share``, ``closed_ceiling_share``,
            ``min_cos``, ``ceiling_edge`` (0: not looked for) and
            ``snap`` (the pixels within it of the ceiling's height count as the ceiling's: those :func:`snap_to_planes`
            puts on a refined ceiling).
        max_edge_m: the farthest a ceiling's edge may lie from C (at the ceiling's height), metres.
    Returns:
        As :func:`onto_walls`; the ceiling's edges' records carry ``"from": "ceiling"``.
    """
    d, records = onto_walls(distance, bearings, walls, params, ceiling)
    if not (params.ceiling_edge > 0 and normals is not None and ceiling is not None and ceiling > 0):
        return d, records
    enclosed = [(np.asarray(r["normal"]), np.sign(r["offset"])) for r in records if r["applied"]]

    def found(n: np.ndarray, sign: float) -> bool:  # a wall found encloses that side
        return any(s == sign and float(m @ n) > 0.999 for m, s in enclosed)

    edges = [(n, o) for n, o in ceiling_walls(d, bearings, ceiling, normals, params.ceiling_edge, params.snap)
             if not found(n, np.sign(o)) and found(n, -np.sign(o)) and np.hypot(o, ceiling) <= max_edge_m]
    d, edge_records = onto_walls(d, bearings, edges, params)
    return d, records + [{**r, "from": "ceiling"} for r in edge_records]

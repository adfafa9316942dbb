"""The "horizontal plane at height h" label family (gravity = world -Z), indexing the sphere cost volume.

A pixel of C with world bearing ``a`` lies on the horizontal plane ``h`` metres above C's centre (negative =
below) at distance ``h / a_z`` when that is positive, i.e. at inverse distance ``a_z / h``.  The label's cost
is the sphere cost volume linearly interpolated at that inverse distance; where the plane is not in front of
the pixel or outside the hypothesis range, the cost is the maximum.  On a floor or ceiling the plane label is
*constant* across pixels while the sphere label changes with every row: SGM's smoothness then favours it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np

from reconstruction.camera.image_ops import central_differences

__all__ = ["add_prior", "PlaneParams", "WALL_YAWS", "plane_heights", "fill_plane_costs", "plane_inverse_distance",
           "bound_costs", "dominant_planes", "wall_normals", "dominant_wall_yaw", "densest_wall_yaw", "dominant_walls",
           "room_planes", "bound_wall_costs", "onto_room_planes", "room_plane_distance", "room_walls"]


#: how :func:`room_walls` finds the walls' yaw (``PlaneParams.wall_yaw``)
WALL_YAWS = ("normals", "offsets", "normals-or-offsets")


@dataclass(frozen=True)
class PlaneParams:
    """Parameters of the horizontal-plane family.

    Attributes:
        per_side: number of plane heights below C and as many above (0 = no plane family).
        h_min_m, h_max_m: smallest and largest |height| relative to C's centre, metres (heights are geometric
            between them).
        bias: cost added to every sphere label so that planes are slightly preferred, uint16 cost units.
        room_bound: find the floor and ceiling in a coarse pass and forbid labels below / above them (removes
            matches of mirror images in glossy floors).
        bound_margin: tolerance of the room bound, as a fraction of the floor's / ceiling's |height|.
        bound_penalty: 0: a sphere label beyond the room bound is forbidden.  > 0: it costs this many gray levels
            more instead, and a pixel whose winner still lies beyond the bound is put on the floor (the ceiling)
            the coarse pass found (:func:`onto_room_planes`): a polished floor's reflection of a lamp matches
            where its mirror image lies, below the floor, and that pixel shows the floor.
        bound_penalty_min_az: the penalty applies only at bearings whose world Z (the sine of their elevation) is
            at least this in magnitude; nearer the horizon a label beyond the bound stays forbidden and no pixel is
            put on the floor (the ceiling).  There the bound is crossed only far away (at 5.7 degrees, ten times
            the floor's depth below C), where a noisy camera's wrong match is likelier than a reflection.
        bound_min_share: share of pixels the floor (ceiling) plane must win in the coarse pass to be used.
        coarse_factor: the coarse pass runs on images this many times smaller.
        wall_labels: labels per wall (0 = no walls).  The coarse pass finds the room's two wall directions (at
            right angles) and, along each, the dominant wall on either side of C; each wall found becomes a label
            family of ``wall_labels`` parallel planes spanning its offset +- ``wall_spread``, so that a plain wall
            is one constant label, as a floor is.
        wall_spread: relative half-width of a wall's family (0.1 = offsets from 0.9 to 1.1 times the wall's).
        room_labels: labels for the floor and as many for the ceiling (0 = none).  The floor and the ceiling the
            coarse pass found (:func:`dominant_planes`) each become a family of ``room_labels`` parallel horizontal
            planes spanning its height +- ``room_spread`` (:func:`room_planes`): the plane family's heights are
            9.5 % apart, which puts a whole floor a few per cent off; these are 2.6 % apart with 17 labels and a
            spread of 0.2, and the winner's sub-label offset interpolates between them.
        room_spread: relative half-width of the floor's and the ceiling's families (0.2 = heights from 0.8 to 1.2
            times the one found: the coarse pass's floor can be a few per cent off).
        wall_min_share: share of the coarse pass's pixels a wall must cover to be used (and the normals' vote for
            the wall direction within 3 degrees must reach, with ``wall_yaw`` ``"normals"`` or
            ``"normals-or-offsets"``).
        wall_yaw: how the walls' yaw is found (:func:`room_walls`), for the coarse pass's wall labels and the
            wall step of :class:`reconstruction.refine.planes.PlaneRefineParams` alike: ``"normals"``, the
            surface normals' vote (:func:`dominant_wall_yaw`); ``"offsets"``, the yaw at which the four walls hold
            the most points (:func:`densest_wall_yaw`), which needs no normals and so holds on plain, noisy walls,
            but whose count is nearly flat over several degrees along a long corridor's walls;
            ``"normals-or-offsets"``: the vote, and where it finds no wall direction the offsets.
        mirror_tolerance: the coarse pass's floor (ceiling) is taken as the ceiling's (floor's) mirror image in a
            nearer plane when it lies within this fraction of its height of that image (:func:`dominant_planes`;
            0 = no test).
    """

    per_side: int = 32
    h_min_m: float = 0.3
    h_max_m: float = 5.0
    bias: int = 4
    room_bound: bool = True
    bound_margin: float = 0.25
    bound_penalty: float = 0.0
    bound_penalty_min_az: float = 0.0
    bound_min_share: float = 0.03
    coarse_factor: int = 2
    wall_labels: int = 0
    wall_spread: float = 0.1
    wall_min_share: float = 0.01
    wall_yaw: str = "normals"
    room_labels: int = 0
    room_spread: float = 0.2
    mirror_tolerance: float = 0.0

    def __post_init__(self) -> None:
        if self.wall_yaw not in WALL_YAWS:
            raise ValueError(f"plane wall_yaw must be one of {', '.join(WALL_YAWS)}, got {self.wall_yaw!r}")
        if not (np.isfinite(self.bound_penalty) and self.bound_penalty >= 0):
            raise ValueError(f"plane bound_penalty must be >= 0 (gray levels), got {self.bound_penalty}")
        if not (np.isfinite(self.bound_penalty_min_az) and 0 <= self.bound_penalty_min_az < 1):
            raise ValueError(f"plane bound_penalty_min_az must be in [0, 1) (sine of the elevation), got "
                             f"{self.bound_penalty_min_az}")


def plane_heights(params: PlaneParams) -> np.ndarray:
    """(2 * per_side,) float64 plane heights relative to C, metres: below C (ascending |h|), then above."""
    if params.per_side <= 0:
        return np.zeros(0)
    mag = np.geomspace(params.h_min_m, params.h_max_m, params.per_side)
    return np.concatenate([-mag, mag])


def wall_normals(yaw_rad: float) -> np.ndarray:
    """(2, 3) the two horizontal unit normals of walls at yaw ``yaw_rad`` and ``yaw_rad + 90 deg`` (world)."""
    c, s = np.cos(yaw_rad), np.sin(yaw_rad)
    return np.array([[c, s, 0.0], [-s, c, 0.0]])


def dominant_wall_yaw(points: np.ndarray, min_share: float, max_tilt_rad: float = 0.2,
                      step_px: int = 4) -> float | None:
    """The yaw of the room's walls (modulo 90 degrees) from a distance map's 3D points.

    Surface normals come from the points ``step_px`` pixels away in the equirect grid (wrapping in longitude;
    wide steps average out the stair steps of a label map); the normals
    within ``max_tilt_rad`` of horizontal vote for their yaw modulo 90 degrees (0.5-degree bins, weighted by
    their horizontality); the mode is refined by the circular mean of the votes within 3 degrees.

    Args:
        points: (H, W, 3) world points relative to C, metres (non-finite = none).
        min_share: the mode (within 3 degrees) must hold at least this share of the H*W pixels.
        max_tilt_rad: largest angle of a wall normal out of the horizontal plane, radians.
        step_px: half the baseline of the finite differences, pixels.
    Returns:
        The yaw in radians in [0, pi/2), or None when no wall direction is dominant.
    """
    p = np.asarray(points, np.float64)
    k = int(step_px)
    du, dv = central_differences(p, step=k, scale=1.0)
    n = np.cross(du, dv)
    norm = np.linalg.norm(n, axis=-1)
    with np.errstate(invalid="ignore", divide="ignore"):
        n = n / norm[..., None]
    tilt = np.abs(n[..., 2])
    ok = np.isfinite(tilt) & (norm > 0) & (tilt < np.sin(max_tilt_rad))
    if not ok.any():
        return None
    quarter = np.mod(np.arctan2(n[..., 1][ok], n[..., 0][ok]), np.pi / 2)
    weight = 1.0 - tilt[ok]
    bins = 180
    hist = np.bincount(np.minimum((quarter / (np.pi / 2) * bins).astype(np.int64), bins - 1), weight, bins)
    window = 6  # 3 degrees either side, circular
    smooth = sum(np.roll(hist, k) for k in range(-window, window + 1))
    mode = (np.argmax(smooth) + 0.5) * (np.pi / 2) / bins
    diff = np.angle(np.exp(4j * (quarter - mode))) / 4  # circular difference modulo 90 degrees
    near = np.abs(diff) <= np.radians(3.0)
    if near.sum() < min_share * points.shape[0] * points.shape[1]:
        return None
    return float(np.mod(mode + np.average(diff[near], weights=weight[near]), np.pi / 2))


def densest_wall_yaw(points: np.ndarray, max_points: int = 20000, step_deg: float = 2.0,
                     fine_deg: float = 0.2) -> float | None:
    """The yaw of the room's walls (modulo 90 degrees) at which the walls hold the most points, fitted to them.

    At the walls' yaw the points of each wall share their offset along its normal, whatever their normals (a plain
    wall's noisy or stair-stepped points vote for no direction, but they still lie at one offset).  For a yaw, on
    each side of C along each of the two normals, the densest window of three 2 % bins of log |offset| (0.3 to 100
    m; 6 %, the window :func:`room_walls` asks a wall to fill) holds some points; the yaw whose four windows hold the
    most is searched on a grid of ``step_deg`` over 90 degrees and then of ``fine_deg`` within one step of the best.
    Within a 6 % window a yaw a degree off still holds much of a wall, so the yaw is then fitted to the points of the
    four windows: the normal that minimises their summed squared distances to their walls' mean offsets (total least
    squares with one direction shared by the walls at right angles).

    Args:
        points: (H, W, 3) world points relative to C, metres (non-finite = none).
        max_points: at most this many of the finite points are used (evenly strided).
        step_deg, fine_deg: the two grids' spacing, degrees.
    Returns:
        The yaw in radians in [0, pi/2), or None when no point is finite.
    """
    p = np.asarray(points).reshape(-1, 3)
    p = p[np.isfinite(p).all(axis=1)]
    if p.shape[0] == 0:
        return None
    xy = np.ascontiguousarray(p[::max(1, -(-p.shape[0] // max_points)), :2], dtype=np.float32)
    coarse = np.radians(np.arange(0.0, 90.0, step_deg))
    best = coarse[int(np.argmax(_wall_mass(xy, coarse)[0]))]
    fine = best + np.radians(np.arange(-step_deg, step_deg + 1e-9, fine_deg))
    mass, first = _wall_mass(xy, fine)
    k = int(np.argmax(mass))
    # each window's points about their mean, those along the second normal turned by -90 degrees onto the first
    scatter = np.zeros((2, 2))
    turns = (np.eye(2), np.array([[0.0, 1.0], [-1.0, 0.0]]))
    for i, normal in enumerate(wall_normals(fine[k])[:, :2]):
        offset = xy.astype(np.float64) @ normal
        with np.errstate(divide="ignore"):
            b = np.floor((np.log(np.abs(offset)) - _LOG_OFFSET_MIN) / _LOG_OFFSET_BIN)
        for side in (0, 1):
            start = first[k + i * fine.size, side]
            q = xy[((offset < 0) == bool(side)) & (b >= start) & (b <= start + 2)].astype(np.float64) @ turns[i].T
            if q.shape[0]:
                scatter += (q - q.mean(axis=0)).T @ (q - q.mean(axis=0))
    if not np.trace(scatter) > 0:  # no window holds two points apart: the grid's yaw
        return float(np.mod(fine[k], np.pi / 2))
    normal = np.linalg.eigh(scatter)[1][:, 0]
    return float(np.mod(np.arctan2(normal[1], normal[0]), np.pi / 2))


_LOG_OFFSET_MIN, _LOG_OFFSET_BIN = np.log(0.3), 0.02
_LOG_OFFSET_BINS = int(np.ceil((np.log(100.0) - _LOG_OFFSET_MIN) / _LOG_OFFSET_BIN))


def _wall_mass(xy: np.ndarray, yaws: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per yaw (radians) the points in the densest three bins of log |offset| on each side of C along each of the
    yaw's two wall normals.

    Args:
        xy: (N, 2) horizontal world points, metres.
        yaws: (Y,) radians.
    Returns:
        ``(mass, first)``: (Y,) those points' number summed over the four sides, and (2Y, 2) per normal (the first
        normals of the Y yaws, then the second ones) per side (positive offsets, then negative) the window's first
        bin (``floor((ln |offset| - ln 0.3) / 0.02)``).
    """
    c, s = np.cos(yaws), np.sin(yaws)
    normals = np.concatenate([np.stack([c, s]), np.stack([-s, c])], axis=1).astype(np.float32)  # (2, 2Y)
    offset = xy @ normals  # (N, 2Y)
    with np.errstate(divide="ignore"):
        k = ((np.log(np.maximum(np.abs(offset), 1e-6)) - _LOG_OFFSET_MIN) / _LOG_OFFSET_BIN).astype(np.int64)
    ok = (k >= 0) & (k < _LOG_OFFSET_BINS)
    m = offset.shape[1]
    index = (np.arange(m) * (2 * _LOG_OFFSET_BINS))[None, :] + (offset < 0) * _LOG_OFFSET_BINS + k
    hist = np.bincount(index[ok], minlength=m * 2 * _LOG_OFFSET_BINS).reshape(m, 2, _LOG_OFFSET_BINS)
    window = hist[..., :-2] + hist[..., 1:-1] + hist[..., 2:]
    per_normal = window.max(axis=2).sum(axis=1)  # (2Y,)
    return per_normal[:yaws.size] + per_normal[yaws.size:], window.argmax(axis=2)


def room_walls(points: np.ndarray, min_share: float,
               yaw_from: str = "normals") -> tuple[float | None, list[tuple[np.ndarray, float]]]:
    """The room's dominant walls from a distance map's 3D points.

    The walls' yaw comes from :func:`dominant_wall_yaw` (``yaw_from`` ``"normals"``), :func:`densest_wall_yaw`
    (``"offsets"``) or the first and, where it finds no wall direction, the second (``"normals-or-offsets"``);
    along each of the two wall normals every point has an offset (``point . normal``), and the points of a wall
    share theirs, however plain the wall (where the points are noisy, their normals are useless but their offsets
    still cluster); on each side of C the mode of the offsets beyond 0.3 m (2 % bins of log |offset|, refined by the
    median within 4 %) is a wall if it holds at least ``min_share`` of the pixels.

    Args:
        points: (H, W, 3) world points relative to C, metres (non-finite = none).
        min_share: share of the pixels a wall must hold (and the normals' vote for the wall direction within 3
            degrees reach).
        yaw_from: ``"normals"``, ``"offsets"`` or ``"normals-or-offsets"`` (:data:`WALL_YAWS`).
    Returns:
        ``(yaw, walls)``: the yaw (radians, None if no wall direction is dominant) and per wall found
        ``(normal, offset)``: (3,) world unit normal and the signed offset along it, metres.
    """
    if yaw_from not in WALL_YAWS:
        raise ValueError(f"room_walls yaw_from must be one of {', '.join(WALL_YAWS)}, got {yaw_from!r}")
    yaw = None if yaw_from == "offsets" else dominant_wall_yaw(points, min_share)
    if yaw is None and yaw_from != "normals":
        yaw = densest_wall_yaw(points)
    if yaw is None:
        return None, []
    p = np.asarray(points, np.float64)
    finite = np.isfinite(p).all(axis=-1)
    walls = []
    need = min_share * p.shape[0] * p.shape[1]
    for normal in wall_normals(yaw):
        o = (p @ normal)[finite]
        for sign in (-1.0, 1.0):
            side = o[(o * sign) > 0.3] * sign
            if side.size < need:
                continue
            logs = np.log(side)
            hist, edges = np.histogram(logs, bins=np.arange(logs.min(), logs.max() + 0.04, 0.02))
            smooth = np.convolve(hist, np.ones(3), mode="same")
            mode = 0.5 * (edges[np.argmax(smooth)] + edges[np.argmax(smooth) + 1])
            near = np.abs(logs - mode) <= 0.04
            if near.sum() < need:
                continue
            walls.append((normal, sign * float(np.exp(np.median(logs[near])))))
    return yaw, walls


def dominant_walls(points: np.ndarray, params: PlaneParams) -> tuple[float | None, list[tuple[np.ndarray, np.ndarray]]]:
    """The room's dominant walls (:func:`room_walls`, ``params.wall_min_share`` and ``params.wall_yaw``) as label
    families.

    Args:
        points: (H, W, 3) world points relative to C, metres (non-finite = none).
        params: ``wall_labels``, ``wall_spread``, ``wall_min_share``, ``wall_yaw``.
    Returns:
        ``(yaw, walls)``: the yaw (radians, None if no wall direction is dominant) and per wall found
        ``(normal, offsets)``: (3,) world unit normal and (wall_labels,) signed offsets along it, metres,
        ascending |offset| (``|o| * geomspace(1 - spread, 1 + spread)``).
    """
    if params.wall_labels <= 0:
        return None, []
    yaw, walls = room_walls(points, params.wall_min_share, params.wall_yaw)
    scale = np.geomspace(1.0 - params.wall_spread, 1.0 + params.wall_spread, params.wall_labels)
    return yaw, [(normal, offset * scale) for normal, offset in walls]


#: the world's up direction (gravity = -Z)
UP = np.array([0.0, 0.0, 1.0])


def room_planes(z_floor: float, z_ceiling: float, params: PlaneParams) -> list[tuple[np.ndarray, np.ndarray]]:
    """The floor and the ceiling as label families, in the form of :func:`dominant_walls`' walls.

    Args:
        z_floor, z_ceiling: their heights relative to C's centre, metres (non-finite = not found: no family).
        params: ``room_labels``, ``room_spread``.
    Returns:
        Per plane found (the floor first) ``(UP, offsets)``: (room_labels,) signed heights, metres, ascending |h|
        (``h * geomspace(1 - room_spread, 1 + room_spread)``); none without ``room_labels``.
    """
    if params.room_labels <= 0:
        return []
    scale = np.geomspace(1.0 - params.room_spread, 1.0 + params.room_spread, params.room_labels)
    return [(UP, float(z) * scale) for z in (z_floor, z_ceiling) if np.isfinite(z)]


def plane_inverse_distance(a_z: np.ndarray, heights: np.ndarray) -> np.ndarray:
    """Inverse distance (1/m) of each plane along bearings with world up component ``a_z``: ``a_z / h``.

    Args:
        a_z: (...) world Z component of unit bearings; heights: (P,) metres.
    Returns:
        (..., P) float64 (<= 0 where the plane is behind the ray).
    """
    return np.asarray(a_z, np.float64)[..., None] / heights


@numba.njit(parallel=True, cache=True)
def _fill(cost, levels, first, a_z, heights, q0, dq, max_cost):
    h, w, _ = cost.shape
    n_p = heights.shape[0]
    for y in numba.prange(h):
        for x in range(w):
            az = a_z[y, x]
            for p in range(n_p):
                f = (az / heights[p] - q0) / dq
                if f < 0.0 or f > levels - 1:
                    cost[y, x, first + p] = max_cost
                else:
                    i0 = min(int(f), levels - 2)
                    t = f - i0
                    c = (1.0 - t) * cost[y, x, i0] + t * cost[y, x, i0 + 1]
                    cost[y, x, first + p] = np.uint16(c + 0.5)


@numba.njit(parallel=True, cache=True)
def _add_bias(cost, levels, bias, cap):
    h, w, _ = cost.shape
    for y in numba.prange(h):
        for x in range(w):
            for i in range(levels):
                c = np.int64(cost[y, x, i]) + bias
                cost[y, x, i] = np.uint16(cap if c > cap else c)


def fill_plane_costs(cost: np.ndarray, levels: int, a_z: np.ndarray, heights: np.ndarray, inv_d: np.ndarray,
                     max_cost: int, bias: int, walls: list[tuple[np.ndarray, np.ndarray]] = ()) -> None:
    """Fill the plane labels ``cost[..., levels:]`` in place from the sphere labels, then add the plane bias.

    Args:
        cost: (H, W, levels + P + sum Q_k) uint16 cost volume with the sphere labels filled.
        levels: number of sphere labels; a_z: (H, W) world Z of C's bearings; heights: (P,) metres.
        inv_d: (levels,) inverse distances of the sphere labels (uniform), 1/m.
        max_cost: cost of a plane label that does not apply at a pixel, uint16 units.
        bias: added to every sphere label (capped at 65535), uint16 units.
        walls: per wall family ``(a_n, offsets)``: (H, W) component of C's world bearings along the wall's normal
            and its (Q_k,) signed offsets, metres (:func:`dominant_walls`); their labels follow the horizontal
            planes, in this order.
    """
    q0 = float(inv_d[0])
    dq = float(inv_d[1] - inv_d[0])
    families = [(np.asarray(a_z), np.asarray(heights))] if heights.size else []
    families += [(a_n, np.asarray(offsets)) for a_n, offsets in walls]
    first = levels
    for axis, offsets in families:
        _fill(cost, levels, first, np.ascontiguousarray(axis, np.float64), offsets.astype(np.float64), q0, dq,
              np.uint16(max_cost))
        first += offsets.size
    if families and bias > 0:
        _add_bias(cost, levels, int(bias), 65535)


@numba.njit(parallel=True, cache=True)
def _bound(cost, levels, a_z, inv_d, heights, z_low, z_high, max_cost, penalty, min_az):
    h, w, _ = cost.shape
    for y in numba.prange(h):
        for x in range(w):
            az = a_z[y, x]
            soft = penalty > 0 and abs(az) >= min_az
            for i in range(levels):
                z = az / inv_d[i]
                if z < z_low or z > z_high:
                    if soft:
                        cost[y, x, i] = min(np.int64(cost[y, x, i]) + penalty, max_cost)
                    else:
                        cost[y, x, i] = max_cost
            for p in range(heights.shape[0]):  # the horizontal planes only (wall labels follow them)
                if heights[p] < z_low or heights[p] > z_high:
                    cost[y, x, levels + p] = max_cost


def bound_costs(cost: np.ndarray, levels: int, a_z: np.ndarray, inv_d: np.ndarray, heights: np.ndarray,
                z_low: float, z_high: float, max_cost: int, penalty: int = 0, min_az: float = 0.0) -> None:
    """Forbid (set to ``max_cost``) every label whose point lies below ``z_low`` or above ``z_high``, or, with
    ``penalty`` > 0, add that much to each such sphere label's cost (at most ``max_cost``) at the pixels whose
    ``|a_z| >= min_az`` (the plane labels beyond, and every label beyond nearer the horizon, stay forbidden).

    The room bound: nothing is seen below the floor or above the ceiling, but a glossy floor's mirror image of
    the ceiling lights is (a virtual point at ``2 z_floor - z_light``).  Forbidding those labels removes the
    reflection matches, and the reflection's pixels then take whatever label is cheapest among the rest (often a
    nearer one: the blob is flat inside, its edges are the lamp's).  A penalty keeps a match beyond the bound that
    is clearly better than any inside it, so that :func:`onto_room_planes` can put it on the floor.

    Args:
        cost: (H, W, levels + P) uint16, modified in place.
        a_z: (H, W) world Z of C's unit bearings; inv_d: (levels,) 1/m; heights: (P,) metres relative to C.
        z_low, z_high: heights relative to C's centre, metres (use -inf / inf for no bound).
        penalty: uint16 cost units added to a sphere label beyond the bound (0: forbidden).
        min_az: smallest ``|a_z|`` (sine of the elevation) at which the penalty replaces the ban.
    """
    _bound(cost, levels, np.ascontiguousarray(a_z, np.float64), inv_d.astype(np.float64),
           heights.astype(np.float64), float(z_low), float(z_high), np.int64(max_cost), np.int64(penalty),
           float(min_az))


def room_plane_distance(a_z: np.ndarray, planes: tuple[float, float]) -> np.ndarray:
    """Distance along C's bearings to the floor (bearings pointing down) or the ceiling (up).

    Args:
        a_z: (H, W) world Z of C's unit bearings; planes: ``(z_floor, z_ceiling)``, heights relative to C, metres
            (``z_floor < 0 < z_ceiling``; -inf / inf: not found).
    Returns:
        (H, W) float32 metres; inf where the bearing is horizontal or its plane was not found.
    """
    a_z = np.asarray(a_z, np.float64)
    with np.errstate(invalid="ignore", divide="ignore"):
        d = np.where(a_z < 0, planes[0] / a_z, np.where(a_z > 0, planes[1] / a_z, np.inf))
    return np.where(np.isfinite(d) & (d > 0), d, np.inf).astype(np.float32)


def onto_room_planes(distance: np.ndarray, a_z: np.ndarray, bounds: tuple[float, float],
                     planes: tuple[float, float], min_az: float = 0.0) -> tuple[np.ndarray, float]:
    """Put every pixel whose point lies beyond the room bound on the floor or the ceiling (only where
    ``|a_z| >= min_az``).

    Args:
        distance: (H, W) metres along C's bearings; a_z: (H, W) world Z of those unit bearings.
        bounds: ``(z_low, z_high)``, the room bound's heights relative to C, metres (-inf / inf: none).
        planes: ``(z_floor, z_ceiling)``, the heights the pixels below ``z_low`` / above ``z_high`` are put on,
            metres (on C's side of the bound: ``z_low <= z_floor < 0 < z_ceiling <= z_high``).
        min_az: smallest ``|a_z|`` (sine of the elevation) of a pixel that is moved.
    Returns:
        The (H, W) float32 distance (a new array) and the share of pixels moved.
    """
    with np.errstate(invalid="ignore", divide="ignore"):
        z = distance * a_z
        steep = np.abs(a_z) >= min_az
        below, above = (z < bounds[0]) & steep, (z > bounds[1]) & steep
        out = np.where(below, planes[0] / a_z, np.where(above, planes[1] / a_z, distance))
    return out.astype(np.float32), float((below | above).mean())


@numba.njit(parallel=True, cache=True)
def _bound_walls(cost, first, a_z, a_n, offsets, z_low, z_high, max_cost):
    h, w, _ = cost.shape
    n_p = offsets.shape[0]
    for y in numba.prange(h):
        for x in range(w):
            az = a_z[y, x]
            an = a_n[y, x]
            for p in range(n_p):
                d = offsets[p] / an if an != 0.0 else -1.0
                if d > 0.0:
                    z = az * d
                    if z < z_low or z > z_high:
                        cost[y, x, first + p] = max_cost


def bound_wall_costs(cost: np.ndarray, first: int, a_z: np.ndarray, a_n: np.ndarray, offsets: np.ndarray,
                     z_low: float, z_high: float, max_cost: int) -> None:
    """The room bound for one wall family: forbid each wall label whose point lies below ``z_low`` or above
    ``z_high`` (a wall's mirror image in a glossy floor lies below it).

    Args:
        cost: (H, W, L) uint16, modified in place; first: index of the family's first label.
        a_z, a_n: (H, W) world Z and wall-normal components of C's unit bearings; offsets: (Q,) metres.
        z_low, z_high: heights relative to C's centre, metres.
    """
    _bound_walls(cost, int(first), np.ascontiguousarray(a_z, np.float64), np.ascontiguousarray(a_n, np.float64),
                 offsets.astype(np.float64), float(z_low), float(z_high), np.uint16(max_cost))


def _mode_height(sel: np.ndarray, centre: float, heights: np.ndarray) -> float:
    """|height| (m) of the labels within one label of ``centre`` on one side: their median, interpolated in log |h|
    between the side's (per,) ``heights``."""
    near = sel[np.abs(sel - centre) <= 1.0]
    return float(np.exp(np.interp(np.median(near), np.arange(heights.size), np.log(np.abs(heights)))))


def dominant_planes(label: np.ndarray, levels: int, heights: np.ndarray, min_share: float,
                    mirror_tolerance: float = 0.0):
    """Floor and ceiling heights: the most frequent winning plane label below and above C.

    A polished floor shows the ceiling's mirror image at ``2 z_floor - z_ceiling``: on a plain glossy floor that
    virtual plane can win more pixels than the floor itself.  With ``mirror_tolerance > 0`` a side's mode is
    replaced by a plane nearer to C on the same side (its own labels winning at least ``min_share``) when the
    mode lies within ``mirror_tolerance * |mode|`` of the other side's mirror image in that nearer plane; of
    several such planes, the one winning the most pixels.  The floor is checked against the ceiling found, then
    the ceiling against the (checked) floor.

    Args:
        label: (H, W) fractional winning labels (plane labels from ``levels`` on).
        heights: (P,) plane heights, metres (below C first, then above, as :func:`plane_heights`).
        min_share: a side's mode must win at least this share of all pixels to count (the mode and its two
            neighbouring labels together).
        mirror_tolerance: relative tolerance of the mirror test (0 = no test).
    Returns:
        ``(z_floor, z_ceiling)`` metres relative to C (-inf / inf where none is dominant); each is the median
        height of the pixels within one label of the mode (sub-level heights interpolated in log |h|).
    """
    per = heights.size // 2
    if per == 0:
        return -np.inf, np.inf
    p = label.ravel() - levels
    min_count = min_share * label.size
    sides = []  # per side: (labels on the side relative to its first, window counts, mode) or None
    out = []
    for side, sign in ((0, -1.0), (1, 1.0)):
        lo = side * per
        sel = p[(p >= lo - 0.5) & (p < lo + per - 0.5)] - lo
        if sel.size == 0:
            sides.append(None)
            out.append(sign * np.inf)
            continue
        counts = np.bincount(np.clip(np.rint(sel).astype(np.int64), 0, per - 1), minlength=per)
        window = np.convolve(counts, np.ones(3, np.int64), mode="same")  # label k and its two neighbours
        mode = int(np.argmax(counts))
        if window[mode] < min_count:
            sides.append(None)
            out.append(sign * np.inf)
            continue
        sides.append((sel, window, mode))
        out.append(sign * _mode_height(sel, mode, heights[lo:lo + per]))
    if mirror_tolerance > 0:
        for side in (0, 1):
            other = out[1 - side]
            if sides[side] is None or not np.isfinite(other):
                continue
            sel, window, mode = sides[side]
            side_heights = heights[side * per:(side + 1) * per]
            sign = -1.0 if side == 0 else 1.0
            best = None
            for k in range(mode - 2):  # nearer planes whose windows do not overlap the mode's
                if window[k] < min_count or (best is not None and window[k] <= window[best[0]]):
                    continue
                z = sign * _mode_height(sel, k, side_heights)
                if abs(2.0 * z - other - out[side]) <= mirror_tolerance * abs(out[side]):
                    best = (k, z)
            if best is not None:
                out[side] = best[1]
    return out[0], out[1]


@numba.njit(parallel=True, cache=True)
def _prior(cost, levels, label_prior, weight, trunc, cap):
    h, w, _ = cost.shape
    for y in numba.prange(h):
        for x in range(w):
            lp = label_prior[y, x]
            wt = weight[y, x]
            if wt <= 0.0 or not np.isfinite(lp):
                continue
            for i in range(levels):
                c = np.float32(cost[y, x, i]) + wt * min(abs(i - lp), trunc)
                cost[y, x, i] = np.uint16(min(c + 0.5, cap))


def add_prior(cost: np.ndarray, levels: int, inv_d: np.ndarray, prior_m: np.ndarray, weight: np.ndarray,
              truncate_levels: float, cap: int) -> None:
    """Add a prior distance map's evidence to the sphere labels, in place (before the plane labels are filled).

    Label ``i`` of pixel p gets ``weight(p) * min(|i - l(p)|, truncate_levels)``, ``l(p)`` the fractional sphere
    label of the prior's inverse distance.

    Args:
        cost: (H, W, levels + P) uint16 cost volume; inv_d: (levels,) uniform inverse distances, 1/m.
        prior_m: (H, W) prior distances, metres (non-finite / non-positive = no prior).
        weight: (H, W) float32 cost units per label of distance to the prior (0 = no prior).
        truncate_levels: largest penalised label distance, labels.
        cap: largest stored cost, uint16 units.
    """
    with np.errstate(divide="ignore", invalid="ignore"):
        q = 1.0 / np.asarray(prior_m, np.float64)
    lab = (q - inv_d[0]) / (inv_d[1] - inv_d[0])
    lab = np.where(np.isfinite(lab) & (q > 0), np.clip(lab, 0.0, levels - 1.0), np.nan).astype(np.float32)
    _prior(cost, levels, lab, np.ascontiguousarray(weight, np.float32), np.float32(truncate_levels), np.float32(cap))

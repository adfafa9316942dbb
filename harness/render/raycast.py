"""Exact synthetic frames without Blender: a vectorised numpy ray-caster for box, cylinder and sphere scenes.

A :class:`scenes.model.SceneSpec` made of boxes (each oriented by a yaw about +Z), capped cylinders and spheres
is intersected analytically, so the distance maps are exact up to float64 rounding (then stored as float32,
like Cycles).
The room shell (``Box.inward=True``) is an ordinary closed box whose faces are seen from inside; solid
boxes occlude.  The first surface along a ray wins, whichever side of it the ray comes from.

Appearance is deliberately simple and **view-independent**, so the three cameras of a rig see exactly
the same colour at the same surface point:

* albedo: a procedural *solid* texture evaluated at the 3-D hit point (hash-based lattice value noise,
  multi-octave, seeded by the material name), shaped per ``Material.kind`` (see ``TEXTURES``);
* shading: Lambertian irradiance from the spec's lights (no shadows, no speculars) plus a constant
  ambient term; ``emission`` materials are self-lit.

Colour is anti-aliased by supersampling (``ss x ss`` sub-pixel rays averaged in linear RGB, then
sRGB-encoded); the distance map comes from the pixel-centre ray only, as Cycles' Z pass does.

Units: metres, radians, linear RGB in [0, 1]; light power in watts (Blender's convention: a point light
of power P has intensity P / (4 pi) W/sr, an area light P cos(theta) / pi W/sr toward -Z).
"""

from __future__ import annotations

import zlib
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from harness.data.frame import Frame
from harness.render.base import BaseRenderer, RenderSettings, srgb_encode
from reconstruction.camera.equirect import bearing_grid, pixel_to_bearing
from reconstruction.camera.rig import CameraPose, Rig, yaw_rotation
from scenes.model import Box, Cylinder, Material, SceneSpec, Sphere

__all__ = ["ENGINE", "AMBIENT", "RaycastRenderer", "raycast", "shade", "render_camera", "render_frame",
           "value_noise", "fbm", "TEXTURES"]

ENGINE = "tri360-raycast"
AMBIENT = 0.15
"""Ambient irradiance term, in the same units as ``E / pi`` (E the light irradiance, W/m^2)."""
CHUNK_RAYS = 1 << 17
"""Rays handled at once (bounds the peak memory: a few hundred bytes per ray)."""
FINEST_FEATURE_M = 0.015
"""Finest noise wavelength, metres (~1 px at 3 m in a 1000 x 500 equirect): finer detail only aliases."""
MAX_OCTAVES = 7
_T_EPS = 1e-12  # metres; hits closer than this to the ray origin are ignored


# --------------------------------------------------------------------------------------------- geometry


@dataclass(frozen=True)
class _BoxGeom:
    """A box prepared for intersection: centre (3,), half extents (3,), world-from-box rotation, normal sign."""

    center: np.ndarray
    half: np.ndarray
    rot: np.ndarray  # (3, 3) world-from-box: yaw_rotation(box.yaw)
    normal_sign: float  # +1: normals point out of the box (solid); -1: into it (room shell)

    @classmethod
    def of(cls, box: Box) -> _BoxGeom:
        return cls(np.asarray(box.center, dtype=np.float64), np.asarray(box.size, dtype=np.float64) / 2.0,
                   yaw_rotation(box.yaw), -1.0 if box.inward else 1.0)

    @property
    def cos(self) -> float:
        return float(self.rot[0, 0])

    @property
    def sin(self) -> float:
        return float(self.rot[1, 0])

    def to_local(self, v: np.ndarray) -> np.ndarray:
        """World vectors (N, 3) -> box-local axes (N, 3) (rotate by -yaw; no translation)."""
        return v @ self.rot

    def to_world(self, v: np.ndarray) -> np.ndarray:
        """Box-local vectors (N, 3) -> world (rotate by +yaw; no translation)."""
        return v @ self.rot.T


def _face_of(g: _BoxGeom, points: np.ndarray) -> np.ndarray:
    """Face index of points (N, 3) lying on the surface of box ``g``: (N,) int8 ``2 * axis + side``.

    The face is the local axis along which the point is (relatively) farthest out, ``|p_local| / half``
    being 1 on that face and at most 1 on the others (ties only on edges, where either face is right).
    """
    rel = g.to_local(points - g.center)
    axis = np.argmax(np.abs(rel) / g.half, axis=1)
    side = rel[np.arange(len(rel)), axis] > 0
    return (2 * axis + side).astype(np.int8)


def _slab_t(g: _BoxGeom, lo, ld, inv) -> np.ndarray:
    """Fast slab test (ray parameter only) in the box's local frame.

    Args:
        lo: local origin, 3 entries, each a scalar or an (N,) array, metres.
        ld: local directions, 3 (N,) arrays (only their count is used, via ``inv``).
        inv: 3 (N,) arrays 1 / ld (zero components replaced by a tiny number).
    Returns:
        (N,) ray parameter of the first surface crossing with ``t > 0``, +inf if none.
    """
    t_near = t_far = None
    for k in range(3):
        a = (-g.half[k] - lo[k]) * inv[k]
        b = (g.half[k] - lo[k]) * inv[k]
        lo_k = np.minimum(a, b)
        hi_k = np.maximum(a, b, out=b)
        t_near = lo_k if t_near is None else np.maximum(t_near, lo_k, out=t_near)
        t_far = hi_k if t_far is None else np.minimum(t_far, hi_k, out=t_far)
    miss = t_near > t_far
    t = np.where(t_near > _T_EPS, t_near, t_far)
    t[miss | (t <= _T_EPS)] = np.inf
    return t


def _safe_inv(v: np.ndarray) -> np.ndarray:
    """1 / v with exact zeros replaced by 1e-300 (parallel rays: huge finite slab times, never NaN)."""
    return 1.0 / np.where(v == 0.0, 1e-300, v)


def _first_root(a: np.ndarray, b: np.ndarray, c: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Both roots of ``a t^2 + 2 b t + c = 0`` (N,) each, (+inf, +inf) where there is none (or a == 0)."""
    disc = b * b - a * c
    ok = (disc >= 0.0) & (a > 0.0)
    sq = np.sqrt(np.where(ok, disc, 0.0))
    a_safe = np.where(ok, a, 1.0)
    t1 = np.where(ok, (-b - sq) / a_safe, np.inf)
    t2 = np.where(ok, (-b + sq) / a_safe, np.inf)
    return t1, t2


def _nearest(*candidates: np.ndarray) -> np.ndarray:
    """Element-wise smallest candidate parameter above ``_T_EPS`` (+inf if none): (N,)."""
    best = np.full(candidates[0].shape, np.inf)
    for t in candidates:
        good = (t > _T_EPS) & (t < best)
        best[good] = t[good]
    return best


def _sphere_t(sph: Sphere, o: np.ndarray, d: np.ndarray) -> np.ndarray:
    """First hit parameter (N,) of rays o + t d (o (3,) or (N, 3), d (N, 3)) with a sphere (either side)."""
    oc = o - np.asarray(sph.center, np.float64)
    a = np.einsum("ij,ij->i", d, d)
    b = (d @ oc) if oc.ndim == 1 else np.einsum("ij,ij->i", d, oc)
    c = (np.dot(oc, oc) if oc.ndim == 1 else np.einsum("ij,ij->i", oc, oc)) - sph.radius ** 2
    return _nearest(*_first_root(a, b, np.broadcast_to(c, a.shape)))


def _cylinder_t(cyl: Cylinder, o: np.ndarray, d: np.ndarray) -> np.ndarray:
    """First hit parameter (N,) of rays with a capped cylinder (its side or either cap, from either side)."""
    frame = cyl.frame()
    lo = (o - np.asarray(cyl.center, np.float64)) @ frame  # local: axis = third coordinate
    ld = d @ frame
    lo = np.broadcast_to(lo, ld.shape)
    half, r2 = cyl.length / 2.0, cyl.radius ** 2
    a = ld[:, 0] ** 2 + ld[:, 1] ** 2
    b = lo[:, 0] * ld[:, 0] + lo[:, 1] * ld[:, 1]
    c = lo[:, 0] ** 2 + lo[:, 1] ** 2 - r2
    out = []
    for t in _first_root(a, b, c):
        z = lo[:, 2] + np.where(np.isfinite(t), t, 0.0) * ld[:, 2]
        out.append(np.where(np.abs(z) <= half, t, np.inf))
    inv = _safe_inv(ld[:, 2])
    with np.errstate(over="ignore", invalid="ignore"):  # rays parallel to the caps: huge t, never a hit
        for zc in (-half, half):
            t = (zc - lo[:, 2]) * inv
            x, y = lo[:, 0] + t * ld[:, 0], lo[:, 1] + t * ld[:, 1]
            out.append(np.where((x * x + y * y <= r2) & np.isfinite(t), t, np.inf))
    return _nearest(*out)


def _round_face(shape, points: np.ndarray) -> np.ndarray:
    """Face index (N,) int8 of points on a cylinder (0 side, 1 the -axis cap, 2 the +axis cap) or sphere (0)."""
    if isinstance(shape, Sphere):
        return np.zeros(len(points), np.int8)
    local = (points - np.asarray(shape.center)) @ shape.frame()
    on_cap = np.abs(local[:, 2]) / (shape.length / 2.0) > np.hypot(local[:, 0], local[:, 1]) / shape.radius
    return np.where(on_cap, np.where(local[:, 2] > 0, 2, 1), 0).astype(np.int8)


def _round_normals(shape, points: np.ndarray, face: np.ndarray) -> np.ndarray:
    """Outward unit world normals (N, 3) at points on a cylinder or sphere (faces from :func:`_round_face`)."""
    rel = points - np.asarray(shape.center)
    if isinstance(shape, Sphere):
        return rel / np.maximum(np.linalg.norm(rel, axis=1, keepdims=True), 1e-12)
    frame = shape.frame()
    local = rel @ frame
    n = np.zeros_like(local)
    side = face == 0
    rad = np.maximum(np.hypot(local[side, 0], local[side, 1]), 1e-12)
    n[side, 0], n[side, 1] = local[side, 0] / rad, local[side, 1] / rad
    n[~side, 2] = np.where(face[~side] == 2, 1.0, -1.0)
    return n @ frame.T


def raycast(spec: SceneSpec, origins, directions, chunk: int = CHUNK_RAYS):
    """Intersect rays with every shape of ``spec`` and return the first hit.

    Args:
        spec: the scene (its boxes, cylinders and spheres: ``spec.shapes()``).
        origins: (3,) (one origin for all rays, the fast path) or (N, 3) ray origins, world metres.
        directions: (N, 3) ray directions, world; need not be unit.
        chunk: rays processed at once.
    Returns:
        ``(t, box_index, face_index, points)``:
        ``t`` (N,) float64 ray parameter of the first hit (the distance in metres when the directions are
        unit; +inf where nothing is hit); ``box_index`` (N,) int32 index into ``spec.shapes()`` (boxes first,
        so for a box scene an index into ``spec.boxes``; -1: no hit); ``face_index`` (N,) int8: for a box
        ``2 * axis + side`` in the box's local frame (axis 0 = x, 1 = y, 2 = z; side 1 = the + face), for a
        cylinder 0 (side), 1 (cap at -axis), 2 (cap at +axis), for a sphere 0; -1 for no hit; ``points``
        (N, 3) float64 world hit points (NaN for no hit).
    """
    d = np.asarray(directions, dtype=np.float64).reshape(-1, 3)
    o = np.asarray(origins, dtype=np.float64)
    single = o.shape == (3,)
    if not single:
        o = np.broadcast_to(o.reshape(-1, 3), d.shape)
    n = len(d)
    geoms = [_BoxGeom.of(b) for b in spec.boxes]
    round_shapes = [*spec.cylinders, *spec.spheres]
    t_all = np.full(n, np.inf)
    box_all = np.full(n, -1, dtype=np.int32)
    face_all = np.full(n, -1, dtype=np.int8)
    for s in range(0, n, chunk):
        dc = d[s:s + chunk]
        oc = o if single else o[s:s + chunk]
        dcols = (dc[:, 0].copy(), dc[:, 1].copy(), dc[:, 2].copy())
        inv_world = None  # 1 / direction, shared by every unrotated box
        t_best = t_all[s:s + chunk]
        box_best = box_all[s:s + chunk]
        for k, g in enumerate(geoms):
            rel = oc - g.center
            if g.sin == 0.0 and g.cos == 1.0:
                if inv_world is None:
                    inv_world = tuple(_safe_inv(c) for c in dcols)
                inv = inv_world
                lo = tuple(rel[..., i] for i in range(3))
            else:
                c, sn = g.cos, g.sin
                inv = (_safe_inv(c * dcols[0] + sn * dcols[1]), _safe_inv(-sn * dcols[0] + c * dcols[1]),
                       inv_world[2] if inv_world is not None else _safe_inv(dcols[2]))
                lo = (c * rel[..., 0] + sn * rel[..., 1], -sn * rel[..., 0] + c * rel[..., 1], rel[..., 2])
            t = _slab_t(g, lo, dcols, inv)
            closer = t < t_best
            t_best[closer] = t[closer]
            box_best[closer] = k
        for k, shape in enumerate(round_shapes, start=len(geoms)):
            t = (_sphere_t if isinstance(shape, Sphere) else _cylinder_t)(shape, oc, dc)
            closer = t < t_best
            t_best[closer] = t[closer]
            box_best[closer] = k
    points = np.full((n, 3), np.nan)
    hit = box_all >= 0
    points[hit] = (o if single else o[hit]) + t_all[hit, None] * d[hit]
    for k, g in enumerate(geoms):  # the face of the winning shape, from the hit point
        sel = np.flatnonzero(box_all == k)
        if len(sel):
            face_all[sel] = _face_of(g, points[sel])
    for k, shape in enumerate(round_shapes, start=len(geoms)):
        sel = np.flatnonzero(box_all == k)
        if len(sel):
            face_all[sel] = _round_face(shape, points[sel])
    return t_all, box_all, face_all, points


# --------------------------------------------------------------------------------------------- noise

_P1, _P2, _P3 = np.uint32(0x8DA6B343), np.uint32(0xD8163841), np.uint32(0xCB1AB31F)


def _seed_of(name: str) -> int:
    """Deterministic 32-bit seed from a string (crc32, stable across processes, unlike ``hash``)."""
    return zlib.crc32(name.encode("utf-8")) & 0xFFFFFFFF


def _mix(h: np.ndarray) -> np.ndarray:
    """32-bit integer finaliser (lowbias32): uint32 array -> well-mixed uint32 array."""
    h = h ^ (h >> np.uint32(16))
    h = h * np.uint32(0x7FEB352D)
    h = h ^ (h >> np.uint32(15))
    h = h * np.uint32(0x846CA68B)
    return h ^ (h >> np.uint32(16))


def _lattice(i: np.ndarray) -> np.ndarray:
    """int64 lattice coordinates -> uint32 (two's complement wrap)."""
    return (i & 0xFFFFFFFF).astype(np.uint32)


def value_noise(q: np.ndarray, seed: int) -> np.ndarray:
    """3-D value noise: random values on the integer lattice, quintic-smoothed trilinear interpolation.

    Args:
        q: (N, 3) coordinates in lattice units (one unit = one feature).
        seed: 32-bit integer.
    Returns:
        (N,) float32 in [0, 1), continuous, deterministic in ``(q, seed)``.
    """
    f = np.floor(q)
    w = (q - f).astype(np.float32)
    w = w * w * w * (w * (w * np.float32(6) - np.float32(15)) + np.float32(10))
    i = f.astype(np.int64)
    # corner hash: mix(x * P1 ^ y * P2 ^ mix(z * P3 ^ seed)); the z part is mixed once per z-corner
    hx0 = _lattice(i[:, 0]) * _P1
    hy0 = _lattice(i[:, 1]) * _P2
    hz = _lattice(i[:, 2]) * _P3
    sd = np.uint32(seed & 0xFFFFFFFF)
    mz0, mz1 = _mix(hz ^ sd), _mix((hz + _P3) ^ sd)
    hx1, hy1 = hx0 + _P1, hy0 + _P2
    scale = np.float32(1.0 / 4294967296.0)

    def val(hx, hy, mz):
        return _mix(hx ^ hy ^ mz).astype(np.float32) * scale

    wx, wy, wz = w[:, 0], w[:, 1], w[:, 2]
    x00 = val(hx0, hy0, mz0)
    x00 += wx * (val(hx1, hy0, mz0) - x00)
    x10 = val(hx0, hy1, mz0)
    x10 += wx * (val(hx1, hy1, mz0) - x10)
    x01 = val(hx0, hy0, mz1)
    x01 += wx * (val(hx1, hy0, mz1) - x01)
    x11 = val(hx0, hy1, mz1)
    x11 += wx * (val(hx1, hy1, mz1) - x11)
    x00 += wy * (x10 - x00)
    x01 += wy * (x11 - x01)
    return x00 + wz * (x01 - x00)


def fbm(q: np.ndarray, seed: int, octaves: int, gain: float = 0.5) -> np.ndarray:
    """Fractal sum of ``octaves`` value-noise layers (frequency x2, amplitude x ``gain`` per octave).

    Args:
        q: (N, 3) coordinates in units of the largest feature.
    Returns:
        (N,) float32 signed noise, zero mean, clipped to [-1, 1], standard deviation ~0.45 for any
        octave count (the sum is normalised by its theoretical standard deviation).
    """
    total = np.zeros(len(q), dtype=np.float32)
    amp, var = 1.0, 0.0
    for k in range(max(1, int(octaves))):
        # per-octave seed and a fixed irrational offset so lattices of successive octaves do not align
        layer_seed = int(_mix(np.uint32([(seed + k) & 0xFFFFFFFF]))[0])
        total += np.float32(amp) * (value_noise(q * (2.0 ** k) + 0.37 * k, layer_seed) - np.float32(0.5))
        var += amp * amp
        amp *= gain
    # one value-noise layer has std ~0.20 about 0.5 (quintic-smoothed lattice of U(0,1) values)
    return np.clip(total * np.float32(0.45 / (0.20 * np.sqrt(var))), -1.0, 1.0)


def _octaves(feature_m: float) -> int:
    """Octave count so that the finest layer has a wavelength of about ``FINEST_FEATURE_M``."""
    return int(np.clip(np.ceil(np.log2(max(feature_m, 1e-6) / FINEST_FEATURE_M)) + 1, 1, MAX_OCTAVES))


# --------------------------------------------------------------------------------------------- textures


@dataclass(frozen=True)
class SurfacePoints:
    """Hit points on one box, as the texture functions see them.

    Attributes:
        q: (N, 3) texture coordinates, metres: the hit point in the box's own axes, translated back to the
            box centre (equal to world coordinates for an unrotated box), so textures move with the box.
        face_axis: (N,) int local axis (0, 1, 2) normal to the face hit.
    """

    q: np.ndarray
    face_axis: np.ndarray

    def tangent(self) -> tuple[np.ndarray, np.ndarray]:
        """The two in-face coordinates (N,), (N,) (metres), e.g. (x, y) on a floor."""
        a = self.face_axis
        u = np.where(a == 0, self.q[:, 1], self.q[:, 0])
        v = np.where(a == 2, self.q[:, 1], self.q[:, 2])
        return u, v


def _mix_colors(m: Material, t: np.ndarray) -> np.ndarray:
    """Blend ``color`` (t = 0) toward ``secondary`` (t = 1): (N,) -> (N, 3) linear RGB."""
    c1, c2 = np.asarray(m.color, np.float32), np.asarray(m.secondary, np.float32)
    return c1 + t[:, None].astype(np.float32) * (c2 - c1)


def _modulate(m: Material, n: np.ndarray, amplitude: float) -> np.ndarray:
    """``color * (1 + amplitude * n)`` for signed noise n (N,) in [-1, 1] -> (N, 3), never negative."""
    gain = np.maximum(1.0 + np.float32(amplitude) * n, 0.0)
    return np.asarray(m.color, np.float32) * gain[:, None]


def _tex_paint(m: Material, s: SurfacePoints, seed: int) -> np.ndarray:
    """Painted wall: faint brightness noise of amplitude ``contrast``, blob size ``scale``."""
    return _modulate(m, fbm(s.q / m.scale, seed, _octaves(m.scale)), m.contrast)


def _tex_noise(m: Material, s: SurfacePoints, seed: int) -> np.ndarray:
    """Strong multi-scale noise: colour mixed toward ``color2``, brightness varied, both by ``contrast``."""
    oct_ = _octaves(m.scale)
    n1 = fbm(s.q / m.scale, seed, oct_, gain=0.6)
    n2 = fbm(s.q / (0.37 * m.scale), seed ^ 0x5BD1E995, max(1, oct_ - 1), gain=0.6)
    t = np.clip(0.5 + 0.9 * n1, 0.0, 1.0) * np.float32(m.contrast)
    return _mix_colors(m, t) * np.maximum(1.0 + np.float32(0.6 * m.contrast) * n2, 0.0)[:, None]


def _tex_board(m: Material, s: SurfacePoints, seed: int) -> np.ndarray:
    """Black/white board: near uniform (a quarter of ``contrast`` as faint smudges)."""
    return _modulate(m, fbm(s.q / m.scale, seed, 2), 0.25 * m.contrast)


def _tex_wood(m: Material, s: SurfacePoints, seed: int) -> np.ndarray:
    """Wood: growth rings about the box's local x axis, spacing ``scale``, warped by noise, plus fibres."""
    q = s.q
    warp = fbm(q * np.array([0.8, 4.0, 4.0]) / (10 * m.scale), seed, 3)
    r = np.hypot(q[:, 1], q[:, 2] + 0.5) / m.scale + 1.5 * warp
    ring = np.float32(0.5) - np.float32(0.5) * np.cos(np.float32(2 * np.pi) * r.astype(np.float32))
    fibre = fbm(q * np.array([0.15, 3.0, 3.0]) / max(m.scale, 0.02), seed ^ 0x68E31DA4, 3)
    t = np.clip(ring ** 3 + 0.25 * fibre, 0.0, 1.0) * np.float32(m.contrast)
    return _mix_colors(m, t) * np.maximum(1.0 + np.float32(0.3 * m.contrast) * fibre, 0.0)[:, None]


def _tex_tiles(m: Material, s: SurfacePoints, seed: int) -> np.ndarray:
    """Tiles of size ``scale`` with grout lines (``color2``, 4% of a tile wide) and per-tile tint."""
    u, v = s.tangent()
    gu, gv = u / m.scale, v / m.scale
    iu, iv = np.floor(gu), np.floor(gv)
    grout_half = 0.02
    fu, fv = gu - iu, gv - iv
    grout = (np.minimum(fu, 1 - fu) < grout_half) | (np.minimum(fv, 1 - fv) < grout_half)
    tile_id = _mix(_lattice(iu.astype(np.int64)) * _P1 ^ _lattice(iv.astype(np.int64)) * _P2
                   ^ np.uint32(seed))
    tint = (tile_id.astype(np.float32) / np.float32(4294967296.0) - 0.5) * 2.0  # [-1, 1)
    speckle = fbm(s.q / (0.25 * m.scale), seed, _octaves(0.25 * m.scale))
    c = _modulate(m, 0.35 * tint + 0.65 * speckle, m.contrast)
    grout_c = np.asarray(m.secondary, np.float32)
    return np.where(grout[:, None], grout_c, c) if m.contrast > 0 else c


TEXTURES: dict[str, Callable[[Material, SurfacePoints, int], np.ndarray]] = {
    "paint": _tex_paint,
    "wood": _tex_wood,
    "tiles": _tex_tiles,
    "board": _tex_board,
    "noise": _tex_noise,
}
"""Texture function per ``Material.kind``: ``(material, points, seed) -> (N, 3)`` linear albedo.
Kinds not listed (fabric, metal, plastic, glass, emission) use noise with amplitude ``contrast``."""


def _fallback(m: Material, s: SurfacePoints, seed: int) -> np.ndarray:
    return _modulate(m, fbm(s.q / m.scale, seed, _octaves(m.scale)), m.contrast)


def albedo(material: Material, points: SurfacePoints) -> np.ndarray:
    """Linear RGB albedo (N, 3) float32 of ``material`` at the given surface points.

    A material with ``contrast == 0`` is exactly uniform (``color``): no texture at all.
    """
    if material.contrast <= 0:
        return np.broadcast_to(np.asarray(material.color, np.float32), (len(points.q), 3)).copy()
    fn = TEXTURES.get(material.kind, _fallback)
    return np.clip(fn(material, points, _seed_of(material.name)), 0.0, None).astype(np.float32, copy=False)


# --------------------------------------------------------------------------------------------- shading


def _irradiance(spec: SceneSpec, points: np.ndarray, normals: np.ndarray) -> np.ndarray:
    """Light arriving at surface points, as ``(ambient + E / pi)`` per RGB channel: (N, 3) float32.

    Args:
        points: (N, 3) world hit points, metres.  normals: (N, 3) unit world normals.
    E is the irradiance (W/m^2) from every light, no shadows: point lights radiate P/(4 pi) W/sr evenly,
    area lights P cos(theta)/pi W/sr into the lower hemisphere (facing -Z, treated as a point at their
    position), "sun" lights give ``power`` W/m^2 from straight above.
    """
    out = np.full((len(points), 3), AMBIENT, dtype=np.float32)
    for light in spec.lights:
        col = np.asarray(light.color, np.float32)
        if light.kind == "sun":
            e = float(light.power) * np.clip(normals[:, 2], 0.0, None)
        else:
            to_l = np.asarray(light.position, np.float64) - points
            r2 = np.maximum(np.einsum("ij,ij->i", to_l, to_l), 1e-6)
            r = np.sqrt(r2)
            cos_s = np.clip(np.einsum("ij,ij->i", normals, to_l) / r, 0.0, None)
            if light.kind == "area":
                intensity = float(light.power) / np.pi * np.clip(to_l[:, 2] / r, 0.0, None)
            else:
                intensity = float(light.power) / (4.0 * np.pi)
            e = intensity * cos_s / r2
        out += (e / np.pi).astype(np.float32)[:, None] * col
    return out


def shade(spec: SceneSpec, points: np.ndarray, box_index: np.ndarray, face_index: np.ndarray) -> np.ndarray:
    """View-independent linear RGB radiance at ray hits.

    Args:
        points: (N, 3) world hit points, metres; box_index, face_index: (N,) from :func:`raycast` (indices into
            ``spec.shapes()``).
    Returns:
        (N, 3) float32 linear RGB (``spec.background`` where nothing is hit).  Depends only on the hit point
        and its face, never on the ray, so every camera sees the same colour at the same surface point.
    """
    out = np.broadcast_to(np.asarray(spec.background, np.float32), (len(points), 3)).copy()
    for k, box in enumerate(spec.boxes):
        sel = np.flatnonzero(box_index == k)
        if not len(sel):
            continue
        g = _BoxGeom.of(box)
        p = points[sel]
        face = face_index[sel].astype(np.int64)
        axis, side = face // 2, face % 2
        q = g.to_local(p - g.center) + g.center
        mat = spec.materials[box.material]
        a = albedo(mat, SurfacePoints(q=q, face_axis=axis))
        if mat.kind == "emission":
            out[sel] = a * np.float32(max(mat.emission, 1.0))
            continue
        n_local = np.zeros((len(sel), 3))
        n_local[np.arange(len(sel)), axis] = np.where(side == 1, 1.0, -1.0) * g.normal_sign
        out[sel] = a * _irradiance(spec, p, g.to_world(n_local))
    for k, shape in enumerate([*spec.cylinders, *spec.spheres], start=len(spec.boxes)):
        sel = np.flatnonzero(box_index == k)
        if not len(sel):
            continue
        p = points[sel]
        normals = _round_normals(shape, p, face_index[sel])
        rot = yaw_rotation(getattr(shape, "yaw", 0.0))
        q = (p - np.asarray(shape.center)) @ rot + np.asarray(shape.center)  # the shape's own (yaw) axes
        axis = np.argmax(np.abs(normals @ rot), axis=1)
        mat = spec.materials[shape.material]
        a = albedo(mat, SurfacePoints(q=q, face_axis=axis))
        out[sel] = (a * np.float32(max(mat.emission, 1.0)) if mat.kind == "emission"
                    else a * _irradiance(spec, p, normals))
    return out


# --------------------------------------------------------------------------------------------- rendering


def render_camera(spec: SceneSpec, position, rotation, width: int, supersample: int = 2,
                  chunk: int = CHUNK_RAYS) -> tuple[np.ndarray, np.ndarray]:
    """Render one equirectangular camera.

    Args:
        position: (3,) camera centre, metres.  rotation: (3, 3) world-from-camera.
        width: image width W in pixels (height H = W // 2).
        supersample: ss; colour averages ss x ss sub-pixel rays per pixel (ss = 1: the centre ray only).
    Returns:
        ``(image, distance)``: (H, W, 3) uint8 sRGB and (H, W) float32 Euclidean distance (metres) from the
        camera centre to the surface through each pixel centre, +inf where nothing is hit.
    """
    if width <= 0 or width % 2:
        raise ValueError(f"width must be a positive even number, got {width}")
    ss = int(supersample)
    if ss < 1:
        raise ValueError(f"supersample must be >= 1, got {supersample}")
    w, h = int(width), int(width) // 2
    pos = np.asarray(position, dtype=np.float64)
    rot = np.asarray(rotation, dtype=np.float64)

    # distance: pixel-centre rays, exact
    d = bearing_grid(w, h, rot).reshape(-1, 3)  # (H*W, 3) unit world bearings, 24 bytes per pixel
    t, _, _, _ = raycast(spec, pos, d, chunk=chunk)
    distance = (t * np.linalg.norm(d, axis=1)).astype(np.float32).reshape(h, w)
    del d, t

    # colour: ss x ss stratified sub-pixel rays, averaged in linear RGB
    offs = (np.arange(ss) + 0.5) / ss - 0.5
    sub = np.stack(np.meshgrid(offs, offs, indexing="ij"), axis=-1).reshape(-1, 2)  # (ss^2, [dv, du])
    image = np.empty((h, w, 3), dtype=np.uint8)
    rows_per = max(1, chunk // (w * ss * ss))
    for r0 in range(0, h, rows_per):
        r1 = min(h, r0 + rows_per)
        d = _bearings(w, h, rot, r0, r1, sub).reshape(-1, 3)
        _, box, face, pts = raycast(spec, pos, d, chunk=chunk)
        rgb = shade(spec, pts, box, face).reshape(r1 - r0, w, len(sub), 3).mean(axis=2)
        image[r0:r1] = srgb_encode(rgb)
    return image, distance


def _bearings(w: int, h: int, rot: np.ndarray, r0: int, r1: int, sub: np.ndarray) -> np.ndarray:
    """World bearings for rows [r0, r1) with sub-pixel offsets ``sub`` (S, 2) = (dv, du) in pixels.

    Returns (r1 - r0, W, S, 3) float64 unit vectors.
    """
    v, u = np.mgrid[r0:r1, 0:w]
    uu = u[:, :, None] + sub[None, None, :, 1]
    vv = v[:, :, None] + sub[None, None, :, 0]
    return pixel_to_bearing(uu, vv, w, h) @ rot.T


class RaycastRenderer(BaseRenderer):
    """The numpy ray-caster as a :class:`harness.render.base.BaseRenderer` (boxes, cylinders, spheres; exact
    distance).

    Uses ``settings.width`` and ``settings.supersample``; the Cycles settings do not apply.
    """

    name = "raycast"
    description = ("numpy ray-caster: boxes, cylinders, spheres; exact distance, simple view-independent shading, "
                   "no Blender")
    pixel_settings = ("width", "supersample")

    @classmethod
    def unsupported(cls, spec: SceneSpec) -> str | None:
        if spec.models:
            names = ", ".join(str(m.path) for m in spec.models)
            return (f"it places {len(spec.models)} external model file(s) ({names}) and the ray-caster draws "
                    "boxes only, plus cylinders and spheres (use --renderer cycles)")
        used = {s.material for s in spec.shapes()}
        glass = sorted(n for n, m in spec.materials.items() if m.kind == "glass" and n in used)
        if glass:
            return (f"material(s) {', '.join(glass)} are transparent glass, which the ray-caster cannot draw "
                    "(use --renderer cycles)")
        return None

    def render_camera(self, name: str, pose: CameraPose) -> tuple[np.ndarray, np.ndarray]:
        return render_camera(self.spec, pose.position, pose.rotation, self.settings.width,
                             self.settings.supersample)

    def engine(self) -> dict:
        return {"engine": ENGINE, "ambient": AMBIENT,
                "shading": "Lambertian irradiance from every light (no shadows) + ambient; emission self-lit",
                "distance": ("analytic ray-box/cylinder/sphere intersection through the pixel centre (float64, "
                             "stored float32)")}


def render_frame(spec: SceneSpec, rig: Rig, width: int, scene_name: str, viewpoint: str,
                 supersample: int = 2) -> Frame:
    """Ray-cast the three cameras C, U, R of ``rig`` in ``spec`` into a complete :class:`Frame`.

    A convenience over :class:`RaycastRenderer` (which builds once and renders several rigs).

    Args:
        spec: the scene (boxes, materials, lights).
        rig: the rig placement.
        width: W in pixels (H = W / 2).
        scene_name, viewpoint: names recorded in the frame (its directory levels).
        supersample: ss x ss colour rays per pixel.
    Returns:
        A frame with images (H, W, 3) uint8 sRGB, distance (H, W) float32 metres (+inf: no hit), poses,
        and ``renderer`` provenance (:func:`harness.render.base.provenance`).
    Raises:
        UserError: the spec places model files or glass (scene-model shapes only here).
        ValueError: the spec or the settings are invalid.
    """
    with RaycastRenderer(spec, RenderSettings(width=int(width), supersample=int(supersample))) as renderer:
        return renderer.render(rig, scene_name, viewpoint)

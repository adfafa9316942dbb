"""The shared randomisation kit of the room families: one piece of code for materials, lighting and furniture.

Not a family itself (files starting with ``_`` are not registered); every family's ``code_version`` includes this
file, so editing it marks every family's frames as out of date.

Everything random takes a ``numpy.random.Generator``.  :func:`streams` splits a family's ``seed`` into
independent streams (layout, look), so that adding a draw to the materials or lights never moves the furniture.

Units: metres, radians, linear RGB in [0, 1], watts, kelvin.  World Z up, floor at z = 0.

- Materials: :func:`draw_color` (HSV ranges -> linear RGB), :func:`draw_contrast` (texture levels from none to
  strong), :func:`draw_material`, :func:`vary_material` (randomise around a preset's look).
- Lighting: :func:`kelvin_to_rgb` (colour temperature -> linear Rec.709), :func:`draw_light_color`,
  :func:`ceiling_panels` (visible emissive panels, each with an invisible area light under it),
  :func:`add_window` (daylight: an emissive pane set into a wall, sky-coloured, with an invisible daylight
  fill light just inside it).
- Geometry: :func:`room_shell`, :func:`place` (parts given in a local frame -> world), :func:`grid`,
  :func:`row`, :func:`scatter` (random non-overlapping discs), furniture parts (:func:`table_parts`,
  :func:`chair_parts`, :func:`round_table_parts`, :func:`stool_parts`).
"""

from __future__ import annotations

import colorsys
from collections.abc import Iterable, Sequence
from dataclasses import replace

import numpy as np

from reconstruction.camera.rig import yaw_rotation
from scenes.model import Box, Cylinder, Light, Material, SceneSpec, Sphere, param

__all__ = ["CONTRAST_LEVELS", "streams", "uniform", "draw_color", "draw_contrast", "draw_material", "vary_material",
           "kelvin_to_rgb", "draw_light_color", "ceiling_panels", "add_window", "room_shell", "place", "grid",
           "row", "scatter", "table_parts", "chair_parts", "round_table_parts", "stool_parts"]

Range = float | tuple[float, float]

CONTRAST_LEVELS: dict[str, tuple[float, float]] = {
    "none": (0.0, 0.0), "weak": (0.03, 0.12), "medium": (0.2, 0.45), "strong": (0.6, 1.0)}
"""Texture contrast (``Material.contrast``) ranges by level: ``none`` is a uniform, texture-less surface."""


def streams(seed: int, n: int = 2) -> list[np.random.Generator]:
    """``n`` independent generators from one seed (``[layout, look, ...]``), stable across numpy versions."""
    return [np.random.default_rng([int(seed), k]) for k in range(n)]


def uniform(rng: np.random.Generator, value: Range) -> float:
    """A number drawn uniformly from ``(lo, hi)``, or ``value`` itself when it is a number."""
    if isinstance(value, int | float):
        return float(value)
    lo, hi = value
    return float(rng.uniform(lo, hi)) if hi > lo else float(lo)


# ------------------------------------------------------------------------------------------------ materials


def srgb_to_linear(c: np.ndarray) -> np.ndarray:
    """sRGB-encoded values in [0, 1] -> linear RGB (the inverse of the sRGB transfer function)."""
    c = np.asarray(c, dtype=np.float64)
    return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)


def draw_color(rng: np.random.Generator, hue: Range = (0.0, 1.0), saturation: Range = (0.0, 0.3),
               value: Range = (0.5, 0.9)) -> tuple[float, float, float]:
    """A colour drawn in HSV (hue in turns, saturation and value of the sRGB-encoded colour, all in [0, 1]),
    returned as linear RGB (3 floats)."""
    h, s, v = uniform(rng, hue) % 1.0, uniform(rng, saturation), uniform(rng, value)
    return tuple(float(x) for x in srgb_to_linear(colorsys.hsv_to_rgb(h, s, v)))


def draw_contrast(rng: np.random.Generator, levels: Sequence[str] = ("none", "weak", "medium", "strong"),
                  weights: Sequence[float] | None = None) -> float:
    """A texture contrast: a level picked from ``levels`` (``CONTRAST_LEVELS``; optional ``weights``), then a
    value uniform in its range."""
    p = None if weights is None else np.asarray(weights, float) / np.sum(weights)
    level = levels[int(rng.choice(len(levels), p=p))]
    return uniform(rng, CONTRAST_LEVELS[level])


def draw_material(rng: np.random.Generator, name: str, kind: str = "paint", *, hue: Range = (0.0, 1.0),
                  saturation: Range = (0.0, 0.3), value: Range = (0.5, 0.9), contrast: Range | None = None,
                  roughness: Range = (0.4, 0.9), scale: Range = (0.1, 0.5), darker: Range = (0.4, 0.7),
                  emission: float = 0.0) -> Material:
    """A material of ``kind`` with every appearance parameter drawn from its range.

    Args:
        hue, saturation, value: the base colour (see :func:`draw_color`).
        contrast: texture amplitude range; ``None`` draws a level with :func:`draw_contrast`.
        roughness: specular roughness (0 = mirror-like gloss, 1 = matte).
        scale: texture feature size, metres.
        darker: the secondary colour (grain, grout, smudges) is the base colour times this factor.
    """
    color = draw_color(rng, hue, saturation, value)
    k = uniform(rng, darker)
    return Material(name, kind=kind, color=color, color2=tuple(k * c for c in color), scale=uniform(rng, scale),
                    contrast=draw_contrast(rng) if contrast is None else uniform(rng, contrast),
                    roughness=uniform(rng, roughness), emission=emission)


def vary_material(rng: np.random.Generator, m: Material, amount: float = 1.0, *, color: float = 0.12,
                  contrast: float = 0.5, roughness: float = 0.15) -> Material:
    """``m`` randomised around its own look: brightness and each channel scaled by up to +-``color``, contrast
    scaled by a factor in [1 - contrast, 1 + contrast] (a texture-less material stays texture-less), roughness
    shifted by up to +-``roughness``; every amplitude times ``amount`` (0 returns ``m`` unchanged)."""
    if amount <= 0:
        return m
    gain = (1.0 + amount * color * rng.uniform(-1, 1)) * (1.0 + 0.5 * amount * color * rng.uniform(-1, 1, 3))
    c1 = tuple(float(np.clip(c * g, 0.0, 1.0)) for c, g in zip(m.color, gain, strict=True))
    c2 = tuple(float(np.clip(c * g, 0.0, 1.0)) for c, g in zip(m.secondary, gain, strict=True))
    k = 1.0 + amount * contrast * rng.uniform(-1, 1)
    r = m.roughness + amount * roughness * rng.uniform(-1, 1)
    return replace(m, color=c1, color2=c2, contrast=float(np.clip(m.contrast * k, 0.0, 1.0)),
                   roughness=float(np.clip(r, 0.02, 1.0)))


# ------------------------------------------------------------------------------------------------- lighting


def kelvin_to_rgb(kelvin: float) -> tuple[float, float, float]:
    """Colour of a black body at ``kelvin`` (1667-25000 K) as linear Rec.709 RGB, brightest channel = 1.

    The Planckian locus in CIE 1931 xy (Kim et al.'s cubic spline, as in the CIE's tables to ~1e-3), Y = 1,
    converted to linear sRGB primaries (D65) and clipped at 0.
    """
    t = float(np.clip(kelvin, 1667.0, 25000.0))
    if t <= 4000:
        x = -0.2661239e9 / t ** 3 - 0.2343589e6 / t ** 2 + 0.8776956e3 / t + 0.179910
    else:
        x = -3.0258469e9 / t ** 3 + 2.1070379e6 / t ** 2 + 0.2226347e3 / t + 0.240390
    if t <= 2222:
        y = -1.1063814 * x ** 3 - 1.34811020 * x ** 2 + 2.18555832 * x - 0.20219683
    elif t <= 4000:
        y = -0.9549476 * x ** 3 - 1.37418593 * x ** 2 + 2.09137015 * x - 0.16748867
    else:
        y = 3.0817580 * x ** 3 - 5.87338670 * x ** 2 + 3.75112997 * x - 0.37001483
    xyz = np.array([x / y, 1.0, (1.0 - x - y) / y])
    m = np.array([[3.2404542, -1.5371385, -0.4985314], [-0.9692660, 1.8760108, 0.0415560],
                  [0.0556434, -0.2040259, 1.0572252]])
    rgb = np.clip(m @ xyz, 0.0, None)
    return tuple(float(c) for c in rgb / rgb.max())


def draw_light_color(rng: np.random.Generator, kelvin: Range = (3000.0, 6500.0)) -> tuple[float, float, float]:
    """A light colour (linear RGB, brightest channel 1) of a colour temperature drawn from ``kelvin``."""
    return kelvin_to_rgb(uniform(rng, kelvin))


def ceiling_panels(spec: SceneSpec, rng: np.random.Generator, area: tuple[float, float, float, float], height: float,
                   grid_shape: tuple[int, int], *, power: Range = 35.0, kelvin: Range = 4500.0,
                   panel: tuple[float, float] = (1.2, 0.3), emission: float = 6.0, name: str = "lamp",
                   drop: float = 0.0) -> list[tuple[float, float]]:
    """Ceiling light panels on a grid over ``area`` = (x0, y0, x1, y1): each a visible emissive box just under
    the ceiling at ``height`` (lowered by ``drop`` metres: a pendant) and an invisible area light under it.

    One colour temperature and one power per call (drawn from ``kelvin`` and ``power``): a room's panels
    match.  Returns the panel centres (x, y).
    """
    nx, ny = (int(v) for v in grid_shape)
    color = draw_light_color(rng, kelvin)
    watts = uniform(rng, power)
    mat = spec.add_material(Material(name, kind="emission", color=color, contrast=0.0, emission=emission))
    x0, y0, x1, y1 = area
    z = height - drop
    centres = []
    for i in range(nx):
        for j in range(ny):
            x, y = x0 + (x1 - x0) * (i + 0.5) / nx, y0 + (y1 - y0) * (j + 0.5) / ny
            spec.boxes.append(Box((x, y, z - 0.02), (panel[0], panel[1], 0.04), mat, name=f"{name}{i}_{j}"))
            spec.lights.append(Light("area", position=(x, y, z - 0.05), size=panel, power=watts, color=color))
            centres.append((x, y))
    return centres


def add_window(spec: SceneSpec, rng: np.random.Generator, wall: str, room: tuple[float, float, float],
               along: float, width: float, height: float, sill: float, *, frame: str,
               strength: Range = (0.8, 1.6), kelvin: Range = (5500.0, 9000.0), fill_power: Range = (20.0, 60.0),
               sky: str | None = None, sill_material: str | None = None, name: str = "window") -> None:
    """Daylight through a window: a frame and an emissive, sky-coloured pane set into ``wall`` plus an invisible
    point light 0.6 m inside the window's upper part (the light the window throws into the room).

    Args:
        wall: "-x", "+x", "-y" or "+y": which wall of the room (interior ``room`` = (W, D, H), centred on x = y
            = 0) the window is in.
        along: the window centre's coordinate along the wall, metres.
        width, height, sill: window size and the sill height above the floor, metres.
        frame: material of the frame.
        strength: pane emission; kelvin: sky colour temperature; fill_power: the fill light's watts (0: no fill
            light, the pane alone lights the room).
        sky: an existing emission material for the pane (several windows of a room share one sky); by default
            one is drawn from ``strength`` and ``kelvin``.
        sill_material: the sill's material (default: ``frame``).
    """
    W, D, _ = room
    axis, sign = ("x" if "x" in wall else "y"), (1.0 if wall[0] == "+" else -1.0)
    half = (W if axis == "x" else D) / 2.0
    zc = sill + height / 2.0
    if sky is None:
        sky = spec.add_material(Material(f"{name}.sky", kind="emission", color=draw_light_color(rng, kelvin),
                                         color2=(1.0, 1.0, 1.0), scale=0.8, contrast=0.25,
                                         emission=uniform(rng, strength)))
    pane, color = sky, spec.materials[sky].color

    def at(depth: float, along_: float, z: float, thick: float, w: float, h: float, mat: str, part: str):
        c = sign * (half - depth)
        center, size = ((c, along_, z), (thick, w, h)) if axis == "x" else ((along_, c, z), (w, thick, h))
        spec.boxes.append(Box(center, size, mat, name=f"{name}.{part}"))

    at(0.015, along, zc, 0.03, width + 0.1, height + 0.1, frame, "frame")
    at(0.02, along, zc, 0.04, width, height, pane, "pane")
    at(0.08, along, sill - 0.02, 0.16, width + 0.2, 0.04, sill_material or frame, "sill")
    watts = uniform(rng, fill_power)
    if watts > 0:
        inside = sign * (half - 0.6)
        pos = (inside, along, sill + 0.8 * height) if axis == "x" else (along, inside, sill + 0.8 * height)
        spec.lights.append(Light("point", position=pos, power=watts, color=color))


# ------------------------------------------------------------------------------------------------- geometry


def room_shell(spec: SceneSpec, size: tuple[float, float, float], walls: str, floor: str, ceiling: str,
               thickness: float = 0.05, baseboard: str | None = None, center: tuple[float, float] = (0.0, 0.0)):
    """A room of interior ``size`` = (W, D, H) centred on ``center`` (x, y): the walls as an inward box and the
    floor and ceiling as slabs of their own materials just outside the interior; optional baseboards."""
    W, D, H = size
    cx, cy = center
    t = thickness
    spec.boxes.append(Box((cx, cy, H / 2), (W, D, H + 2 * t), walls, name="shell", inward=True))
    spec.boxes.append(Box((cx, cy, -t / 2), (W, D, t), floor, name="floor"))
    spec.boxes.append(Box((cx, cy, H + t / 2), (W, D, t), ceiling, name="ceiling"))
    if baseboard:
        bb, bh = 0.015, 0.08
        spec.boxes += [Box((cx, cy + D / 2 - bb / 2, bh / 2), (W, bb, bh), baseboard, name="baseboard.front"),
                       Box((cx, cy - D / 2 + bb / 2, bh / 2), (W, bb, bh), baseboard, name="baseboard.back"),
                       Box((cx - W / 2 + bb / 2, cy, bh / 2), (bb, D - 2 * bb, bh), baseboard, name="baseboard.left"),
                       Box((cx + W / 2 - bb / 2, cy, bh / 2), (bb, D - 2 * bb, bh), baseboard, name="baseboard.right")]


def place(spec: SceneSpec, name: str, x: float, y: float, yaw: float, parts: Iterable) -> None:
    """Add ``parts`` (Box, Cylinder and Sphere objects whose centres are given in a local frame: origin at
    (x, y) on the floor, local +y the object's front) rotated by ``yaw`` about +Z and moved to (x, y)."""
    rot = yaw_rotation(yaw)
    for k, part in enumerate(parts):
        cx, cy, cz = rot @ np.asarray(part.center, float)
        center = (float(x + cx), float(y + cy), float(cz))
        label = f"{name}.{part.name or k}"
        if isinstance(part, Sphere):
            spec.spheres.append(replace(part, center=center, name=label))
        elif isinstance(part, Cylinder):
            spec.cylinders.append(replace(part, center=center, yaw=part.yaw + yaw, name=label))
        else:
            spec.boxes.append(replace(part, center=center, yaw=part.yaw + yaw, name=label))


def grid(x_range: tuple[float, float], y_range: tuple[float, float], rows: int, cols: int) -> np.ndarray:
    """(rows * cols, 2) centres of a rows (along y) x cols (along x) grid spanning the ranges (row-major,
    first row at ``y_range[1]``); a single row or column sits in the middle."""
    xs = np.linspace(*x_range, cols) if cols > 1 else np.full(max(cols, 0), np.mean(x_range))
    ys = np.linspace(y_range[1], y_range[0], rows) if rows > 1 else np.full(max(rows, 0), np.mean(y_range))
    return np.array([(x, y) for y in ys for x in xs], dtype=float).reshape(-1, 2)


def row(start: tuple[float, float], end: tuple[float, float], n: int) -> np.ndarray:
    """(n, 2) points evenly spaced from ``start`` to ``end`` (x, y) inclusive; one point sits in the middle."""
    if n == 1:
        return (np.asarray(start, float) + np.asarray(end, float))[None] / 2.0
    return np.linspace(start, end, max(n, 0)).reshape(-1, 2)


def scatter(rng: np.random.Generator, n: int, lo: tuple[float, float], hi: tuple[float, float], radius: float,
            taken: Iterable[tuple[float, float, float]] = (), gap: float = 0.0,
            max_tries: int = 2000) -> list[tuple[float, float]]:
    """Up to ``n`` random centres (x, y) in the rectangle [lo, hi] whose discs of ``radius`` keep ``gap``
    metres from each other and from every (x, y, r) disc in ``taken`` (rejection sampling; fewer than ``n``
    when the room is full)."""
    discs = [tuple(map(float, t)) for t in taken]
    out: list[tuple[float, float]] = []
    lo_, hi_ = np.asarray(lo, float) + radius, np.asarray(hi, float) - radius
    if np.any(hi_ < lo_):
        return out
    for _ in range(max_tries):
        if len(out) >= n:
            break
        x, y = rng.uniform(lo_, hi_)
        if all(np.hypot(x - a, y - b) >= radius + r + gap for a, b, r in discs):
            out.append((float(x), float(y)))
            discs.append((float(x), float(y), radius))
    return out


def table_parts(w: float, d: float, h: float, top: str, legs: str, leg: float = 0.035,
                thick: float = 0.03, round_legs: bool = False) -> list:
    """A table (w x d, height h, metres): a top and four legs (square boxes of side ``leg`` or, with
    ``round_legs``, cylinders of diameter ``leg``)."""
    parts: list = [Box((0.0, 0.0, h - thick / 2), (w, d, thick), top, name="top")]
    ix, iy = w / 2 - leg, d / 2 - leg
    for sx in (-1, 1):
        for sy in (-1, 1):
            c = (sx * ix, sy * iy, (h - thick) / 2)
            parts.append(Cylinder(c, leg / 2, h - thick, legs) if round_legs else
                         Box(c, (leg, leg, h - thick), legs))
    return parts


def chair_parts(seat: str, legs: str, seat_h: float = 0.45, w: float = 0.40, d: float = 0.40,
                back_h: float = 0.38, leg: float = 0.025, round_legs: bool = False) -> list:
    """A chair facing +y (its back at -y): seat, back, four legs and two back posts (``leg`` thick)."""
    def post(c, length):
        return Cylinder(c, leg / 2, length, legs) if round_legs else Box(c, (leg, leg, length), legs)

    parts: list = [Box((0.0, 0.0, seat_h - 0.015), (w, d, 0.03), seat, name="seat"),
                   Box((0.0, -d / 2 + 0.015, seat_h + 0.08 + back_h / 2), (w, 0.025, back_h), seat, name="back")]
    for sx in (-1, 1):
        for sy in (-1, 1):
            parts.append(post((sx * (w / 2 - leg), sy * (d / 2 - leg), (seat_h - 0.03) / 2), seat_h - 0.03))
    for sx in (-1, 1):
        parts.append(post((sx * (w / 2 - leg), -d / 2 + 0.015, seat_h + 0.04), 0.08))
    return parts


def round_table_parts(radius: float, h: float, top: str, stand: str, thick: float = 0.04,
                      column: float = 0.05) -> list:
    """A round table: a disc top of ``radius`` at height ``h`` with an 8 cm apron under its rim, a central column
    of radius ``column`` and a round foot (cylinders).  (Top and apron together are 12 cm tall, so that the
    rig-placement check, which samples the column under each camera every 10 cm, cannot miss the table.)"""
    foot = min(0.6 * radius, 0.4)
    return [Cylinder((0.0, 0.0, h - thick / 2), radius, thick, top, name="top"),
            Cylinder((0.0, 0.0, h - thick - 0.04), radius - 0.05, 0.08, top, name="apron"),
            Cylinder((0.0, 0.0, (h - thick) / 2), column, h - thick - 0.02, stand, name="column"),
            Cylinder((0.0, 0.0, 0.01), foot, 0.02, stand, name="foot")]


def stool_parts(seat: str, legs: str, h: float = 0.65, radius: float = 0.17, leg: float = 0.022) -> list:
    """A stool: a round seat (cylinder) on three thin round legs."""
    parts: list = [Cylinder((0.0, 0.0, h - 0.02), radius, 0.04, seat, name="seat")]
    for k in range(3):
        a = 2 * np.pi * k / 3
        parts.append(Cylinder((0.75 * radius * np.cos(a), 0.75 * radius * np.sin(a), (h - 0.04) / 2), leg / 2,
                              h - 0.04, legs))
    return parts


def room_size_param(default: tuple[float, float, float]):
    """The ``size`` field of a room family's parameters: ``default`` (width x, depth y, height z) of the room
    interior, metres, before the seed's jitter (:func:`scenes.model.param`)."""
    return param(default, "(width x, depth y, height z) of the room interior before jitter", unit="m",
                 limits=(2.0, 100.0))


def size_jitter_param(default: float):
    """The ``size_jitter`` field of a room family's parameters: the relative room-size jitter drawn from the seed,
    per axis, the height's half of it (:func:`scenes.model.param`)."""
    return param(default, "relative room-size jitter drawn from the seed, per axis (height: half of it)",
                 limits=(0.0, 0.5))

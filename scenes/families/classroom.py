"""A classroom like the paper's (about 8 x 7 x 3 m): rows of desks and chairs, a teacher's desk, a chalkboard
and a whiteboard, windows, a door, ceiling lights, lockers and a bookshelf.

Everything is built from boxes (a table is a top plus four legs, a chair a seat, a back and four legs), so
the scene stays renderer-agnostic.  Coordinates: room centred on x = y = 0, floor at z = 0; the front wall
(boards) is at +y, the windows on the -x wall, the door on the +x wall, the lockers on the back (-y) wall.
Students face +y.

The ``seed`` jitters the layout (desk and chair positions and angles, empty seats, books) and, through the
shared kit (``scenes/families/_kit.py``) on a stream of its own, the look: every material's colour, texture
contrast and roughness around its preset look, the ceiling panels' power and colour temperature, the sky's
colour and brightness in the windows (``look_variation`` scales all of it).  The default, 0, is the fixed look
of the reference classroom (the scene every earlier figure of tri360 was measured on, so ``make evaluate`` and
the regression bounds stay comparable); suites set 1 to draw the look per seed.  Presets
change the room size and furnishing.  Weak-texture surfaces on purpose: the ceiling (uniform), the whiteboard
(uniform), the window panes (nearly uniform, bright) and the lockers (faint).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from scenes.families import _kit as kit
from scenes.model import Box, Material, ModelFile, SceneEntry, SceneParams, SceneSpec, param

MATERIALS = [
    Material("floor", kind="tiles", color=(0.55, 0.52, 0.46), color2=(0.32, 0.30, 0.27), scale=0.3,
             contrast=0.5, roughness=0.45),
    Material("walls", kind="paint", color=(0.72, 0.68, 0.58), color2=(0.55, 0.52, 0.45), scale=0.15,
             contrast=0.35, roughness=0.85),
    # suspended acoustic ceiling: 60 cm tiles, darker T-bar grid, fissured speckle
    Material("ceiling", kind="tiles", color=(0.84, 0.84, 0.82), color2=(0.50, 0.50, 0.50), scale=0.6,
             contrast=0.45, roughness=0.9),
    Material("baseboard", kind="plastic", color=(0.12, 0.10, 0.09), contrast=0.3, roughness=0.5),
    Material("desk_wood", kind="wood", color=(0.50, 0.32, 0.16), color2=(0.26, 0.14, 0.06), scale=0.04,
             contrast=0.8, roughness=0.4),
    Material("dark_wood", kind="wood", color=(0.28, 0.16, 0.08), color2=(0.12, 0.06, 0.03), scale=0.05,
             contrast=0.7, roughness=0.45),
    Material("leg_metal", kind="metal", color=(0.55, 0.56, 0.58), scale=0.2, contrast=0.3, roughness=0.35),
    Material("seat", kind="plastic", color=(0.10, 0.22, 0.45), color2=(0.05, 0.12, 0.30), scale=0.1,
             contrast=0.4, roughness=0.5),
    Material("chalkboard", kind="board", color=(0.05, 0.12, 0.08), color2=(0.25, 0.30, 0.27), scale=0.5,
             contrast=0.5, roughness=0.9),
    Material("whiteboard", kind="plastic", color=(0.85, 0.86, 0.86), contrast=0.0, roughness=0.2),
    Material("frame", kind="metal", color=(0.70, 0.70, 0.72), scale=0.3, contrast=0.2, roughness=0.3),
    Material("window", kind="emission", color=(0.75, 0.85, 1.0), color2=(0.95, 0.97, 1.0), scale=0.8,
             contrast=0.3, emission=1.1),
    Material("door", kind="wood", color=(0.42, 0.25, 0.12), color2=(0.22, 0.12, 0.05), scale=0.06,
             contrast=0.6, roughness=0.5),
    Material("locker", kind="metal", color=(0.30, 0.40, 0.48), color2=(0.22, 0.30, 0.36), scale=0.3,
             contrast=0.15, roughness=0.5),
    Material("monitor", kind="plastic", color=(0.03, 0.03, 0.035), contrast=0.2, roughness=0.3),
    Material("poster_a", kind="noise", color=(0.8, 0.3, 0.1), color2=(0.1, 0.3, 0.7), scale=0.08, contrast=1.0),
    Material("poster_b", kind="noise", color=(0.9, 0.85, 0.2), color2=(0.1, 0.5, 0.2), scale=0.05,
             contrast=1.0),
    Material("book_a", kind="fabric", color=(0.55, 0.08, 0.06), scale=0.05, contrast=0.4),
    Material("book_b", kind="fabric", color=(0.08, 0.2, 0.5), scale=0.05, contrast=0.4),
    Material("book_c", kind="fabric", color=(0.1, 0.4, 0.15), scale=0.05, contrast=0.4),
    Material("book_d", kind="fabric", color=(0.8, 0.7, 0.5), scale=0.05, contrast=0.4),
]
BOOKS = ("book_a", "book_b", "book_c", "book_d")


def _place(spec: SceneSpec, name: str, x: float, y: float, yaw: float, parts) -> None:
    """Add parts given as (dx, dy, z centre, size, material) boxes or kit parts, rotated by ``yaw`` about (x, y)."""
    kit.place(spec, name, x, y, yaw, [p if not isinstance(p, tuple) else
                                      Box((p[0], p[1], p[2]), p[3], p[4]) for p in parts])


def _chair_parts(seat_h=0.45, w=0.40, d=0.40, back_h=0.38):
    """A chair facing +y (its back at -y)."""
    return kit.chair_parts("seat", "leg_metal", seat_h=seat_h, w=w, d=d, back_h=back_h)


@dataclass(frozen=True)
class ClassroomParams(SceneParams):
    """The classroom's parameters (``tri360 scenes --params``)."""

    size: tuple[float, float, float] = param((8.0, 7.0, 3.0), "(width x, depth y, height z) of the room interior",
                                             unit="m", limits=(2.0, 100.0))
    rows: int = param(5, "student desk rows, along y", limits=(0, 100))
    cols: int = param(6, "student desk columns, along x", limits=(0, 100))
    windows: int = param(3, "number of windows on the -x wall", limits=(0, 100))
    lockers: bool = param(True, "a row of lockers on the back wall")
    shelf: bool = param(True, "a bookshelf in the back corner of the +x wall")
    lights: tuple[int, int] = param((2, 3), "(nx, ny) grid of ceiling light panels", limits=(0, 100))
    light_power: float = param(35.0, "power per ceiling area light", unit="W", limits=(0.0, None))
    jitter: float = param(0.05, "layout jitter amplitude; angles get jitter / 1 m radians", unit="m",
                          limits=(0.0, 1.0))
    empty_seat_rate: float = param(0.15, "share of desks without a chair", limits=(0.0, 1.0))
    look_variation: float = param(0.0, "amplitude of the seed's material and lighting randomisation, 0 = the fixed "
                                  "look, 1 = the full randomisation suites use", limits=(0.0, 1.0))
    model_path: str | None = param(None, "an external model file (.blend, .glb, .gltf, .obj) to place; Cycles only")
    model_location: tuple[float, float, float] = param((0.0, 0.0, 0.0), "(x, y, z) of the model", unit="m")
    model_rotation: tuple[float, float, float] = param((0.0, 0.0, 0.0), "(rx, ry, rz) Euler XYZ rotation of the "
                                                       "model", unit="rad")
    model_scale: float = param(1.0, "uniform scale of the model", limits=(0.0, None))


REFERENCE_LAMP_COLOR = (1.0, 0.97, 0.92)
"""Colour of the light panels in the fixed look (``look_variation = 0``), linear RGB."""


def build(p: ClassroomParams, seed: int) -> SceneSpec:
    """Build a classroom."""
    rng = np.random.default_rng(seed)  # the layout stream (as before the look was randomised)
    look = kit.streams(seed)[1]
    amount = p.look_variation
    W, D, H = p.size
    rows, cols = p.rows, p.cols
    jitter = p.jitter
    spec = SceneSpec(name="classroom", bounds=((-W / 2, -D / 2, 0.0), (W / 2, D / 2, H)),
                     rig_height=(1.1, min(1.5, H - 0.9)), background=(0.0, 0.0, 0.0))
    for m in MATERIALS:
        if m.name == "window" and amount > 0:  # daylight: sky colour temperature (7000-11500 K), brightness
            kelvin = 9000.0 + amount * look.uniform(-2000.0, 2500.0)
            gain = 1.0 + 0.25 * amount * look.uniform(-1, 1)
            m = replace(m, color=kit.kelvin_to_rgb(kelvin), emission=m.emission * gain)
        elif m.kind != "emission":
            m = kit.vary_material(look, m, amount)
        spec.add_material(m)
    b = spec.boxes

    # shell: walls (inward box), tiled floor slab and ceiling slab (different materials), baseboards
    kit.room_shell(spec, (W, D, H), "walls", "floor", "ceiling", baseboard="baseboard")

    # front wall: chalkboard with frame and chalk tray, whiteboard beside it, a clock
    fy = D / 2
    bw = min(3.6, 0.45 * W)
    b.append(Box((0.0, fy - 0.015, 1.5), (bw + 0.08, 0.03, 1.28), "frame", name="board.frame"))
    b.append(Box((0.0, fy - 0.035, 1.5), (bw, 0.03, 1.2), "chalkboard", name="chalkboard"))
    b.append(Box((0.0, fy - 0.06, 0.88), (bw, 0.08, 0.025), "frame", name="chalk_tray"))
    wx = min(bw / 2 + 1.2, W / 2 - 0.9)
    b.append(Box((wx, fy - 0.02, 1.45), (1.4, 0.04, 1.0), "whiteboard", name="whiteboard"))
    b.append(Box((-wx, fy - 0.02, 2.35), (0.32, 0.04, 0.32), "monitor", name="clock"))

    # windows on the -x wall: frame, bright pane, sill
    n_win = p.windows
    win_w = min(1.5, 0.8 * D / max(n_win, 1))
    for k in range(n_win):
        y = -D / 2 + D * (k + 0.5) / n_win
        b.append(Box((-W / 2 + 0.015, y, 1.65), (0.03, win_w + 0.1, 1.5), "frame", name=f"window{k}.frame"))
        b.append(Box((-W / 2 + 0.02, y, 1.65), (0.04, win_w, 1.4), "window", name=f"window{k}.pane"))
        b.append(Box((-W / 2 + 0.08, y, 0.88), (0.16, win_w + 0.2, 0.04), "walls", name=f"window{k}.sill"))

    # door on the +x wall near the front
    dy = D / 2 - 1.0
    b.append(Box((W / 2 - 0.025, dy, 1.05), (0.05, 0.95, 2.1), "door", name="door"))
    b.append(Box((W / 2 - 0.07, dy - 0.35, 1.0), (0.05, 0.12, 0.025), "frame", name="door.handle"))

    # teacher's desk (with a drawer block and a monitor) and chair
    tx, ty = 0.25 * W + rng.uniform(-jitter, jitter), D / 2 - 1.4
    tyaw = np.pi + rng.uniform(-jitter, jitter)
    _place(spec, "teacher_desk", tx, ty, tyaw, kit.table_parts(1.4, 0.7, 0.76, "dark_wood", "dark_wood", leg=0.05))
    _place(spec, "teacher_desk.drawers", tx, ty, tyaw, [(0.45, 0.0, 0.36, (0.4, 0.6, 0.7), "dark_wood")])
    _place(spec, "monitor", tx, ty, tyaw, [(-0.2, 0.15, 0.76 + 0.22, (0.5, 0.03, 0.32), "monitor"),
                                           (-0.2, 0.15, 0.76 + 0.03, (0.2, 0.15, 0.06), "monitor")])
    _place(spec, "teacher_chair", tx - 0.2 * np.cos(tyaw), ty + 0.6, tyaw + rng.uniform(-0.3, 0.3),
           _chair_parts(0.48, 0.46, 0.44, 0.45))

    # student desks and chairs
    x0, x1 = -W / 2 + 1.3, W / 2 - 0.9
    y0, y1 = -D / 2 + (1.5 if p.lockers else 1.0), D / 2 - 2.4
    empty_rate = p.empty_seat_rate
    for r in range(rows):
        y = y1 if rows == 1 else y1 - (y1 - y0) * r / (rows - 1)
        for c in range(cols):
            x = (x0 + x1) / 2 if cols == 1 else x0 + (x1 - x0) * c / (cols - 1)
            jx, jy = rng.uniform(-jitter, jitter, 2)
            yaw = rng.uniform(-jitter, jitter)
            _place(spec, f"desk{r}_{c}", x + jx, y + jy, yaw,
                   kit.table_parts(0.65, 0.45, 0.72, "desk_wood", "leg_metal"))
            if rng.uniform() >= empty_rate:
                off = rng.uniform(0.35, 0.55)
                cyaw = yaw + rng.uniform(-4 * jitter, 4 * jitter)
                _place(spec, f"chair{r}_{c}", x + jx + rng.uniform(-jitter, jitter), y + jy - off, cyaw,
                       _chair_parts())

    # lockers on the back wall
    if p.lockers:
        n = int((W - 2.0) / 0.42)
        for k in range(n):
            x = -W / 2 + 1.0 + 0.42 * (k + 0.5)
            b.append(Box((x, -D / 2 + 0.225, 0.9), (0.41, 0.45, 1.8), "locker", name=f"locker{k}"))
            b.append(Box((x + 0.14, -D / 2 + 0.455, 1.0), (0.03, 0.02, 0.12), "frame", name=f"locker{k}.handle"))
    # posters above the lockers / on the side wall
    b.append(Box((-0.8, -D / 2 + 0.01, 2.3), (0.9, 0.02, 0.6), "poster_a", name="poster0"))
    b.append(Box((0.8, -D / 2 + 0.01, 2.3), (0.6, 0.02, 0.8), "poster_b", name="poster1"))
    b.append(Box((W / 2 - 0.01, 0.0, 1.8), (0.02, 0.8, 0.6), "poster_b", name="poster2"))

    # bookshelf in the back corner of the +x wall, with books
    if p.shelf:
        sx, sy0, sw, sd, sh = W / 2 - 0.18, -D / 2 + 1.6, 1.2, 0.34, 1.9
        b.append(Box((sx, sy0 - sw / 2 + 0.01, sh / 2), (sd, 0.02, sh), "dark_wood", name="shelf.side0"))
        b.append(Box((sx, sy0 + sw / 2 - 0.01, sh / 2), (sd, 0.02, sh), "dark_wood", name="shelf.side1"))
        b.append(Box((W / 2 - 0.01, sy0, sh / 2), (0.02, sw, sh), "dark_wood", name="shelf.back"))
        for k, z in enumerate(np.linspace(0.05, sh - 0.01, 5)):
            b.append(Box((sx, sy0, z), (sd, sw - 0.04, 0.02), "dark_wood", name=f"shelf.board{k}"))
            if z > sh - 0.1:
                continue
            yb = sy0 - sw / 2 + 0.04
            while True:
                bw_, bh_ = rng.uniform(0.02, 0.06), rng.uniform(0.2, 0.3)
                if yb + bw_ > sy0 + sw / 2 - 0.04:
                    break
                if rng.uniform() > 0.1:
                    b.append(Box((sx - 0.02, yb + bw_ / 2, z + 0.01 + bh_ / 2), (0.22, bw_, bh_),
                                 BOOKS[int(rng.integers(len(BOOKS)))], name=f"book{len(b)}"))
                yb += bw_ + 0.003

    # ceiling light panels (visible emitters) with area lights just below them (invisible to cameras)
    # (one power and colour temperature per room, drawn around the preset's: +-25 %, 3300-6000 K)
    power = p.light_power * (1.0 + 0.25 * amount * look.uniform(-1, 1))
    kelvin = 4500.0 + amount * look.uniform(-1200.0, 1500.0)
    kit.ceiling_panels(spec, look, (-W / 2, -D / 2, W / 2, D / 2), H, p.lights, power=power,
                       kelvin=kelvin, panel=(1.2, 0.3), emission=6.0, name="lamp")
    if amount == 0:  # the reference classroom's fixed look: warm-white panels over white lights
        spec.materials["lamp"] = replace(spec.materials["lamp"], color=REFERENCE_LAMP_COLOR)
        spec.lights = [replace(light, color=(1.0, 1.0, 1.0)) for light in spec.lights]

    if p.model_path:
        spec.models.append(ModelFile(path=p.model_path, location=p.model_location,
                                     rotation_euler=p.model_rotation, scale=p.model_scale))
    return spec


PRESETS = {
    "standard": {"size": (8.0, 7.0, 3.0), "rows": 5, "cols": 6, "windows": 3, "lockers": True, "shelf": True,
                 "lights": (2, 3)},
    "small": {"size": (6.0, 5.0, 2.7), "rows": 3, "cols": 4, "windows": 2, "lockers": False, "shelf": True,
              "lights": (2, 2)},
    "lecture": {"size": (12.0, 10.0, 3.5), "rows": 7, "cols": 8, "windows": 5, "lockers": True, "shelf": True,
                "lights": (3, 4), "light_power": 45.0},
    "empty": {"size": (8.0, 7.0, 3.0), "rows": 0, "cols": 0, "windows": 3, "lockers": False, "shelf": False,
              "lights": (2, 3)},
}

# version: the scene code version frames and suite ids record; change it when what build() builds changes,
# and only then (tests/scenes/test_scene_fingerprints.py; scenes/README.md)
SCENES = [SceneEntry(name="classroom", version="sha256:1ed56314fc16eeec",
                     build=build, presets=PRESETS, default_preset="standard",
                     description="classroom (8 x 7 x 3 m standard): desks, chairs, boards, windows, lockers",
                     parameters=ClassroomParams, renderer="cycles", tags=("repetitive", "thin"))]

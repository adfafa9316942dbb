"""A library reading room: rows of double-sided book stacks filled with books (many small boxes of varied
colours and sizes), wall shelves, long reading tables with chairs and desk lamps, windows.

Hard for matching on purpose: the stacks repeat the same structure row after row and shelf after shelf, and
the books are hundreds of narrow, similar faces at slightly different depths (repetitive), broken by gaps,
book ends and the clutter of open books and lamps on the tables (cluttered).  Coordinates: room centred on
x = y = 0, floor at z = 0; the stacks fill the front (+y) part of the room, in two banks either side of a main
aisle along y at x = 0; the reading tables stand in the back (-y) part in front of wall shelves on the back
wall; windows (if any) are on the -x wall, the door on the +x wall.

The ``seed`` draws the room size (around the preset's, by ``size_jitter``), how many stack rows fit, every
book (width, height, depth, colour, gaps), the tables' positions, chairs and lamps, and (through the shared kit,
``scenes/families/_kit.py``) every material (colour, texture contrast from none to strong, roughness), the
ceiling lights' power and colour temperature and the daylight in the windows.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from reconstruction.camera.rig import yaw_rotation
from scenes.families import _kit as kit
from scenes.model import Box, Cylinder, SceneEntry, SceneParams, SceneSpec, Sphere, param


@dataclass(frozen=True)
class LibraryParams(SceneParams):
    """The library's parameters (``tri360 scenes --params``)."""

    size: tuple[float, float, float] = kit.room_size_param((12.0, 10.0, 3.2))
    size_jitter: float = kit.size_jitter_param(0.08)
    stack_zone: float = param(0.55, "share of the room depth (from the +y wall) given to the book stacks",
                              limits=(0.0, 1.0))
    stack_height: float = param(2.0, "height of a book stack", unit="m", limits=(0.5, 10.0))
    levels: int = param(5, "shelf levels per stack", limits=(1, 50))
    aisle: float = param(1.3, "aisle between stack rows", unit="m", limits=(0.5, 20.0))
    main_aisle: float = param(1.8, "width of the main aisle between the two banks of stacks", unit="m",
                              limits=(0.5, 50.0))
    fill: float = param(0.8, "share of the shelf length filled with books", limits=(0.0, 1.0))
    book_colors: int = param(10, "number of book materials (colours)", limits=(1, 1000))
    tables: int = param(2, "reading tables in the back part of the room", limits=(0, 50))
    wall_shelves: bool = param(True, "a book wall along the back (-y) wall")
    windows: int = param(3, "windows on the -x wall, with daylight", limits=(0, 20))
    lights: tuple[int, int] = param((4, 3), "(nx, ny) grid of ceiling light panels", limits=(0, 100))
    light_power: tuple[float, float] = param((45.0, 65.0), "(min, max) power per ceiling area light", unit="W",
                                             limits=(0.0, None))
    kelvin: tuple[float, float] = param((3000.0, 5000.0), "(min, max) colour temperature of the ceiling lights",
                                        unit="K", limits=(1000.0, 40000.0))

SHELF_D = 0.30  # depth of one side of a stack (a double-sided stack is twice as deep), metres
BOARD = 0.02  # shelf board thickness, metres


def _materials(spec: SceneSpec, look: np.random.Generator, n_books: int) -> list[str]:
    add = spec.add_material
    add(kit.draw_material(look, "walls", "paint", hue=(0.05, 0.15), saturation=(0.0, 0.25), value=(0.6, 0.9),
                          contrast=kit.draw_contrast(look, ("none", "weak", "medium"), (1, 2, 1)),
                          roughness=(0.7, 0.95), scale=(0.1, 0.5)))
    add(kit.draw_material(look, "ceiling", "paint", saturation=(0.0, 0.04), value=(0.8, 0.95),
                          contrast=kit.draw_contrast(look, ("none", "weak")), roughness=0.9, scale=(0.3, 0.8)))
    floor_kind = "wood" if look.uniform() < 0.5 else "fabric"  # parquet or carpet
    add(kit.draw_material(look, "floor", floor_kind, hue=(0.03, 0.12) if floor_kind == "wood" else (0.0, 1.0),
                          saturation=(0.2, 0.6), value=(0.2, 0.55),
                          contrast=kit.draw_contrast(look, ("weak", "medium", "strong")), roughness=(0.4, 0.95),
                          scale=(0.04, 0.12)))
    add(kit.draw_material(look, "shelf", "wood", hue=(0.04, 0.11), saturation=(0.2, 0.7), value=(0.15, 0.7),
                          contrast=kit.draw_contrast(look, ("weak", "medium", "strong")), roughness=(0.35, 0.7),
                          scale=(0.03, 0.08)))
    add(kit.draw_material(look, "table", "wood", hue=(0.04, 0.11), saturation=(0.3, 0.7), value=(0.2, 0.6),
                          contrast=(0.3, 0.9), roughness=(0.25, 0.5), scale=(0.03, 0.06)))
    add(kit.draw_material(look, "seat", "fabric", saturation=(0.2, 0.7), value=(0.1, 0.45), contrast=(0.05, 0.4),
                          roughness=(0.8, 1.0), scale=(0.03, 0.1)))
    add(kit.draw_material(look, "metal", "metal", saturation=(0.0, 0.1), value=(0.3, 0.8), contrast=(0.05, 0.3),
                          roughness=(0.2, 0.45), scale=(0.1, 0.3)))
    add(kit.draw_material(look, "paper", "paint", saturation=(0.0, 0.08), value=(0.8, 0.95), contrast=0.0,
                          roughness=0.9))
    add(kit.draw_material(look, "shade", "emission", hue=(0.1, 0.15), saturation=(0.1, 0.4), value=(0.8, 1.0),
                          contrast=0.0, emission=float(look.uniform(2.0, 4.0))))
    add(kit.draw_material(look, "door", "wood", hue=(0.05, 0.1), saturation=(0.3, 0.6), value=(0.25, 0.5),
                          contrast=(0.3, 0.7), roughness=(0.4, 0.6), scale=(0.04, 0.08)))
    books = []
    for k in range(n_books):
        kind = ("fabric", "plastic", "paint")[int(look.integers(3))]  # cloth, laminated, paper covers
        books.append(add(kit.draw_material(look, f"book{k}", kind, saturation=(0.15, 0.85), value=(0.12, 0.85),
                                           contrast=kit.draw_contrast(look, ("none", "weak", "medium", "strong"),
                                                                      (1, 2, 2, 1)),
                                           roughness=(0.3, 0.9), scale=(0.01, 0.05))))
    return books


def _books(rng: np.random.Generator, x0: float, x1: float, z: float, gap: float, side: float, fill: float,
           books: list[str]) -> list:
    """Books standing on a board (top at ``z``) from local x0 to x1, their spines facing ``side`` (+1: +y), in
    a shelf of clear height ``gap``: Boxes in the stack's local frame (centre line y = 0)."""
    parts = []
    x = x0 + rng.uniform(0.0, 0.05)
    run_colour = books[int(rng.integers(len(books)))]
    # after each book a gap (mean 0.2 m: lent books, the end of a run) with the probability that leaves
    # ``fill`` of the length to books of mean width 0.045 m
    p_gap = 0.045 * (1.0 - fill) / (max(fill, 1e-3) * 0.2)
    while True:
        if rng.uniform() < p_gap:
            x += rng.uniform(0.05, 0.35)
            run_colour = books[int(rng.integers(len(books)))]
        w = rng.uniform(0.02, 0.07)
        if x + w > x1:
            break
        h = rng.uniform(0.16, max(0.17, min(0.34, gap - 0.03)))
        d = rng.uniform(0.14, min(0.26, SHELF_D - 0.03))
        inset = rng.uniform(0.005, 0.035)
        colour = run_colour if rng.uniform() < 0.4 else books[int(rng.integers(len(books)))]  # series share a colour
        parts.append(Box((x + w / 2, side * (SHELF_D - inset - d / 2), z + h / 2), (w, d, h), colour,
                         name=f"book{len(parts)}"))
        x += w + rng.uniform(0.0, 0.004)
    return parts


def _stack(rng: np.random.Generator, length: float, height: float, levels: int, sides: tuple, fill: float,
           books: list[str]) -> list:
    """A book stack of ``length`` along local x: end panels, a back panel on y = 0, boards, and books on the
    given ``sides`` (+1 and/or -1: the faces at +y / -y).  Local frame: origin on the floor, centred."""
    depth = SHELF_D * len(sides)
    yc = 0.0 if len(sides) == 2 else sides[0] * SHELF_D / 2
    parts: list = [Box((-length / 2 + 0.0125, yc, height / 2), (0.025, depth, height), "shelf", name="end0"),
                   Box((length / 2 - 0.0125, yc, height / 2), (0.025, depth, height), "shelf", name="end1"),
                   Box((0.0, 0.0, height / 2), (length - 0.05, 0.02, height), "shelf", name="back"),
                   Box((0.0, yc, 0.04), (length - 0.05, depth - 0.02, 0.08), "shelf", name="kick")]
    pitch = (height - 0.08 - BOARD) / levels
    for lv in range(levels + 1):
        z = 0.08 + lv * pitch + BOARD / 2
        parts.append(Box((0.0, yc, z), (length - 0.05, depth, BOARD), "shelf", name=f"board{lv}"))
        if lv == levels:
            break
        for s in sides:
            parts += _books(rng, -length / 2 + 0.03, length / 2 - 0.03, z + BOARD / 2, pitch - BOARD, s, fill, books)
    return parts


def _reading_table(rng: np.random.Generator, length: float) -> list:
    """A long reading table along local x with chairs on both sides, lamps and open books on it."""
    h, d = 0.75, 1.0
    parts = kit.table_parts(length, d, h, "table", "table", leg=0.06, thick=0.04)
    n = max(1, int(length / 0.8))
    for k in range(n):
        x = -length / 2 + length * (k + 0.5) / n
        for side in (-1, 1):
            if rng.uniform() < 0.25:
                continue  # an empty place
            chair = kit.chair_parts("seat", "metal", seat_h=0.46, w=0.44, d=0.42, back_h=0.4, leg=0.022,
                                    round_legs=True)
            yaw = (0.0 if side < 0 else np.pi) + rng.uniform(-0.25, 0.25)
            cy = side * (d / 2 + rng.uniform(0.15, 0.4))
            parts += _moved(chair, x + rng.uniform(-0.08, 0.08), cy, yaw)
            if rng.uniform() < 0.5:  # an open book and notes at this place
                parts.append(Box((x + rng.uniform(-0.15, 0.15), side * 0.25, h + 0.01), (0.32, 0.22, 0.02),
                                 "paper", yaw=rng.uniform(-0.4, 0.4), name=f"open{k}_{side}"))
    for k in range(max(1, n // 2)):  # a lamp for every two places: foot, stem, glowing shade
        x = -length / 2 + length * (k + 0.5) / max(1, n // 2)
        parts += [Cylinder((x, 0.0, h + 0.01), 0.08, 0.02, "metal", name=f"lamp{k}.foot"),
                  Cylinder((x, 0.0, h + 0.2), 0.01, 0.38, "metal", name=f"lamp{k}.stem"),
                  Sphere((x, 0.0, h + 0.42), 0.09, "shade", name=f"lamp{k}.shade")]
    return parts


def _moved(parts: list, x: float, y: float, yaw: float) -> list:
    """``parts`` (local frame) as seen in another local frame: rotated by ``yaw`` and moved to (x, y)."""
    rot = yaw_rotation(yaw)
    out = []
    for p in parts:
        cx, cy, cz = rot @ np.asarray(p.center, float)
        c = (float(x + cx), float(y + cy), float(cz))
        out.append(replace(p, center=c) if isinstance(p, Sphere) else replace(p, center=c, yaw=p.yaw + yaw))
    return out


def build(p: LibraryParams, seed: int) -> SceneSpec:
    """Build a library reading room."""
    layout, look = kit.streams(seed)
    jit = p.size_jitter
    W0, D0, H0 = p.size
    W, D = W0 * (1 + layout.uniform(-jit, jit)), D0 * (1 + layout.uniform(-jit, jit))
    H = H0 * (1 + 0.5 * layout.uniform(-jit, jit))
    spec = SceneSpec(name="library", bounds=((-W / 2, -D / 2, 0.0), (W / 2, D / 2, H)),
                     rig_height=(1.1, min(1.5, H - 0.9)), background=(0.0, 0.0, 0.0))
    books = _materials(spec, look, p.book_colors)
    kit.room_shell(spec, (W, D, H), "walls", "floor", "ceiling", baseboard="shelf")
    b = spec.boxes
    fill = p.fill
    sh, levels = p.stack_height, p.levels

    # the stacks: two banks either side of the main aisle, rows along x, from the +y wall back
    zone = p.stack_zone * D
    aisle, main = p.aisle, p.main_aisle
    wall_gap = 0.9  # free floor between a bank and the side walls, metres
    bank = (W - main) / 2 - wall_gap  # length of a stack
    pitch = 2 * SHELF_D + aisle
    n_rows = max(1, int((zone - 0.6) // pitch))
    for r in range(n_rows):
        y = D / 2 - 0.9 - SHELF_D - r * pitch
        for side in (-1, 1):
            if bank < 0.8:
                continue
            x = side * (main / 2 + bank / 2) + layout.uniform(-0.05, 0.05)
            kit.place(spec, f"stack{r}_{side}", x, y, 0.0, _stack(layout, bank, sh, levels, (-1, 1), fill, books))

    # the book wall on the back wall, behind the reading area
    if p.wall_shelves:
        length = W - 2.4
        kit.place(spec, "wallshelf", layout.uniform(-0.2, 0.2), -D / 2 + 0.01, 0.0,
                  _stack(layout, length, min(sh + 0.2, H - 0.4), levels + 1, (1,), fill, books))

    # reading tables in the back part of the room
    n_tab = p.tables
    y_read = (-D / 2 + (1.0 if p.wall_shelves else 0.4) + D / 2 - zone) / 2
    length = min(3.2, (W - 2.0) / max(n_tab, 1) - 1.6)
    for k, (x, _) in enumerate(kit.row((-W / 2 + 1.0 + (length + 1.6) / 2, 0), (W / 2 - 1.0 - (length + 1.6) / 2, 0),
                                        n_tab)):
        if length < 1.0:
            break
        kit.place(spec, f"table{k}", x + layout.uniform(-0.2, 0.2), y_read + layout.uniform(-0.2, 0.2),
                  layout.uniform(-0.05, 0.05), _reading_table(layout, length))

    # door on the +x wall (in the reading part), windows with daylight on the -x wall
    dy = layout.uniform(-D / 2 + 1.0, D / 2 - zone - 0.6)
    b.append(Box((W / 2 - 0.025, dy, 1.05), (0.05, 0.95, 2.1), "door", name="door"))
    b.append(Box((W / 2 - 0.07, dy - 0.35, 1.0), (0.05, 0.12, 0.025), "metal", name="door.handle"))
    n_win = p.windows
    for k in range(n_win):
        y = -D / 2 + D * (k + 0.5) / n_win
        kit.add_window(spec, look, "-x", (W, D, H), along=y, width=min(1.4, 0.7 * D / n_win),
                       height=min(1.6, H - 1.3), sill=0.95, frame="metal", name=f"window{k}")

    margin = 0.8
    kit.ceiling_panels(spec, look, (-W / 2 + margin, -D / 2 + margin, W / 2 - margin, D / 2 - margin), H,
                       p.lights, power=p.light_power, kelvin=p.kelvin, panel=(1.2, 0.3), emission=6.0)
    return spec


PRESETS = {
    "reading_room": {"size": (12.0, 10.0, 3.2), "tables": 2, "windows": 3, "lights": (4, 3)},
    "stacks": {"size": (12.0, 12.0, 3.0), "stack_zone": 0.75, "tables": 1, "aisle": 1.2, "levels": 5,
               "stack_height": 2.1, "fill": 0.7, "windows": 0, "lights": (4, 4), "light_power": (45.0, 65.0)},
    "small": {"size": (8.0, 7.0, 2.8), "stack_zone": 0.5, "tables": 1, "windows": 2, "lights": (3, 2)},
}

# version: the scene code version frames and suite ids record; change it when what build() builds changes,
# and only then (tests/scenes/test_scene_fingerprints.py; scenes/README.md)
SCENES = [SceneEntry(name="library", version="sha256:94f773fe8efd3881",
                     build=build, presets=PRESETS, default_preset="reading_room",
                     description="library (12 x 10 x 3.2 m): rows of book stacks, wall shelves, reading tables",
                     parameters=LibraryParams, renderer="cycles", tags=("repetitive", "cluttered"))]

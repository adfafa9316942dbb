"""A lecture hall: a tiered floor (one box per tier) rising away from a large board, rows of seats on thin
standards with a writing desk in front of each row, aisles with half-steps, side walls that fan out (the room is
narrower at the board than at the back), a lectern and a front desk on the flat floor before the board.

Hard for matching on purpose: row after row of identical seats, backs and desks (repetitive); seat standards,
arm rests and desk posts 3-4 cm thin (thin); and the room is not a box (a stepped floor, slanted side walls).
Coordinates: x across the hall, the board on the front (+y) wall, the tiers rising toward the back (-y) wall,
floor of the front area at z = 0.  Rigs stand on the flat front area (``bounds`` covers it): the free floor
between the board and the first row.

The ``seed`` draws the hall size (around the preset's, by ``size_jitter``), the fan of the side walls, the
seats (folded up or down, empty rows' ends), the board and lectern positions, and (through the shared kit,
``scenes/families/_kit.py``) every material (colour, texture contrast from none to strong, roughness), the
ceiling lights' power and colour temperature and the daylight in the (optional) back windows.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from scenes.families import _kit as kit
from scenes.model import Box, SceneEntry, SceneParams, SceneSpec, param


@dataclass(frozen=True)
class LectureHallParams(SceneParams):
    """The lecture hall's parameters (``tri360 scenes --params``)."""

    size: tuple[float, float, float] = param((14.0, 15.0, 5.5), "(width at the back x, depth y, height above the "
                                             "front floor z) of the hall before jitter", unit="m",
                                             limits=(4.0, 100.0))
    size_jitter: float = param(0.06, "relative hall-size jitter drawn from the seed, per axis (height: half of it)",
                               limits=(0.0, 0.5))
    front_width: float = param(0.75, "width at the board as a share of the back width, 1 = parallel walls "
                               "(jittered by +-0.05 when < 1)", limits=(0.4, 1.0))
    rows: int = param(9, "rows of seats, one per tier", limits=(0, 100))
    tread: float = param(0.95, "depth of one tier", unit="m", limits=(0.6, 3.0))
    rise: float = param(0.3, "height of one tier", unit="m", limits=(0.0, 1.0))
    front_area: float = param(4.0, "depth of the flat floor between the board and the first row", unit="m",
                              limits=(1.5, 100.0))
    aisles: int = param(2, "aisles splitting the rows into blocks: 0, 1 (centre) or 2", limits=(0, 2))
    seat_width: float = param(0.55, "seat pitch along a row", unit="m", limits=(0.3, 2.0))
    folded: float = param(0.5, "share of seats folded up", limits=(0.0, 1.0))
    windows: int = param(0, "windows high on the back (-y) wall, with daylight", limits=(0, 20))
    lights: tuple[int, int] = param((4, 5), "(nx, ny) grid of ceiling light panels", limits=(0, 100))
    light_power: tuple[float, float] = param((70.0, 100.0), "(min, max) power per ceiling area light", unit="W",
                                             limits=(0.0, None))
    kelvin: tuple[float, float] = param((3500.0, 6000.0), "(min, max) colour temperature of the ceiling lights",
                                        unit="K", limits=(1000.0, 40000.0))


def _materials(spec: SceneSpec, look: np.random.Generator) -> None:
    add = spec.add_material
    add(kit.draw_material(look, "walls", "paint", saturation=(0.0, 0.2), value=(0.6, 0.9),
                          contrast=kit.draw_contrast(look, ("none", "weak", "medium")), roughness=(0.7, 0.95),
                          scale=(0.1, 0.6)))
    add(kit.draw_material(look, "ceiling", "tiles", saturation=(0.0, 0.03), value=(0.8, 0.95),
                          contrast=kit.draw_contrast(look, ("none", "weak", "medium")), roughness=0.9, scale=0.6,
                          darker=(0.5, 0.75)))
    floor_kind = ("fabric", "tiles", "wood")[int(look.integers(3))]
    add(kit.draw_material(look, "floor", floor_kind, saturation=(0.05, 0.5), value=(0.2, 0.55),
                          contrast=kit.draw_contrast(look, ("weak", "medium", "strong")), roughness=(0.5, 1.0),
                          scale=(0.3, 0.5) if floor_kind == "tiles" else (0.04, 0.15)))
    add(kit.draw_material(look, "nosing", "metal", saturation=(0.0, 0.05), value=(0.3, 0.7), contrast=(0.0, 0.2),
                          roughness=(0.3, 0.5)))
    add(kit.draw_material(look, "seat", "fabric", saturation=(0.2, 0.8), value=(0.1, 0.5), contrast=(0.05, 0.5),
                          roughness=(0.8, 1.0), scale=(0.03, 0.1)))
    shell_kind = "wood" if look.uniform() < 0.5 else "plastic"
    add(kit.draw_material(look, "seat_shell", shell_kind, hue=(0.05, 0.12), saturation=(0.0, 0.5),
                          value=(0.2, 0.7), contrast=(0.2, 0.7) if shell_kind == "wood" else (0.0, 0.15),
                          roughness=(0.3, 0.6), scale=(0.03, 0.06)))
    add(kit.draw_material(look, "desk", "wood", hue=(0.05, 0.12), saturation=(0.2, 0.6), value=(0.3, 0.75),
                          contrast=kit.draw_contrast(look, ("weak", "medium", "strong")), roughness=(0.3, 0.6),
                          scale=(0.03, 0.06)))
    add(kit.draw_material(look, "metal", "metal", saturation=(0.0, 0.05), value=(0.25, 0.7), contrast=(0.05, 0.3),
                          roughness=(0.25, 0.5), scale=(0.1, 0.3)))
    if look.uniform() < 0.5:  # chalkboards or whiteboards
        add(kit.draw_material(look, "board", "board", hue=(0.3, 0.45), saturation=(0.2, 0.6), value=(0.1, 0.25),
                              contrast=(0.3, 0.8), roughness=0.9, scale=(0.3, 0.7), darker=(1.5, 2.5)))
    else:
        add(kit.draw_material(look, "board", "plastic", saturation=(0.0, 0.02), value=(0.88, 0.95),
                              contrast=kit.draw_contrast(look, ("none", "weak")), roughness=(0.1, 0.3)))
    add(kit.draw_material(look, "screen", "plastic", saturation=(0.0, 0.02), value=(0.6, 0.8), contrast=0.0,
                          roughness=0.9))
    add(kit.draw_material(look, "lectern", "wood", hue=(0.05, 0.1), saturation=(0.3, 0.6), value=(0.2, 0.5),
                          contrast=(0.3, 0.8), roughness=(0.4, 0.6), scale=(0.04, 0.08)))


def _seat(folded: bool) -> list:
    """One seat facing +y (local origin on the tier, below the seat's centre): pan, back, no standards."""
    pan = (Box((0.0, 0.05, 0.62), (0.46, 0.05, 0.36), "seat", name="pan") if folded else
           Box((0.0, 0.0, 0.44), (0.46, 0.42, 0.05), "seat", name="pan"))
    return [pan,
            Box((0.0, -0.24, 0.72), (0.48, 0.045, 0.52), "seat_shell", name="back"),
            Box((0.0, -0.215, 0.74), (0.44, 0.01, 0.44), "seat", name="cushion")]


def _standard() -> list:
    """The thin support between two seats: a post, a foot and an arm rest."""
    return [Box((0.0, -0.12, 0.33), (0.035, 0.035, 0.66), "metal", name="post"),
            Box((0.0, -0.12, 0.01), (0.04, 0.30, 0.02), "metal", name="foot"),
            Box((0.0, -0.05, 0.67), (0.05, 0.32, 0.03), "seat_shell", name="arm")]


def _lift(parts: list, z: float) -> list:
    """``parts`` raised by ``z`` metres (onto a tier)."""
    return [replace(p, center=(p.center[0], p.center[1], p.center[2] + z)) for p in parts]


def build(p: LectureHallParams, seed: int) -> SceneSpec:
    """Build a lecture hall."""
    layout, look = kit.streams(seed)
    jit = p.size_jitter
    W0, D0, H0 = p.size
    W, D = W0 * (1 + layout.uniform(-jit, jit)), D0 * (1 + layout.uniform(-jit, jit))
    H = H0 * (1 + 0.5 * layout.uniform(-jit, jit))
    fw = p.front_width
    Wf = W * float(np.clip(fw + (layout.uniform(-0.05, 0.05) if fw < 1 else 0.0), 0.4, 1.0))
    rows, tread, rise = p.rows, p.tread, p.rise
    front = p.front_area
    rows = min(rows, int((D - front - 0.5) // tread))
    if rows * rise > H - 2.6:
        raise ValueError(f"{rows} tiers of {rise} m leave less than 2.6 m under the {H:.2f} m ceiling at the back")
    y0 = D / 2 - front  # front edge of the first row; row k's tread spans [y0 - (k + 1) tread, y0 - k tread]

    def width_at(y: float) -> float:
        """Inner width between the slanted side walls at depth y, metres."""
        return Wf + (W - Wf) * (D / 2 - y) / D

    # rigs stand on the flat front area, inside the slanted walls
    spec = SceneSpec(name="lecture_hall", bounds=((-Wf / 2, y0, 0.0), (Wf / 2, D / 2, H)),
                     rig_height=(1.1, 1.5), background=(0.0, 0.0, 0.0))
    _materials(spec, look)
    kit.room_shell(spec, (W, D, H), "walls", "floor", "ceiling")
    b = spec.boxes

    # slanted side walls: thick wall boxes whose inner face runs from (Wf/2, D/2) to (W/2, -D/2)
    if Wf < W - 1e-6:
        t = 0.4  # wall thickness, metres
        for s in (-1, 1):
            ux, uy = s * (W - Wf) / 2, -D
            length = float(np.hypot(ux, uy))
            ux, uy = ux / length, uy / length
            nx, ny = -s * uy, s * ux  # unit normal pointing out of the hall
            b.append(Box((s * (Wf + W) / 4 + nx * t / 2, ny * t / 2, H / 2), (length + 1.0, t, H + 0.1), "walls",
                         yaw=float(np.arctan2(uy, ux)), name=f"sidewall{s}"))

    # tiers: one box per raised row, from its front edge to the back wall (the last one is the back landing),
    # each with a metal nosing on its edge
    for k in range(1, rows + 1):
        yk, z = y0 - k * tread, k * rise
        depth = yk + D / 2
        b.append(Box((0.0, -D / 2 + depth / 2 + 0.001, z / 2), (W - 0.002, depth, z), "floor", name=f"tier{k}"))
        b.append(Box((0.0, yk - 0.02, z + 0.004), (W - 0.002, 0.04, 0.008), "nosing", name=f"tier{k}.nosing"))

    # rows of seats in blocks between the aisles (which follow the fan), a desk in front of each block
    aisles = p.aisles
    aisle_w = 1.1
    fractions = {0: [], 1: [0.0]}.get(aisles, [-0.22, 0.22])
    seat_w = p.seat_width
    folded_rate = p.folded
    for k in range(rows):
        z = k * rise
        y_front = y0 - k * tread  # the row's desk is at the front of its tread, the seats behind
        wy = width_at(y_front - tread / 2)
        centres = [f * wy for f in fractions]
        edges = [-wy / 2 + 0.4] + [e for c in centres for e in (c - aisle_w / 2, c + aisle_w / 2)] + [wy / 2 - 0.4]
        ys = y_front - tread + 0.42
        for blk in range(len(edges) // 2):
            x0, x1 = edges[2 * blk], edges[2 * blk + 1]
            n = int((x1 - x0) // seat_w)
            if n < 1:
                continue
            xs = (x0 + x1) / 2 + seat_w * (np.arange(n) - (n - 1) / 2)
            name = f"row{k}.block{blk}"
            for i, x in enumerate(xs):
                kit.place(spec, f"{name}.seat{i}", float(x), ys, 0.0,
                          _lift(_seat(bool(layout.uniform() < folded_rate)), z))
            for i in range(n + 1):
                kit.place(spec, f"{name}.standard{i}", float(xs[0] - seat_w / 2 + i * seat_w), ys, 0.0,
                          _lift(_standard(), z))
            # the writing desk in front of the row, on thin posts every second seat
            b.append(Box(((x0 + x1) / 2, y_front - 0.17, z + 0.76), (n * seat_w, 0.3, 0.025), "desk",
                         name=f"{name}.desk"))
            for i in range(0, n + 1, 2):
                b.append(Box((float(xs[0] - seat_w / 2 + i * seat_w), y_front - 0.06, z + 0.375), (0.03, 0.03, 0.75),
                             "metal", name=f"{name}.post{i}"))
        # a half-step in each aisle on the back half of the tread, halfway up to the next tier
        for c in centres:
            top = z + rise / 2
            b.append(Box((c, y_front - 0.75 * tread, top / 2), (aisle_w - 0.1, tread / 2, top), "floor",
                         name=f"row{k}.step{c:+.1f}"))

    # the board wall: boards, a projection screen above, a lectern and a front desk
    n_boards = 3 if Wf > 8 else 2
    bw = min(2.4, (0.7 * Wf) / n_boards)
    bx = layout.uniform(-0.3, 0.3)
    for i in range(n_boards):
        x = bx + (i - (n_boards - 1) / 2) * (bw + 0.1)
        b.append(Box((x, D / 2 - 0.02, 1.6), (bw, 0.04, 1.3), "board", name=f"board{i}"))
        b.append(Box((x, D / 2 - 0.015, 1.6), (bw + 0.06, 0.03, 1.36), "metal", name=f"board{i}.frame"))
    b.append(Box((bx, D / 2 - 0.08, 0.93), (n_boards * (bw + 0.1), 0.1, 0.03), "metal", name="board.tray"))
    sh = min(2.6, H - 2.9)  # a projection screen above the boards, where the hall is tall enough
    if sh > 0.8:
        b.append(Box((bx, D / 2 - 0.05, 2.5 + sh / 2), (min(5.0, 0.5 * Wf), 0.02, sh), "screen", name="screen"))
    lx = layout.choice([-1, 1]) * layout.uniform(0.2, 0.35) * Wf
    kit.place(spec, "lectern", lx, D / 2 - 1.6, np.pi + layout.uniform(-0.3, 0.3),
              [Box((0.0, 0.0, 0.55), (0.6, 0.45, 1.1), "lectern"),
               Box((0.0, 0.02, 1.12), (0.66, 0.5, 0.04), "lectern", name="top")])
    kit.place(spec, "front_desk", -lx * 0.8, D / 2 - 1.8, np.pi,
              kit.table_parts(2.2, 0.8, 0.76, "lectern", "metal", leg=0.05))

    # optional daylight: windows high on the back wall, above the back landing
    n_win = p.windows
    sill = rows * rise + 1.2
    for k in range(n_win):
        x = -W / 2 + W * (k + 0.5) / n_win
        kit.add_window(spec, look, "-y", (W, D, H), along=x, width=min(2.0, 0.6 * W / n_win),
                       height=max(0.6, min(1.5, H - sill - 0.3)), sill=sill, frame="metal", name=f"window{k}")

    margin = 1.0
    xw = Wf / 2 - margin
    kit.ceiling_panels(spec, look, (-xw, -D / 2 + margin, xw, D / 2 - margin), H, p.lights,
                       power=p.light_power, kelvin=p.kelvin, panel=(1.2, 0.3), emission=6.0)
    return spec


PRESETS = {
    "hall": {"size": (14.0, 15.0, 5.5), "rows": 9, "aisles": 2, "windows": 0, "lights": (4, 5)},
    "seminar_tiers": {"size": (10.0, 10.0, 4.2), "rows": 6, "rise": 0.2, "front_width": 0.85, "front_area": 3.5,
                      "aisles": 1, "windows": 2, "lights": (3, 3), "light_power": (50.0, 80.0)},
    "steep": {"size": (16.0, 16.0, 7.0), "rows": 10, "rise": 0.38, "tread": 1.0, "front_width": 0.6,
              "aisles": 2, "folded": 0.8, "windows": 3, "lights": (4, 6), "light_power": (90.0, 130.0)},
}

# version: the scene code version frames and suite ids record; change it when what build() builds changes,
# and only then (tests/scenes/test_scene_fingerprints.py; scenes/README.md)
SCENES = [SceneEntry(name="lecture_hall", version="sha256:91d0c40d526a51ef",
                     build=build, presets=PRESETS, default_preset="hall",
                     description="lecture hall (14 x 15 x 5.5 m): tiered floor, rows of seats, fanned walls, board",
                     parameters=LectureHallParams, renderer="cycles", tags=("thin", "repetitive"))]

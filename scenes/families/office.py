"""An open-plan office: clusters of desks facing each other behind low partitions, a monitor and clutter on
every desk, office chairs on a thin column and a five-spoke base, cabinets and plants along the walls.

Hard for matching on purpose: the same desk, monitor and chair repeat across the room (repetitive), chair
columns, spokes, monitor necks and table legs are 2-4 cm thin (thin), and the desks carry papers, mugs,
keyboards and binders at random (cluttered).  Coordinates: room centred on x = y = 0, floor at z = 0; windows
(if any) on the -x wall, the door on the +x wall, a whiteboard on the front (+y) wall, cabinets on the back
(-y) wall.  Desk clusters run along x; aisles of ``aisle`` metres separate them (that is where rigs stand).

The ``seed`` draws the room size (around the preset's, by ``size_jitter``), how many clusters fit, which desks
are occupied, how chairs are pulled out and turned, the clutter on each desk, the cabinets and plants, and
(through the shared kit, ``scenes/families/_kit.py``) every material (colour, texture contrast from none to
strong, roughness), the ceiling lights' power and colour temperature and the daylight in the windows.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from scenes.families import _kit as kit
from scenes.model import Box, Cylinder, SceneEntry, SceneParams, SceneSpec, Sphere, param


@dataclass(frozen=True)
class OfficeParams(SceneParams):
    """The office's parameters (``tri360 scenes --params``)."""

    size: tuple[float, float, float] = kit.room_size_param((12.0, 10.0, 2.8))
    size_jitter: float = kit.size_jitter_param(0.08)
    desks_per_side: int = param(2, "desks side by side in each half of a cluster (a cluster has twice as many)",
                                limits=(1, 20))
    aisle: float = param(1.2, "free aisle between clusters (chairs included); as many clusters as fit", unit="m",
                         limits=(0.5, 20.0))
    occupancy: float = param(0.85, "share of desks with a monitor and a chair", limits=(0.0, 1.0))
    clutter: float = param(3.0, "mean number of small objects (papers, mugs, binders) per occupied desk",
                           limits=(0.0, 50.0))
    windows: int = param(3, "windows on the -x wall, with daylight", limits=(0, 20))
    lights: tuple[int, int] = param((4, 3), "(nx, ny) grid of ceiling light panels", limits=(0, 100))
    light_power: tuple[float, float] = param((30.0, 45.0), "(min, max) power per ceiling area light", unit="W",
                                             limits=(0.0, None))
    kelvin: tuple[float, float] = param((3500.0, 6000.0), "(min, max) colour temperature of the ceiling lights",
                                        unit="K", limits=(1000.0, 40000.0))

DESK_W, DESK_D, DESK_H = 1.4, 0.75, 0.76  # one desk, metres (the top, 0.735-0.76 m, spans a 0.75 m sample of the
# rig-placement check, which tests the column under each camera every 10 cm from 0.05 m: no rig hovers over a desk)
CHAIR_OUT = 0.7  # how far a chair (and the person's room) reaches behind the desk edge, metres


def _materials(spec: SceneSpec, look: np.random.Generator) -> None:
    add = spec.add_material
    add(kit.draw_material(look, "walls", "paint", saturation=(0.0, 0.12), value=(0.7, 0.92),
                          contrast=kit.draw_contrast(look, ("none", "weak", "medium"), (2, 2, 1)),
                          roughness=(0.7, 0.95), scale=(0.1, 0.5)))
    add(kit.draw_material(look, "ceiling", "tiles", saturation=(0.0, 0.03), value=(0.82, 0.95),
                          contrast=kit.draw_contrast(look, ("none", "weak", "medium")), roughness=0.9,
                          scale=0.6, darker=(0.5, 0.7)))
    carpet_kind = "tiles" if look.uniform() < 0.5 else "fabric"  # carpet tiles or broadloom
    add(kit.draw_material(look, "carpet", carpet_kind, saturation=(0.05, 0.4), value=(0.2, 0.5),
                          contrast=kit.draw_contrast(look, ("weak", "medium", "strong")), roughness=(0.85, 1.0),
                          scale=0.5 if carpet_kind == "tiles" else (0.05, 0.2), darker=(0.5, 0.8)))
    add(kit.draw_material(look, "baseboard", "plastic", saturation=(0.0, 0.1), value=(0.1, 0.4), contrast=0.0,
                          roughness=0.5))
    top_kind = "wood" if look.uniform() < 0.5 else "plastic"
    add(kit.draw_material(look, "desk", top_kind, hue=(0.05, 0.12), saturation=(0.0, 0.5), value=(0.45, 0.9),
                          contrast=(0.3, 0.8) if top_kind == "wood" else kit.draw_contrast(look, ("none", "weak")),
                          roughness=(0.3, 0.6), scale=(0.03, 0.06)))
    add(kit.draw_material(look, "metal", "metal", saturation=(0.0, 0.05), value=(0.3, 0.8), contrast=(0.05, 0.3),
                          roughness=(0.25, 0.5), scale=(0.1, 0.3)))
    add(kit.draw_material(look, "partition", "fabric", saturation=(0.1, 0.6), value=(0.3, 0.7),
                          contrast=kit.draw_contrast(look), roughness=(0.85, 1.0), scale=(0.03, 0.1)))
    add(kit.draw_material(look, "seat", "fabric", saturation=(0.0, 0.6), value=(0.08, 0.4),
                          contrast=(0.05, 0.4), roughness=(0.8, 1.0), scale=(0.03, 0.1)))
    add(kit.draw_material(look, "plastic_dark", "plastic", saturation=(0.0, 0.05), value=(0.03, 0.12),
                          contrast=(0.0, 0.15), roughness=(0.2, 0.4)))
    add(kit.draw_material(look, "screen", "emission", saturation=(0.0, 0.3), value=(0.4, 0.8),
                          contrast=kit.draw_contrast(look, ("weak", "medium", "strong")), scale=(0.02, 0.06),
                          emission=float(look.uniform(0.6, 1.4))))
    add(kit.draw_material(look, "paper", "paint", saturation=(0.0, 0.05), value=(0.85, 0.95), contrast=0.0,
                          roughness=0.9))
    for k in range(4):
        add(kit.draw_material(look, f"thing{k}", "plastic", saturation=(0.3, 0.9), value=(0.3, 0.9),
                              contrast=(0.0, 0.3), roughness=(0.2, 0.6)))
    add(kit.draw_material(look, "cabinet", "metal", saturation=(0.0, 0.15), value=(0.4, 0.85),
                          contrast=(0.05, 0.3), roughness=(0.3, 0.6), scale=(0.1, 0.3)))
    add(kit.draw_material(look, "whiteboard", "plastic", saturation=(0.0, 0.02), value=(0.9, 0.95), contrast=0.0,
                          roughness=(0.1, 0.25)))
    add(kit.draw_material(look, "door", "wood", hue=(0.05, 0.1), saturation=(0.3, 0.6), value=(0.3, 0.6),
                          contrast=(0.3, 0.7), roughness=(0.4, 0.6), scale=(0.04, 0.08)))
    add(kit.draw_material(look, "pot", "plastic", saturation=(0.0, 0.4), value=(0.2, 0.7), contrast=(0.0, 0.2),
                          roughness=(0.3, 0.6)))
    add(kit.draw_material(look, "leaves", "noise", hue=(0.22, 0.36), saturation=(0.5, 0.8), value=(0.25, 0.5),
                          contrast=(0.7, 1.0), roughness=(0.6, 0.9), scale=(0.03, 0.08), darker=(0.3, 0.5)))


def _office_chair(seat: str, metal: str, dark: str) -> list:
    """An office chair facing +y: seat, back on a post, a gas column and a five-spoke base (thin parts)."""
    parts: list = [Box((0.0, 0.0, 0.47), (0.48, 0.46, 0.07), seat, name="seat"),
                   Box((0.0, -0.24, 0.80), (0.44, 0.05, 0.48), seat, name="back"),
                   Box((0.0, -0.24, 0.55), (0.05, 0.03, 0.14), dark, name="backpost"),
                   Cylinder((0.0, 0.0, 0.25), 0.022, 0.40, metal, name="column")]
    for k in range(5):
        a = 2 * np.pi * k / 5
        parts.append(Box((0.15 * np.cos(a), 0.15 * np.sin(a), 0.06), (0.30, 0.03, 0.03), dark, yaw=a,
                         name=f"spoke{k}"))
        parts.append(Cylinder((0.29 * np.cos(a), 0.29 * np.sin(a), 0.025), 0.025, 0.05, dark, axis="x", yaw=a,
                              name=f"castor{k}"))
    return parts


def _desk(layout: np.random.Generator, occupied: bool, clutter: float) -> list:
    """One desk facing +y (the user sits at -y) with, when occupied, a monitor, keyboard and clutter."""
    parts = kit.table_parts(DESK_W, DESK_D, DESK_H, "desk", "metal", leg=0.035, thick=0.025,
                            round_legs=bool(layout.uniform() < 0.5))
    if not occupied:
        return parts
    mx = layout.uniform(-0.3, 0.3)
    top = DESK_H
    parts += [Box((mx, 0.18, top + 0.32), (0.56, 0.025, 0.34), "plastic_dark", name="monitor"),
              Box((mx, 0.165, top + 0.32), (0.52, 0.002, 0.30), "screen", name="screen"),
              Cylinder((mx, 0.20, top + 0.08), 0.015, 0.16, "metal", name="neck"),
              Box((mx, 0.20, top + 0.005), (0.22, 0.16, 0.01), "metal", name="stand"),
              Box((mx + layout.uniform(-0.05, 0.05), -0.12, top + 0.012), (0.44, 0.14, 0.024), "plastic_dark",
                  yaw=layout.uniform(-0.1, 0.1), name="keyboard")]
    if layout.uniform() < 0.5:  # a second monitor
        sx = mx + (0.6 if mx < 0 else -0.6)
        parts += [Box((sx, 0.16, top + 0.30), (0.5, 0.025, 0.3), "plastic_dark", yaw=-0.3 * np.sign(sx - mx),
                      name="monitor2"),
                  Cylinder((sx, 0.19, top + 0.07), 0.015, 0.14, "metal", name="neck2")]
    for k in range(int(layout.poisson(clutter))):
        x, y = layout.uniform(-DESK_W / 2 + 0.12, DESK_W / 2 - 0.12), layout.uniform(-DESK_D / 2 + 0.1, 0.05)
        kind = layout.integers(4)
        mat = f"thing{int(layout.integers(4))}"
        if kind == 0:  # a sheet or a stack of paper
            h = 0.004 * (1 + k)  # distinct heights: overlapping sheets never share a plane
            parts.append(Box((x, y, top + h / 2), (0.21, 0.297, h), "paper", yaw=layout.uniform(-0.6, 0.6),
                             name=f"paper{k}"))
        elif kind == 1:  # a mug
            parts.append(Cylinder((x, y, top + 0.05), 0.04, 0.1, mat, name=f"mug{k}"))
        elif kind == 2:  # a standing binder
            parts.append(Box((x, 0.2, top + 0.16), (0.06, 0.28, 0.32), mat, yaw=layout.uniform(-0.15, 0.15),
                             name=f"binder{k}"))
        else:  # a box or a phone
            s = layout.uniform(0.08, 0.25, 3)
            parts.append(Box((x, y, top + s[2] / 2), tuple(s), mat, yaw=layout.uniform(-np.pi, np.pi),
                             name=f"box{k}"))
    return parts


def build(p: OfficeParams, seed: int) -> SceneSpec:
    """Build an open-plan office."""
    layout, look = kit.streams(seed)
    jit = p.size_jitter
    W0, D0, H0 = p.size
    W, D = W0 * (1 + layout.uniform(-jit, jit)), D0 * (1 + layout.uniform(-jit, jit))
    H = H0 * (1 + 0.5 * layout.uniform(-jit, jit))
    spec = SceneSpec(name="office", bounds=((-W / 2, -D / 2, 0.0), (W / 2, D / 2, H)),
                     rig_height=(1.1, min(1.5, H - 0.9)), background=(0.0, 0.0, 0.0))
    _materials(spec, look)
    kit.room_shell(spec, (W, D, H), "walls", "carpet", "ceiling", baseboard="baseboard")
    b = spec.boxes

    # along the walls: cabinets at the back, a whiteboard at the front, the door on +x
    wall_zone = 0.55  # depth kept for cabinets and plants along the walls, metres
    n_cab = int(layout.integers(3, max(4, int(W / 1.2))))
    x = -W / 2 + 0.6 + layout.uniform(0.0, 1.0)
    for k in range(n_cab):
        w, h = layout.choice([0.8, 1.0, 1.2]), layout.choice([0.75, 1.1, 1.9])
        if x + w > W / 2 - 0.8:
            break
        kit.place(spec, f"cabinet{k}", x + w / 2, -D / 2 + 0.23, 0.0,
                  [Box((0.0, 0.0, h / 2), (w, 0.44, h), "cabinet"),
                   *[Box((0.0, 0.225, z), (0.3, 0.012, 0.025), "metal", name=f"handle{i}")
                     for i, z in enumerate(np.arange(0.3, h - 0.1, 0.37) + 0.1)]])
        x += w + layout.uniform(0.0, 0.4)
    wb_x = layout.uniform(-W / 4, W / 4)
    b.append(Box((wb_x, D / 2 - 0.015, 1.45), (min(2.4, W / 4), 0.03, 1.2), "whiteboard", name="whiteboard"))
    dy = layout.uniform(-D / 2 + 1.0, D / 2 - 1.0)
    b.append(Box((W / 2 - 0.025, dy, 1.05), (0.05, 0.95, 2.1), "door", name="door"))
    b.append(Box((W / 2 - 0.07, dy - 0.35, 1.0), (0.05, 0.12, 0.025), "metal", name="door.handle"))

    # windows with daylight on the -x wall
    n_win = p.windows
    for k in range(n_win):
        y = -D / 2 + D * (k + 0.5) / n_win
        kit.add_window(spec, look, "-x", (W, D, H), along=y, width=min(1.8, 0.8 * D / n_win),
                       height=min(1.5, H - 1.2), sill=0.85, frame="metal", name=f"window{k}")

    # desk clusters: two rows of desks facing each other, a partition between them
    per_side = p.desks_per_side
    aisle = p.aisle
    cw = per_side * DESK_W  # cluster width along x
    cd = 2 * (DESK_D + CHAIR_OUT)  # cluster depth along y, chairs included
    free_w, free_d = W - 2 * wall_zone, D - 2 * wall_zone
    edge = 0.75 * aisle  # the free floor between the outer clusters and the wall zone, at least
    cols = max(1, int((free_w - 2 * edge + aisle) // (cw + aisle)))
    rows = max(1, int((free_d - 2 * edge + aisle) // (cd + aisle)))
    gx = (free_w - cols * cw) / (cols + 1)  # the gaps actually left, spread evenly
    gy = (free_d - rows * cd) / (rows + 1)
    occupancy, clutter = p.occupancy, p.clutter
    for i in range(cols):
        for j in range(rows):
            cx = -free_w / 2 + gx + cw / 2 + i * (cw + gx) + layout.uniform(-0.1, 0.1) * max(gx - aisle, 0)
            cy = -free_d / 2 + gy + cd / 2 + j * (cd + gy) + layout.uniform(-0.1, 0.1) * max(gy - aisle, 0)
            name = f"cluster{i}_{j}"
            kit.place(spec, f"{name}.partition", cx, cy, 0.0,
                      [Box((0.0, 0.0, DESK_H + 0.2), (cw, 0.03, 0.4), "partition"),
                       Box((0.0, 0.0, DESK_H + 0.41), (cw, 0.04, 0.02), "metal", name="rail")])
            for side, yaw in ((-1, 0.0), (1, np.pi)):  # desks at -y face +y; desks at +y face -y
                for k in range(per_side):
                    dx = -cw / 2 + DESK_W * (k + 0.5)
                    x, y = cx + dx, cy + side * (DESK_D / 2 + 0.02)
                    occupied = bool(layout.uniform() < occupancy)
                    kit.place(spec, f"{name}.desk{side}_{k}", x, y, yaw, _desk(layout, occupied, clutter))
                    if occupied or layout.uniform() < 0.3:
                        off = DESK_D / 2 + layout.uniform(0.05, 0.4)
                        cyaw = yaw + layout.uniform(-0.6, 0.6)
                        kit.place(spec, f"{name}.chair{side}_{k}", x + layout.uniform(-0.25, 0.25),
                                  y + side * off, cyaw, _office_chair("seat", "metal", "plastic_dark"))

    # plants in the corners of the wall zone
    for k, (sx, sy) in enumerate([(-1, 1), (1, 1), (1, -1)]):
        if layout.uniform() < 0.35:
            continue
        px, py = sx * (W / 2 - 0.4), sy * (D / 2 - 0.4)
        r = layout.uniform(0.15, 0.25)
        kit.place(spec, f"plant{k}", px, py, 0.0,
                  [Cylinder((0.0, 0.0, 0.22), r, 0.44, "pot", name="pot"),
                   Sphere((0.0, 0.0, 0.44 + layout.uniform(0.3, 0.5)), layout.uniform(0.25, 0.32), "leaves",
                          name="crown")])

    margin = 0.6
    kit.ceiling_panels(spec, look, (-W / 2 + margin, -D / 2 + margin, W / 2 - margin, D / 2 - margin), H,
                       p.lights, power=p.light_power, kelvin=p.kelvin, panel=(0.6, 0.6), emission=5.0)
    return spec


PRESETS = {
    "open_plan": {"size": (12.0, 10.0, 2.8), "desks_per_side": 2, "windows": 3, "lights": (4, 3)},
    "small": {"size": (8.0, 6.5, 2.7), "desks_per_side": 2, "windows": 2, "lights": (3, 2),
              "light_power": (35.0, 50.0)},
    "dense": {"size": (14.0, 11.0, 2.8), "desks_per_side": 3, "aisle": 1.1, "occupancy": 1.0, "clutter": 5.0,
              "windows": 0, "lights": (5, 4), "light_power": (35.0, 50.0)},
}

# version: the scene code version frames and suite ids record; change it when what build() builds changes,
# and only then (tests/scenes/test_scene_fingerprints.py; scenes/README.md)
SCENES = [SceneEntry(name="office", version="sha256:4a1029386b73bb11",
                     build=build, presets=PRESETS, default_preset="open_plan",
                     description="open-plan office (12 x 10 x 2.8 m): desk clusters, monitors, partitions, clutter",
                     parameters=OfficeParams, renderer="cycles", tags=("cluttered", "thin", "repetitive"))]

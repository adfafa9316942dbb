"""A white laboratory: a polished floor, a glossy whiteboard, metal cabinets, lab benches, stools, pipes.

Hard for matching on purpose: the floor, the whiteboard and the cabinets are glossy (their colour changes with
the viewpoint, so the three cameras see different colours at the same point: reflections), and almost
everything is white and weakly textured.  Coordinates: room centred on x = y = 0, floor at z = 0; the
whiteboard on the front (+y) wall, metal cabinets along the -x and back (-y) walls, benches in rows along x.

The ``seed`` draws the room size (around the preset's), the bench rows' positions, the stools, the cabinets'
widths, and (through the shared kit, ``scenes/families/_kit.py``) the materials (floor gloss and colour, white
or grey walls with no or weak texture, cabinet metal), the lights' power and colour temperature and the daylight.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from scenes.families import _kit as kit
from scenes.model import Box, Cylinder, Material, SceneEntry, SceneParams, SceneSpec, param


@dataclass(frozen=True)
class LabParams(SceneParams):
    """The laboratory's parameters (``tri360 scenes --params``)."""

    size: tuple[float, float, float] = kit.room_size_param((9.0, 7.0, 3.0))
    size_jitter: float = kit.size_jitter_param(0.08)
    benches: int = param(2, "rows of lab benches (island benches along x)", limits=(0, 20))
    floor_roughness: tuple[float, float] = param((0.04, 0.15), "(min, max) roughness of the polished floor, "
                                                 "0 = mirror", limits=(0.0, 1.0))
    windows: int = param(2, "windows on the +x wall, with daylight", limits=(0, 20))
    lights: tuple[int, int] = param((3, 2), "(nx, ny) grid of ceiling light panels", limits=(0, 100))
    light_power: tuple[float, float] = param((28.0, 40.0), "(min, max) power per ceiling area light", unit="W",
                                             limits=(0.0, None))
    kelvin: tuple[float, float] = param((4000.0, 6500.0), "(min, max) colour temperature of the ceiling lights",
                                        unit="K", limits=(1000.0, 40000.0))


def build(p: LabParams, seed: int) -> SceneSpec:
    """Build a laboratory."""
    layout, look = kit.streams(seed)
    jit = p.size_jitter
    W0, D0, H0 = p.size
    W, D = W0 * (1 + layout.uniform(-jit, jit)), D0 * (1 + layout.uniform(-jit, jit))
    H = H0 * (1 + 0.5 * layout.uniform(-jit, jit))
    spec = SceneSpec(name="lab", bounds=((-W / 2, -D / 2, 0.0), (W / 2, D / 2, H)),
                     rig_height=(1.1, min(1.5, H - 0.9)), background=(0.0, 0.0, 0.0))

    rough = p.floor_roughness
    spec.add_material(kit.draw_material(look, "floor", "tiles", saturation=(0.0, 0.08), value=(0.7, 0.9),
                                        contrast=kit.draw_contrast(look, ("weak", "medium"), (3, 1)),
                                        roughness=rough, scale=(0.45, 0.65), darker=(0.75, 0.9)))
    spec.add_material(kit.draw_material(look, "walls", "paint", saturation=(0.0, 0.04), value=(0.85, 0.95),
                                        contrast=kit.draw_contrast(look, ("none", "weak")), roughness=(0.6, 0.9),
                                        scale=(0.2, 0.5)))
    spec.add_material(kit.draw_material(look, "ceiling", "tiles", saturation=(0.0, 0.02), value=(0.88, 0.95),
                                        contrast=(0.05, 0.2), roughness=0.9, scale=0.6, darker=(0.7, 0.85)))
    spec.add_material(Material("whiteboard", kind="plastic", color=(0.86, 0.87, 0.87), contrast=0.0,
                               roughness=float(look.uniform(0.04, 0.12))))
    spec.add_material(kit.draw_material(look, "cabinet", "metal", hue=(0.5, 0.65), saturation=(0.0, 0.12),
                                        value=(0.6, 0.85), contrast=(0.05, 0.25), roughness=(0.12, 0.3),
                                        scale=(0.2, 0.4)))
    spec.add_material(kit.draw_material(look, "bench_top", "plastic", saturation=(0.0, 0.05),
                                        value=(0.8, 0.92) if look.uniform() < 0.5 else (0.08, 0.15),  # white / black
                                        contrast=(0.0, 0.15), roughness=(0.1, 0.3)))
    spec.add_material(kit.draw_material(look, "bench_body", "plastic", saturation=(0.0, 0.05), value=(0.8, 0.92),
                                        contrast=(0.0, 0.05), roughness=(0.3, 0.5)))
    spec.add_material(kit.draw_material(look, "steel", "metal", saturation=(0.0, 0.03), value=(0.6, 0.8),
                                        contrast=(0.1, 0.3), roughness=(0.15, 0.35), scale=(0.1, 0.3)))
    spec.add_material(kit.draw_material(look, "stool", "plastic", saturation=(0.3, 0.8), value=(0.3, 0.7),
                                        contrast=(0.0, 0.2), roughness=(0.3, 0.5)))
    spec.add_material(kit.draw_material(look, "glassware", "plastic", saturation=(0.0, 0.5), value=(0.4, 0.9),
                                        contrast=(0.0, 0.2), roughness=(0.05, 0.2)))
    spec.add_material(kit.draw_material(look, "poster", "noise", saturation=(0.3, 0.9), value=(0.5, 0.9),
                                        contrast=(0.7, 1.0), scale=(0.04, 0.1), darker=(0.2, 0.5)))
    spec.add_material(Material("frame", kind="metal", color=(0.7, 0.7, 0.72), contrast=0.1, roughness=0.3))
    spec.add_material(Material("baseboard", kind="plastic", color=(0.25, 0.25, 0.26), contrast=0.0, roughness=0.4))

    kit.room_shell(spec, (W, D, H), "walls", "floor", "ceiling", baseboard="baseboard")
    b = spec.boxes

    # front wall: a glossy whiteboard in a frame; a poster beside it
    bw = min(3.0, 0.4 * W)
    bx = layout.uniform(-0.15, 0.15) * W
    b.append(Box((bx, D / 2 - 0.015, 1.5), (bw + 0.06, 0.03, 1.26), "frame", name="board.frame"))
    b.append(Box((bx, D / 2 - 0.035, 1.5), (bw, 0.02, 1.2), "whiteboard", name="whiteboard"))
    b.append(Box((bx + np.sign(-bx or 1) * (bw / 2 + 0.9), D / 2 - 0.01, 1.6), (0.6, 0.02, 0.85), "poster",
                 name="poster"))

    # metal cabinets along the -x wall (tall) and the back wall (base cabinets with a worktop)
    y = -D / 2 + 0.6
    k = 0
    while y < D / 2 - 1.4:
        w = float(layout.choice([0.6, 0.8, 1.0]))
        if y + w > D / 2 - 1.4:
            break
        b.append(Box((-W / 2 + 0.3, y + w / 2, 1.0), (0.58, w - 0.01, 2.0), "cabinet", name=f"cabinet{k}"))
        b.append(Box((-W / 2 + 0.6, y + w / 2 + 0.3 * w - 0.05, 1.05), (0.03, 0.02, 0.3), "steel",
                     name=f"cabinet{k}.handle"))
        y += w
        k += 1
    x0 = -W / 2 + 1.0
    nbase = int((W - 2.0) / 0.6)
    for i in range(nbase):
        b.append(Box((x0 + 0.6 * (i + 0.5), -D / 2 + 0.3, 0.43), (0.59, 0.58, 0.86), "cabinet", name=f"base{i}"))
    b.append(Box((x0 + 0.3 * nbase, -D / 2 + 0.31, 0.885), (0.6 * nbase + 0.02, 0.62, 0.03), "bench_top",
                 name="worktop"))
    for i in range(int(layout.integers(3, 7))):  # bottles and beakers on the worktop (cylinders)
        r = layout.uniform(0.03, 0.07)
        h = layout.uniform(0.1, 0.3)
        bx_, by_ = x0 + layout.uniform(0.2, 0.6 * nbase - 0.2), -D / 2 + layout.uniform(0.15, 0.45)
        spec.cylinders.append(Cylinder((bx_, by_, 0.9 + h / 2), r, h, "glassware", name=f"bottle{i}"))

    # island benches: rows along x, each a glossy top on white cabinet bodies, with stools
    rows = p.benches
    length = min(4.0, W - 3.4)
    ys = kit.row((0.0, -D / 2 + 2.0), (0.0, D / 2 - 2.0), rows)[:, 1] if rows else []
    for r_, yb in enumerate(ys):
        xb = layout.uniform(-0.3, 0.3) + 0.3
        yb = float(yb) + layout.uniform(-0.15, 0.15)
        b.append(Box((xb, yb, 0.885), (length, 0.9, 0.03), "bench_top", name=f"bench{r_}.top"))
        for s in (-1, 1):  # cabinet bodies at the ends, a knee space in the middle
            b.append(Box((xb + s * (length / 2 - 0.45), yb, 0.435), (0.88, 0.86, 0.87), "bench_body",
                         name=f"bench{r_}.body{s:+d}"))
        # a service spine under the middle (0.2 m deep: no rig is placed hovering over the bench's knee space)
        b.append(Box((xb, yb, 0.4), (length - 1.8, 0.2, 0.8), "bench_body", name=f"bench{r_}.spine"))
        # a shelf of reagents on steel posts above the bench
        for s in (-1, 1):
            spec.cylinders.append(Cylinder((xb + s * (length / 2 - 0.1), yb, 1.25), 0.015, 0.7, "steel",
                                           name=f"bench{r_}.post{s:+d}"))
        b.append(Box((xb, yb, 1.45), (length - 0.1, 0.3, 0.02), "steel", name=f"bench{r_}.shelf"))
        for i in range(int(layout.integers(2, 6))):
            r = layout.uniform(0.03, 0.06)
            h = layout.uniform(0.1, 0.22)
            spec.cylinders.append(Cylinder((xb + layout.uniform(-length / 2 + 0.2, length / 2 - 0.2), yb, 1.46 + h / 2),
                                           r, h, "glassware", name=f"bench{r_}.jar{i}"))
        for side in (-1, 1):  # stools at the knee space
            for i in range(2):
                if layout.uniform() < 0.25:
                    continue
                sx = xb + (i - 0.5) * 0.6 + layout.uniform(-0.1, 0.1)
                sy = yb + side * (0.75 + layout.uniform(0.0, 0.15))
                kit.place(spec, f"stool{r_}_{side:+d}_{i}", sx, sy, layout.uniform(0, 2 * np.pi),
                          kit.stool_parts("stool", "steel", h=0.62, radius=0.17, leg=0.022))

    # exposed pipes along the ceiling (horizontal cylinders) and a fume-hood-like box at the front -x corner
    for i in range(int(layout.integers(1, 4))):
        spec.cylinders.append(Cylinder((0.0, D / 2 - 0.3 - 0.15 * i, H - 0.2 - 0.05 * i), layout.uniform(0.03, 0.06),
                                       W - 0.02, "steel", axis="x", name=f"pipe{i}"))
    b.append(Box((-W / 2 + 0.5, D / 2 - 0.8, 1.2), (0.98, 1.2, 2.4), "bench_body", name="hood"))

    # windows with daylight on the +x wall
    n_win = p.windows
    for k in range(n_win):
        yw = -D / 2 + D * (k + 0.5) / n_win
        kit.add_window(spec, look, "+x", (W, D, H), along=yw, width=min(1.6, 0.7 * D / n_win), height=1.5,
                       sill=0.95, frame="frame", fill_power=(20.0, 40.0), name=f"window{k}",
                       sky=None if k == 0 else "window0.sky")

    kit.ceiling_panels(spec, look, (-W / 2 + 0.5, -D / 2 + 0.5, W / 2 - 0.5, D / 2 - 0.5), H,
                       p.lights, power=p.light_power, kelvin=p.kelvin, panel=(1.2, 0.3), emission=6.0)
    return spec


PRESETS = {
    "default": {"size": (9.0, 7.0, 3.0), "benches": 2, "windows": 2, "lights": (3, 2)},
    "mirror": {"size": (8.0, 6.5, 3.0), "benches": 1, "windows": 1, "lights": (2, 2),
               "floor_roughness": (0.01, 0.04)},
    "large": {"size": (12.0, 9.0, 3.2), "benches": 3, "windows": 3, "lights": (4, 3), "light_power": (30.0, 45.0)},
}

# version: the scene code version frames and suite ids record; change it when what build() builds changes,
# and only then (tests/scenes/test_scene_fingerprints.py; scenes/README.md)
SCENES = [SceneEntry(name="lab", version="sha256:6cdc2da813615981",
                     build=build, presets=PRESETS, default_preset="default",
                     description="white laboratory (9 x 7 x 3 m): polished floor, glossy whiteboard, metal cabinets",
                     parameters=LabParams, renderer="cycles", tags=("reflective", "weak_texture"))]

"""A long corridor (about 30 m): rows of doors on both walls, a row of ceiling lights, a window at the far end.

Hard for matching on purpose: distances past 15 m along the corridor (tiny disparities at a 0.4 m baseline),
and repetition: identical doors, door frames, radiators, ceiling lights and floor tiles at regular spacing.
Coordinates: corridor centred on x = y = 0 and running along y, floor at z = 0; the window is in the +y end
wall, a double door in the -y end wall.

The ``seed`` draws the corridor length and width (around the preset's), the door spacing and which door slots
are used on each side, radiators, notice boards and fire extinguishers, and (through the shared kit,
``scenes/families/_kit.py``) the materials (tile size and contrast, wall paint from plain to textured, door
colour), the lights' power and colour temperature and the daylight.
"""

from __future__ import annotations

from dataclasses import dataclass

from scenes.families import _kit as kit
from scenes.model import Box, Cylinder, Material, SceneEntry, SceneParams, SceneSpec, param


@dataclass(frozen=True)
class CorridorParams(SceneParams):
    """The corridor's parameters (``tri360 scenes --params``)."""

    length: float = param(30.0, "corridor length along y before jitter", unit="m", limits=(4.0, 500.0))
    width: float = param(2.4, "corridor width along x before jitter", unit="m", limits=(1.0, 20.0))
    height: float = param(2.8, "ceiling height", unit="m", limits=(2.0, 20.0))
    size_jitter: float = param(0.1, "relative jitter of length and width drawn from the seed", limits=(0.0, 0.5))
    door_spacing: tuple[float, float] = param((3.2, 4.0), "(min, max) spacing of the door slots along each wall",
                                              unit="m", limits=(1.5, 100.0))
    light_spacing: float = param(4.0, "spacing of the ceiling lights along the corridor", unit="m",
                                 limits=(0.5, 100.0))
    light_power: tuple[float, float] = param((30.0, 45.0), "(min, max) power per ceiling area light", unit="W",
                                             limits=(0.0, None))
    kelvin: tuple[float, float] = param((3500.0, 6000.0), "(min, max) colour temperature of the ceiling lights",
                                        unit="K", limits=(1000.0, 40000.0))


def build(p: CorridorParams, seed: int) -> SceneSpec:
    """Build a corridor."""
    layout, look = kit.streams(seed)
    jit = p.size_jitter
    L = p.length * (1 + layout.uniform(-jit, jit))
    W = p.width * (1 + layout.uniform(-jit, jit))
    H = p.height
    spec = SceneSpec(name="corridor", bounds=((-W / 2, -L / 2, 0.0), (W / 2, L / 2, H)),
                     rig_height=(1.1, min(1.5, H - 0.9)), background=(0.0, 0.0, 0.0))

    spec.add_material(kit.draw_material(look, "floor", "tiles", saturation=(0.0, 0.2), value=(0.45, 0.75),
                                        contrast=kit.draw_contrast(look, ("medium", "strong")),
                                        roughness=(0.2, 0.5), scale=(0.3, 0.6), darker=(0.4, 0.7)))
    spec.add_material(kit.draw_material(look, "walls", "paint", saturation=(0.0, 0.25), value=(0.6, 0.9),
                                        contrast=kit.draw_contrast(look, ("none", "weak", "medium"), (1, 2, 1)),
                                        roughness=(0.6, 0.9), scale=(0.1, 0.4)))
    spec.add_material(kit.draw_material(look, "ceiling", "tiles", saturation=(0.0, 0.03), value=(0.8, 0.92),
                                        contrast=(0.2, 0.45), roughness=0.9, scale=0.6, darker=(0.5, 0.7)))
    door_kind = "wood" if look.uniform() < 0.5 else "paint"
    spec.add_material(kit.draw_material(look, "door", door_kind, hue=(0.0, 1.0) if door_kind == "paint" else
                                        (0.05, 0.1), saturation=(0.2, 0.6), value=(0.3, 0.7),
                                        contrast=(0.4, 0.8) if door_kind == "wood" else (0.0, 0.1),
                                        roughness=(0.3, 0.6), scale=(0.04, 0.08)))
    spec.add_material(kit.draw_material(look, "frame", "metal", saturation=(0.0, 0.1), value=(0.3, 0.8),
                                        contrast=(0.05, 0.2), roughness=(0.3, 0.5)))
    spec.add_material(kit.draw_material(look, "baseboard", "plastic", saturation=(0.0, 0.1), value=(0.1, 0.4),
                                        contrast=0.0, roughness=(0.4, 0.6)))
    spec.add_material(Material("radiator", kind="paint", color=(0.8, 0.8, 0.78), contrast=0.05, roughness=0.4))
    spec.add_material(Material("extinguisher", kind="plastic", color=(0.6, 0.03, 0.02), contrast=0.0,
                               roughness=0.25))
    spec.add_material(kit.draw_material(look, "notice", "noise", saturation=(0.3, 0.8), value=(0.5, 0.9),
                                        contrast=(0.7, 1.0), scale=(0.03, 0.08), darker=(0.2, 0.5)))
    spec.add_material(Material("cork", kind="noise", color=(0.55, 0.38, 0.22), scale=0.02, contrast=0.6))

    kit.room_shell(spec, (W, L, H), "walls", "floor", "ceiling", baseboard="baseboard")
    b = spec.boxes

    # doors on both walls: slots at a regular spacing, most of them used
    lo_s, hi_s = p.door_spacing
    spacing = layout.uniform(lo_s, hi_s)
    n_slots = int((L - 2.0) // spacing)
    dw, dh = 0.95, 2.1
    for side in (-1, 1):
        x = side * W / 2
        offset = layout.uniform(0.0, 0.5 * spacing) if side > 0 else 0.0
        for k in range(n_slots):
            y = -L / 2 + 1.0 + spacing * (k + 0.5) + offset
            if y > L / 2 - 1.2:
                break
            if layout.uniform() < 0.85:  # a door
                b.append(Box((x - side * 0.02, y, dh / 2 + 0.03), (0.04, dw + 0.12, dh + 0.06), "frame",
                             name=f"door{side:+d}_{k}.frame"))
                b.append(Box((x - side * 0.04, y, dh / 2), (0.04, dw, dh), "door", name=f"door{side:+d}_{k}"))
                b.append(Box((x - side * 0.08, y - 0.35, 1.0), (0.05, 0.12, 0.025), "frame",
                             name=f"door{side:+d}_{k}.handle"))
            # between slots: a radiator (repetitive fins), a notice board or a fire extinguisher
            yb = y + spacing / 2
            if yb > L / 2 - 1.0:
                continue
            what = layout.uniform()
            if what < 0.4:
                for f in range(12):
                    b.append(Box((x - side * 0.06, yb - 0.33 + 0.06 * f, 0.45), (0.08, 0.03, 0.6), "radiator",
                                 name=f"radiator{side:+d}_{k}.{f}"))
            elif what < 0.75:
                b.append(Box((x - side * 0.01, yb, 1.5), (0.02, 1.0, 0.7), "cork", name=f"board{side:+d}_{k}"))
                b.append(Box((x - side * 0.025, yb + layout.uniform(-0.25, 0.25), 1.5), (0.01, 0.3, 0.4), "notice",
                             name=f"board{side:+d}_{k}.notice"))
            elif what < 0.9:
                spec.cylinders.append(Cylinder((x - side * 0.15, yb, 0.6), 0.08, 0.5, "extinguisher",
                                               name=f"extinguisher{side:+d}_{k}"))

    # the +y end wall: a window with daylight; the -y end: a double door
    kit.add_window(spec, look, "+y", (W, L, H), along=0.0, width=min(1.6, W - 0.6), height=1.5, sill=0.9,
                   frame="frame", fill_power=(20.0, 50.0), name="window")
    b.append(Box((0.0, -L / 2 + 0.02, 1.1), (1.7, 0.04, 2.2), "frame", name="end_door.frame"))
    for s in (-1, 1):
        b.append(Box((s * 0.41, -L / 2 + 0.04, 1.05), (0.8, 0.04, 2.1), "door", name=f"end_door{s:+d}"))

    # a row of ceiling lights along the corridor, one power and colour temperature
    n_lights = max(1, int(round(L / p.light_spacing)))
    kit.ceiling_panels(spec, look, (-0.3, -L / 2, 0.3, L / 2), H, (1, n_lights),
                       power=p.light_power,
                       kelvin=p.kelvin, panel=(0.6, 1.2), emission=6.0)
    return spec


PRESETS = {
    "default": {"length": 30.0, "width": 2.4, "height": 2.8},
    "long": {"length": 45.0, "width": 2.6, "height": 3.0, "light_spacing": 5.0},
    "wide": {"length": 24.0, "width": 3.6, "height": 3.0, "door_spacing": (4.0, 5.0)},
}

# version: the scene code version frames and suite ids record; change it when what build() builds changes,
# and only then (tests/scenes/test_scene_fingerprints.py; scenes/README.md)
SCENES = [SceneEntry(name="corridor", version="sha256:dd529b9f760552af",
                     build=build, presets=PRESETS, default_preset="default",
                     description="corridor (30 x 2.4 x 2.8 m): rows of doors and ceiling lights, far range",
                     parameters=CorridorParams, renderer="cycles", tags=("far", "repetitive"))]

"""A seminar / meeting room: plain walls and ceiling, a round meeting table, chairs on thin round legs.

Hard for matching on purpose: the walls, the ceiling and the screen are (nearly) texture-less, the carpet is
only weakly textured, and the chairs stand on 2 cm round legs.  Coordinates: room centred on x = y = 0, floor at
z = 0; the screen hangs on the front (+y) wall, windows (if any) are on the -x wall, the door on the +x wall.

The ``seed`` draws the room size (around the preset's, by ``size_jitter``), where the table stands, how many
chairs there are and how they are turned, a sideboard and a plant, and (through the shared kit,
``scenes/families/_kit.py``) every material (colours, texture contrast from none to weak on walls and ceiling,
roughness), the lights' power and colour temperature and the daylight in the windows.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from scenes.families import _kit as kit
from scenes.model import Box, Cylinder, Material, SceneEntry, SceneParams, SceneSpec, Sphere, param


@dataclass(frozen=True)
class SeminarParams(SceneParams):
    """The seminar room's parameters (``tri360 scenes --params``)."""

    size: tuple[float, float, float] = kit.room_size_param((7.0, 5.5, 2.8))
    size_jitter: float = kit.size_jitter_param(0.1)
    table_radius: float = param(0.8, "radius of the round meeting table", unit="m", limits=(0.2, 10.0))
    chairs: tuple[int, int] = param((6, 9), "(min, max) number of chairs around the table", limits=(0, 100))
    windows: int = param(2, "windows on the -x wall, with daylight", limits=(0, 20))
    lights: tuple[int, int] = param((2, 2), "(nx, ny) grid of ceiling light panels", limits=(0, 100))
    light_power: tuple[float, float] = param((40.0, 60.0), "(min, max) power per ceiling area light", unit="W",
                                             limits=(0.0, None))
    kelvin: tuple[float, float] = param((3000.0, 5500.0), "(min, max) colour temperature of the ceiling lights",
                                        unit="K", limits=(1000.0, 40000.0))


def build(p: SeminarParams, seed: int) -> SceneSpec:
    """Build a seminar room."""
    layout, look = kit.streams(seed)
    jit = p.size_jitter
    W0, D0, H0 = p.size
    W, D = W0 * (1 + layout.uniform(-jit, jit)), D0 * (1 + layout.uniform(-jit, jit))
    H = H0 * (1 + 0.5 * layout.uniform(-jit, jit))
    spec = SceneSpec(name="seminar", bounds=((-W / 2, -D / 2, 0.0), (W / 2, D / 2, H)),
                     rig_height=(1.1, min(1.5, H - 0.9)), background=(0.0, 0.0, 0.0))

    # materials: plain walls and ceiling (no or weak texture), weakly textured carpet
    wall_hue = look.uniform(0.0, 1.0)
    spec.add_material(kit.draw_material(look, "walls", "paint", hue=wall_hue, saturation=(0.0, 0.15),
                                        value=(0.75, 0.92), contrast=kit.draw_contrast(look, ("none", "weak")),
                                        roughness=(0.7, 0.95), scale=(0.2, 0.6)))
    spec.add_material(kit.draw_material(look, "ceiling", "paint", saturation=(0.0, 0.03), value=(0.88, 0.95),
                                        contrast=0.0, roughness=0.9))
    spec.add_material(kit.draw_material(look, "carpet", "fabric", hue=(0.0, 1.0), saturation=(0.05, 0.35),
                                        value=(0.25, 0.5), contrast=kit.draw_contrast(look, ("weak", "medium"),
                                                                                      (3, 1)),
                                        roughness=(0.85, 1.0), scale=(0.05, 0.2)))
    spec.add_material(kit.draw_material(look, "baseboard", "plastic", saturation=(0.0, 0.1), value=(0.2, 0.9),
                                        contrast=0.0, roughness=(0.4, 0.6)))
    top_kind = "wood" if look.uniform() < 0.6 else "plastic"
    spec.add_material(kit.draw_material(look, "table", top_kind, hue=(0.05, 0.11), saturation=(0.3, 0.6),
                                        value=(0.35, 0.75), contrast=(0.3, 0.8) if top_kind == "wood" else (0.0, 0.1),
                                        roughness=(0.25, 0.5), scale=(0.03, 0.06)))
    spec.add_material(kit.draw_material(look, "seat", "fabric", saturation=(0.2, 0.7), value=(0.2, 0.6),
                                        contrast=(0.1, 0.4), roughness=(0.8, 1.0), scale=(0.05, 0.15)))
    spec.add_material(kit.draw_material(look, "chrome", "metal", saturation=(0.0, 0.05), value=(0.6, 0.8),
                                        contrast=(0.05, 0.2), roughness=(0.2, 0.4), scale=(0.1, 0.3)))
    spec.add_material(Material("screen", kind="plastic", color=(0.02, 0.02, 0.025), contrast=0.0, roughness=0.15))
    spec.add_material(kit.draw_material(look, "frame", "metal", saturation=(0.0, 0.05), value=(0.5, 0.8),
                                        contrast=(0.05, 0.2), roughness=(0.3, 0.5)))
    spec.add_material(kit.draw_material(look, "door", "wood", hue=(0.05, 0.1), saturation=(0.3, 0.6),
                                        value=(0.3, 0.6), contrast=(0.3, 0.7), roughness=(0.4, 0.6),
                                        scale=(0.04, 0.08)))
    spec.add_material(kit.draw_material(look, "pot", "plastic", saturation=(0.0, 0.4), value=(0.2, 0.7),
                                        contrast=(0.0, 0.2), roughness=(0.3, 0.6)))
    spec.add_material(kit.draw_material(look, "leaves", "noise", hue=(0.22, 0.36), saturation=(0.5, 0.8),
                                        value=(0.25, 0.5), contrast=(0.7, 1.0), roughness=(0.6, 0.9),
                                        scale=(0.03, 0.08), darker=(0.3, 0.5)))
    spec.add_material(kit.draw_material(look, "art", "noise", saturation=(0.4, 0.9), value=(0.4, 0.9),
                                        contrast=(0.8, 1.0), scale=(0.05, 0.15), darker=(0.2, 0.5)))

    kit.room_shell(spec, (W, D, H), "walls", "carpet", "ceiling", baseboard="baseboard")
    b = spec.boxes

    # front wall: a large screen; back wall: a picture; door on +x
    sw = min(2.2, 0.4 * W)
    b.append(Box((layout.uniform(-0.3, 0.3), D / 2 - 0.03, 1.55), (sw, 0.05, sw * 9 / 16), "screen", name="screen"))
    b.append(Box((layout.uniform(-1.0, 1.0), -D / 2 + 0.01, 1.6), (1.0, 0.02, 0.7), "art", name="picture"))
    dy = layout.uniform(0.0, D / 2 - 0.8)
    b.append(Box((W / 2 - 0.025, dy, 1.05), (0.05, 0.95, 2.1), "door", name="door"))
    b.append(Box((W / 2 - 0.07, dy - 0.35, 1.0), (0.05, 0.12, 0.025), "frame", name="door.handle"))

    # windows with daylight on the -x wall
    n_win = p.windows
    for k in range(n_win):
        y = -D / 2 + D * (k + 0.5) / n_win
        kit.add_window(spec, look, "-x", (W, D, H), along=y, width=min(1.4, 0.7 * D / n_win), height=1.3,
                       sill=0.9, frame="frame", sill_material="baseboard", fill_power=(15.0, 40.0),
                       name=f"window{k}", sky=None if k == 0 else "window0.sky")

    # the round meeting table near the middle, chairs around it on thin round legs
    radius = p.table_radius
    tx, ty = layout.uniform(-0.15, 0.15) * W, layout.uniform(-0.15, 0.05) * D
    kit.place(spec, "table", tx, ty, 0.0, kit.round_table_parts(radius, 0.74, "table", "chrome", column=0.06))
    lo_n, hi_n = p.chairs
    n_chairs = int(layout.integers(lo_n, hi_n + 1))
    a0 = layout.uniform(0, 2 * np.pi)
    for k in range(n_chairs):
        if layout.uniform() < 0.1:  # a chair pulled away from the table
            continue
        a = a0 + 2 * np.pi * k / n_chairs + layout.uniform(-0.1, 0.1)
        r = radius + layout.uniform(0.25, 0.45)
        x, y = tx + r * np.cos(a), ty + r * np.sin(a)
        # the chair faces the table (its +y toward the centre), turned a little
        yaw = a + np.pi / 2 + layout.uniform(-0.35, 0.35)
        kit.place(spec, f"chair{k}", x, y, yaw, kit.chair_parts("seat", "chrome", seat_h=0.46, w=0.46, d=0.44,
                                                                back_h=0.42, leg=0.02, round_legs=True))

    # a sideboard along the back wall and a plant in a corner (cylinder pot, sphere crown)
    sb_w = min(2.0, 0.35 * W)
    sb_x = layout.uniform(-W / 2 + sb_w / 2 + 0.3, W / 2 - sb_w / 2 - 0.3)
    kit.place(spec, "sideboard", sb_x, -D / 2 + 0.25, 0.0, [Box((0, 0, 0.4), (sb_w, 0.45, 0.8), "table")])
    px, py = (W / 2 - 0.45) * layout.choice([-1, 1]), (D / 2 - 0.45) * layout.choice([-1, 1])
    spec.cylinders.append(Cylinder((px, py, 0.25), 0.22, 0.5, "pot", name="plant.pot"))
    spec.cylinders.append(Cylinder((px, py, 0.65), 0.02, 0.4, "pot", name="plant.stem"))
    spec.spheres.append(Sphere((px, py, 1.1), layout.uniform(0.3, 0.4), "leaves", name="plant.crown"))

    # ceiling panels: one power and colour temperature per room
    margin = 0.8
    kit.ceiling_panels(spec, look, (-W / 2 + margin, -D / 2 + margin, W / 2 - margin, D / 2 - margin), H,
                       p.lights, power=p.light_power, kelvin=p.kelvin, panel=(0.6, 0.6), emission=5.0)
    return spec


PRESETS = {
    "default": {"size": (7.0, 5.5, 2.8), "table_radius": 0.8, "chairs": (6, 9), "windows": 2, "lights": (2, 2)},
    "large": {"size": (9.0, 7.0, 3.0), "table_radius": 1.2, "chairs": (10, 14), "windows": 3, "lights": (3, 2),
              "light_power": (45.0, 65.0)},
    "windowless": {"size": (6.0, 5.0, 2.7), "table_radius": 0.7, "chairs": (5, 7), "windows": 0, "lights": (2, 2)},
}

# version: the scene code version frames and suite ids record; change it when what build() builds changes,
# and only then (tests/scenes/test_scene_fingerprints.py; scenes/README.md)
SCENES = [SceneEntry(name="seminar", version="sha256:e4a8d8af834dd25a",
                     build=build, presets=PRESETS, default_preset="default",
                     description=("seminar room (7 x 5.5 x 2.8 m): plain walls and ceiling, round table, "
                                  "thin-legged chairs"),
                     parameters=SeminarParams, renderer="cycles", tags=("weak_texture", "thin"))]

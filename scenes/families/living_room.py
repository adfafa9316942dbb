"""A living room: plain walls and ceiling, round and curved furniture (a round coffee table on a round rug,
stools and poufs, a sofa with round arms and bolsters, spherical floor and pendant lamps), cylindrical heating
pipes and column radiators, plants in round pots, a TV on a low cabinet, windows with daylight.

Hard for matching on purpose: the walls and the ceiling are texture-less or nearly so, and so are the sofa, the
lamp shades and the TV (weak texture), and most furniture is curved (cylinders and spheres, whose silhouettes move
with the viewpoint).  Coordinates: room centred on x = y = 0, floor at z = 0; windows on the -x wall, the door on
the +x wall; the sofa stands against the -y or the +y wall (drawn from the seed), the TV faces it.

The ``seed`` draws the room size (around the preset's, by ``size_jitter``), which wall the sofa stands against
and where, the coffee table, stools, poufs, lamps, plants and pipes, and (through the shared kit,
``scenes/families/_kit.py``) every material (colour, texture contrast from none to strong on the floor and rug,
none to weak on walls, ceiling and sofa; roughness), the lamps' power and colour temperature and the daylight in
the windows.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from scenes.families import _kit as kit
from scenes.model import Box, Cylinder, Light, SceneEntry, SceneParams, SceneSpec, Sphere, param


@dataclass(frozen=True)
class LivingRoomParams(SceneParams):
    """The living room's parameters (``tri360 scenes --params``)."""

    size: tuple[float, float, float] = kit.room_size_param((6.0, 5.0, 2.6))
    size_jitter: float = kit.size_jitter_param(0.1)
    sofa_width: float = param(2.0, "sofa seat width between the arms", unit="m", limits=(0.5, 10.0))
    stools: tuple[int, int] = param((1, 3), "(min, max) number of stools and poufs", limits=(0, 100))
    plants: tuple[int, int] = param((1, 3), "(min, max) number of potted plants", limits=(0, 100))
    floor_lamps: int = param(1, "floor lamps with a spherical shade, each with a light", limits=(0, 20))
    pendants: int = param(1, "spherical pendant lamps hanging from the ceiling, each with a light", limits=(0, 20))
    lamp_power: tuple[float, float] = param((60.0, 100.0), "(min, max) power of each lamp's light", unit="W",
                                            limits=(0.0, None))
    kelvin: tuple[float, float] = param((2700.0, 4000.0), "(min, max) colour temperature of the lamps", unit="K",
                                        limits=(1000.0, 40000.0))
    windows: int = param(2, "windows on the -x wall, with daylight, each with a column radiator under it",
                         limits=(0, 20))
    pipes: bool = param(True, "heating pipes: a riser pair in a corner and a pipe along the -x wall")


def _materials(spec: SceneSpec, look: np.random.Generator) -> None:
    add = spec.add_material
    add(kit.draw_material(look, "walls", "paint", saturation=(0.0, 0.2), value=(0.7, 0.92),
                          contrast=kit.draw_contrast(look, ("none", "weak"), (3, 1)), roughness=(0.75, 0.95),
                          scale=(0.2, 0.6)))
    add(kit.draw_material(look, "ceiling", "paint", saturation=(0.0, 0.03), value=(0.85, 0.95), contrast=0.0,
                          roughness=0.9))
    floor_kind = "wood" if look.uniform() < 0.6 else "fabric"  # parquet or fitted carpet
    add(kit.draw_material(look, "floor", floor_kind, hue=(0.04, 0.12) if floor_kind == "wood" else (0.0, 1.0),
                          saturation=(0.1, 0.6), value=(0.25, 0.65),
                          contrast=kit.draw_contrast(look, ("none", "weak", "medium", "strong"), (1, 2, 2, 1)),
                          roughness=(0.3, 0.9), scale=(0.05, 0.15)))
    add(kit.draw_material(look, "baseboard", "paint", saturation=(0.0, 0.05), value=(0.8, 0.95), contrast=0.0,
                          roughness=0.5))
    add(kit.draw_material(look, "rug", "fabric", saturation=(0.1, 0.7), value=(0.2, 0.7),
                          contrast=kit.draw_contrast(look, ("weak", "medium", "strong")), roughness=(0.85, 1.0),
                          scale=(0.05, 0.3)))
    add(kit.draw_material(look, "sofa", "fabric", saturation=(0.0, 0.5), value=(0.2, 0.7),
                          contrast=kit.draw_contrast(look, ("none", "weak"), (1, 2)), roughness=(0.85, 1.0),
                          scale=(0.05, 0.2)))
    add(kit.draw_material(look, "cushion", "fabric", saturation=(0.2, 0.8), value=(0.2, 0.8),
                          contrast=kit.draw_contrast(look, ("none", "weak", "medium")), roughness=(0.85, 1.0),
                          scale=(0.03, 0.1)))
    add(kit.draw_material(look, "wood", "wood", hue=(0.04, 0.11), saturation=(0.2, 0.7), value=(0.2, 0.7),
                          contrast=(0.2, 0.8), roughness=(0.25, 0.6), scale=(0.03, 0.06)))
    add(kit.draw_material(look, "metal", "metal", saturation=(0.0, 0.08), value=(0.4, 0.85), contrast=(0.0, 0.2),
                          roughness=(0.2, 0.45), scale=(0.1, 0.3)))
    add(kit.draw_material(look, "pipe", "paint", saturation=(0.0, 0.05), value=(0.8, 0.95), contrast=0.0,
                          roughness=(0.3, 0.6)))
    add(kit.draw_material(look, "pot", "plastic", saturation=(0.0, 0.6), value=(0.2, 0.85),
                          contrast=kit.draw_contrast(look, ("none", "weak")), roughness=(0.2, 0.6)))
    add(kit.draw_material(look, "leaves", "noise", hue=(0.22, 0.36), saturation=(0.5, 0.8), value=(0.25, 0.5),
                          contrast=(0.7, 1.0), roughness=(0.6, 0.9), scale=(0.03, 0.08), darker=(0.3, 0.5)))
    add(kit.draw_material(look, "tv", "plastic", saturation=(0.0, 0.02), value=(0.02, 0.05), contrast=0.0,
                          roughness=(0.05, 0.2)))
    add(kit.draw_material(look, "door", "paint", saturation=(0.0, 0.1), value=(0.75, 0.95), contrast=0.0,
                          roughness=(0.4, 0.6)))


def _sofa(w: float, sofa: str, cushion: str, feet: str, rng: np.random.Generator) -> list:
    """A sofa facing +y, its back against the wall at local y = -0.45: a base on round feet, seat and back
    cushions, arms with round tops, round bolsters (local origin on the floor, centre of the seat)."""
    arm = 0.2
    parts: list = [Box((0.0, 0.0, 0.26), (w + 2 * arm, 0.9, 0.28), sofa, name="base"),
                   Box((0.0, -0.34, 0.67), (w, 0.22, 0.54), sofa, name="back"),
                   Cylinder((0.0, -0.34, 0.94), 0.11, w, sofa, axis="x", name="backroll")]
    n = 3 if w > 1.8 else 2
    for k in range(n):
        x = -w / 2 + w * (k + 0.5) / n
        parts.append(Box((x, 0.09, 0.46), (w / n - 0.015, 0.68, 0.12), sofa, name=f"seat{k}"))
    for s in (-1, 1):
        parts += [Box((s * (w / 2 + arm / 2), 0.0, 0.43), (arm, 0.9, 0.3), sofa, name=f"arm{s}"),
                  Cylinder((s * (w / 2 + arm / 2), 0.0, 0.58), arm / 2, 0.9, sofa, axis="y", name=f"armroll{s}")]
        if rng.uniform() < 0.7:
            parts.append(Cylinder((s * (w / 2 - 0.25), -0.15, 0.63), 0.1, 0.42, cushion, axis="x",
                                  name=f"bolster{s}"))
        for fy in (-0.38, 0.38):
            parts.append(Cylinder((s * (w / 2 + arm - 0.06), fy, 0.06), 0.025, 0.12, feet, name=f"foot{s}{fy:+.0f}"))
    return parts


def _floor_lamp(shade_r: float) -> list:
    return [Cylinder((0.0, 0.0, 0.015), 0.16, 0.03, "metal", name="base"),
            Cylinder((0.0, 0.0, 0.8), 0.012, 1.54, "metal", name="stem"),
            Sphere((0.0, 0.0, 1.57 + shade_r), shade_r, "glow", name="shade")]


def _radiator(width: float) -> list:
    """A column radiator along local x standing 5 cm off the wall (local y = 0), with its supply pipe."""
    n = max(4, int(width / 0.06))
    xs = (np.arange(n) - (n - 1) / 2) * 0.06
    parts: list = [Cylinder((float(x), 0.0, 0.45), 0.022, 0.6, "pipe", name=f"column{k}") for k, x in enumerate(xs)]
    parts += [Cylinder((0.0, 0.0, z), 0.02, n * 0.06 + 0.02, "pipe", axis="x", name=f"header{k}")
              for k, z in enumerate((0.2, 0.7))]
    return parts


def build(p: LivingRoomParams, seed: int) -> SceneSpec:
    """Build a living room."""
    layout, look = kit.streams(seed)
    jit = p.size_jitter
    W0, D0, H0 = p.size
    W, D = W0 * (1 + layout.uniform(-jit, jit)), D0 * (1 + layout.uniform(-jit, jit))
    H = H0 * (1 + 0.5 * layout.uniform(-jit, jit))
    spec = SceneSpec(name="living_room", bounds=((-W / 2, -D / 2, 0.0), (W / 2, D / 2, H)),
                     rig_height=(1.1, min(1.5, H - 0.9)), background=(0.0, 0.0, 0.0))
    _materials(spec, look)
    lamp_color = kit.draw_light_color(look, p.kelvin)
    glow = kit.draw_material(look, "glow", "emission", saturation=0.0, value=1.0, contrast=0.0,
                             emission=float(look.uniform(3.0, 6.0)))
    spec.add_material(replace(glow, color=lamp_color))
    power = p.lamp_power
    kit.room_shell(spec, (W, D, H), "walls", "floor", "ceiling", baseboard="baseboard")
    b = spec.boxes

    # the seating group: sofa against the -y or +y wall, the TV facing it, a round table on a round rug between
    side = -1.0 if layout.uniform() < 0.5 else 1.0  # the wall the sofa stands against
    yaw = 0.0 if side < 0 else np.pi  # the sofa faces into the room
    sw = p.sofa_width
    sx = layout.uniform(-1, 1) * max(0.0, W / 2 - sw / 2 - 0.9)
    kit.place(spec, "sofa", sx, side * (D / 2 - 0.47), yaw, _sofa(sw, "sofa", "cushion", "wood", layout))
    tx, ty = sx + layout.uniform(-0.2, 0.2), side * (D / 2 - 0.47 - 1.25) + layout.uniform(-0.1, 0.1)
    r_table = layout.uniform(0.35, 0.55)
    spec.cylinders.append(Cylinder((tx, ty, 0.006), r_table + layout.uniform(0.6, 0.9), 0.012, "rug", name="rug"))
    kit.place(spec, "table", tx, ty, 0.0, kit.round_table_parts(r_table, layout.uniform(0.4, 0.5), "wood", "metal",
                                                                 column=0.04))
    # TV on a low cabinet against the opposite wall
    cab_w = layout.uniform(1.4, 2.0)
    kit.place(spec, "tv", sx + layout.uniform(-0.3, 0.3), -side * (D / 2 - 0.22), yaw + np.pi,
              [Box((0.0, 0.0, 0.25), (cab_w, 0.42, 0.5), "wood", name="cabinet"),
               Box((0.0, -0.05, 0.5 + 0.08 + 0.35), (1.2, 0.04, 0.7), "tv", name="screen"),
               Cylinder((0.0, -0.05, 0.54), 0.12, 0.08, "metal", name="stand")])

    # stools and poufs around the table, out of the sofa's and the TV's way
    taken = [(tx, ty, r_table + 0.15)]
    lo_n, hi_n = p.stools
    n_stools = int(layout.integers(lo_n, hi_n + 1))
    y_lo, y_hi = -D / 2 + 0.4, D / 2 - 0.4
    if side < 0:
        y_lo = -D / 2 + 1.05
    else:
        y_hi = D / 2 - 1.05
    for k, (x, y) in enumerate(kit.scatter(layout, n_stools, (-W / 2 + 0.6, y_lo), (W / 2 - 0.6, y_hi), 0.3,
                                           taken, gap=0.15)):
        taken.append((x, y, 0.3))
        kind = int(layout.integers(3))
        if kind == 0:
            parts = kit.stool_parts("wood", "metal", h=layout.uniform(0.45, 0.7), radius=layout.uniform(0.15, 0.2))
        elif kind == 1:  # a round pouf
            parts = [Cylinder((0.0, 0.0, 0.2), layout.uniform(0.22, 0.3), 0.4, "cushion", name="pouf")]
        else:  # a ball pouf
            r = layout.uniform(0.2, 0.28)
            parts = [Sphere((0.0, 0.0, r), r, "cushion", name="ball")]
        kit.place(spec, f"stool{k}", x, y, layout.uniform(-np.pi, np.pi), parts)

    # lamps: floor lamps beside the sofa, pendants over the table; each spherical shade glows, with an
    # invisible point light just under it
    for k in range(p.floor_lamps):
        s = 1 if k % 2 == 0 else -1
        fx, fy = sx + s * (sw / 2 + 0.55), side * (D / 2 - 0.35)
        fx = float(np.clip(fx, -W / 2 + 0.3, W / 2 - 0.3))
        r = layout.uniform(0.15, 0.25)
        kit.place(spec, f"floorlamp{k}", fx, fy, 0.0, _floor_lamp(r))
        spec.lights.append(Light("point", position=(fx, fy, 1.57 - 0.06), power=kit.uniform(look, power),
                                 color=lamp_color))
    for k in range(p.pendants):
        px, py = tx + (k - (p.pendants - 1) / 2) * 0.8, ty + layout.uniform(-0.2, 0.2)
        r = layout.uniform(0.15, 0.3)
        z = H - layout.uniform(0.6, 0.9) - r
        cord = H - (z + r)
        spec.cylinders.append(Cylinder((px, py, H - cord / 2), 0.006, cord, "metal", name=f"pendant{k}.cord"))
        spec.spheres.append(Sphere((px, py, z), r, "glow", name=f"pendant{k}.shade"))
        spec.lights.append(Light("point", position=(px, py, z - r - 0.08), power=kit.uniform(look, power),
                                 color=lamp_color))

    # windows with daylight on the -x wall, a column radiator under each
    n_win = p.windows
    for k in range(n_win):
        y = -D / 2 + D * (k + 0.5) / n_win
        ww = min(1.4, 0.7 * D / max(n_win, 1))
        kit.add_window(spec, look, "-x", (W, D, H), along=y, width=ww, height=min(1.4, H - 1.1), sill=0.85,
                       frame="baseboard", name=f"window{k}")
        kit.place(spec, f"radiator{k}", -W / 2 + 0.07, y, np.pi / 2, _radiator(0.8 * ww))
    # heating pipes: a riser pair in the +x corner on the TV's side, and a pipe along the -x wall
    if p.pipes:
        cx, cy = W / 2 - 0.08, -side * (D / 2 - 0.08)
        for k in range(2):
            spec.cylinders.append(Cylinder((cx, cy + side * 0.09 * k, H / 2), 0.025, H, "pipe", name=f"riser{k}"))
        spec.cylinders.append(Cylinder((-W / 2 + 0.05, 0.0, 0.12), 0.018, D - 0.02, "pipe", axis="y", name="pipe"))

    # plants in round pots, along the walls, away from the furniture
    lo_n, hi_n = p.plants
    n_plants = int(layout.integers(lo_n, hi_n + 1))
    for k, (x, y) in enumerate(kit.scatter(layout, n_plants, (-W / 2 + 0.35, -D / 2 + 0.35),
                                           (W / 2 - 0.35, D / 2 - 0.35), 0.3, taken, gap=0.1)):
        if min(W / 2 - abs(x), D / 2 - abs(y)) > 0.8:  # keep the middle of the room free
            edge = layout.integers(2)
            x = x if edge else np.sign(x) * (W / 2 - 0.35)
            y = y if not edge else np.sign(y) * (D / 2 - 0.35)
        r, h = layout.uniform(0.12, 0.22), layout.uniform(0.25, 0.5)
        parts = [Cylinder((0.0, 0.0, h / 2), r, h, "pot", name="pot")]
        for j in range(int(layout.integers(1, 4))):
            rr = layout.uniform(0.15, 0.3)
            parts.append(Sphere((layout.uniform(-0.1, 0.1), layout.uniform(-0.1, 0.1), h + rr + 0.25 * j), rr,
                                "leaves", name=f"crown{j}"))
        kit.place(spec, f"plant{k}", float(x), float(y), 0.0, parts)

    # the door on the +x wall
    dy = layout.uniform(-D / 2 + 0.9, D / 2 - 0.9)
    b.append(Box((W / 2 - 0.025, dy, 1.03), (0.05, 0.9, 2.05), "door", name="door"))
    b.append(Box((W / 2 - 0.07, dy - 0.33, 1.0), (0.05, 0.12, 0.025), "metal", name="door.handle"))
    return spec


PRESETS = {
    "default": {"size": (6.0, 5.0, 2.6), "floor_lamps": 1, "pendants": 1, "windows": 2},
    "evening": {"size": (6.0, 5.0, 2.6), "floor_lamps": 2, "pendants": 2, "windows": 0, "lamp_power": (70.0, 110.0),
                "kelvin": (2400.0, 3200.0)},
    "large": {"size": (8.0, 6.0, 2.9), "sofa_width": 2.6, "stools": (2, 4), "plants": (2, 4), "floor_lamps": 2,
              "pendants": 2, "windows": 3},
}

# version: the scene code version frames and suite ids record; change it when what build() builds changes,
# and only then (tests/scenes/test_scene_fingerprints.py; scenes/README.md)
SCENES = [SceneEntry(name="living_room", version="sha256:727ac299509743bf",
                     build=build, presets=PRESETS, default_preset="default",
                     description="living room (6 x 5 x 2.6 m): plain walls, round table, stools, sphere lamps, pipes",
                     parameters=LivingRoomParams, renderer="cycles", tags=("weak_texture",))]

"""The shared randomisation kit of the room families (``scenes/families/_kit.py``)."""

from __future__ import annotations

import numpy as np
import pytest

from scenes.families import _kit as kit
from scenes.model import Box, Cylinder, Material, SceneSpec, Sphere


def test_kelvin_to_rgb_follows_the_planckian_locus():
    warm, d65, cold = kit.kelvin_to_rgb(2700), kit.kelvin_to_rgb(6504), kit.kelvin_to_rgb(10000)
    assert max(warm) == max(d65) == max(cold) == pytest.approx(1.0)
    assert warm[0] == 1.0 and warm[0] > warm[1] > warm[2] > 0.1  # incandescent: orange
    # D65 lies 0.003 (uv) off the locus, so its locus colour is nearly white (measured: G 0.944, B 0.994)
    assert min(d65) > 0.93
    assert cold[2] == 1.0 and cold[0] < 0.85  # blue sky
    blues = [kit.kelvin_to_rgb(t)[2] / kit.kelvin_to_rgb(t)[0] for t in (2000, 3000, 4000, 5000, 6500, 9000)]
    assert np.all(np.diff(blues) > 0)


def test_draws_are_deterministic_and_within_their_ranges():
    a = kit.draw_material(kit.streams(3)[1], "m", "paint", value=(0.6, 0.8), roughness=(0.2, 0.3))
    b = kit.draw_material(kit.streams(3)[1], "m", "paint", value=(0.6, 0.8), roughness=(0.2, 0.3))
    c = kit.draw_material(kit.streams(4)[1], "m", "paint", value=(0.6, 0.8), roughness=(0.2, 0.3))
    assert a == b and a != c
    assert 0.2 <= a.roughness <= 0.3 and 0.0 <= a.contrast <= 1.0
    assert kit.srgb_to_linear(0.6) - 1e-9 <= max(a.color) <= kit.srgb_to_linear(0.8) + 1e-9
    rng = np.random.default_rng(0)
    assert {kit.draw_contrast(rng, ("none",)) for _ in range(5)} == {0.0}
    strong = [kit.draw_contrast(rng, ("strong",)) for _ in range(20)]
    assert min(strong) >= 0.6 and max(strong) <= 1.0
    layout, look = kit.streams(5)
    assert layout.uniform() != look.uniform()


def test_vary_material_keeps_the_look_and_texture_less_stays_texture_less():
    m = Material("w", kind="paint", color=(0.5, 0.4, 0.3), contrast=0.3, roughness=0.6)
    plain = Material("p", kind="plastic", color=(0.8, 0.8, 0.8), contrast=0.0)
    rng = np.random.default_rng(1)
    assert kit.vary_material(rng, m, 0.0) is m
    for _ in range(20):
        v = kit.vary_material(rng, m)
        assert np.allclose(v.color, m.color, rtol=0.25) and 0.15 <= v.contrast <= 0.45
        assert abs(v.roughness - 0.6) <= 0.15 + 1e-12 and v.kind == m.kind and v.name == m.name
        assert kit.vary_material(rng, plain).contrast == 0.0


def test_lights_windows_and_panels():
    spec = SceneSpec(name="t", materials={"frame": Material("frame")})
    centres = kit.ceiling_panels(spec, np.random.default_rng(0), (-2, -1, 2, 1), 3.0, (2, 1), power=(30, 40),
                                 kelvin=(3000, 4000))
    assert centres == [(-1.0, 0.0), (1.0, 0.0)] and len(spec.lights) == 2
    assert 30 <= spec.lights[0].power <= 40 and spec.lights[0].power == spec.lights[1].power
    assert spec.lights[0].position[2] < 3.0 and all(b.center[2] < 3.0 for b in spec.boxes)
    kit.add_window(spec, np.random.default_rng(0), "-x", (6.0, 5.0, 3.0), along=0.5, width=1.2, height=1.4,
                   sill=0.9, frame="frame")
    pane = next(b for b in spec.boxes if b.name == "window.pane")
    assert pane.center[0] == pytest.approx(-2.98) and spec.materials[pane.material].kind == "emission"
    fill = spec.lights[-1]
    assert fill.kind == "point" and -3.0 < fill.position[0] < -2.0 and 0.9 < fill.position[2] < 2.3
    spec.validate()


def test_placement_helpers():
    g = kit.grid((0, 2), (0, 1), rows=2, cols=3)
    assert g.shape == (6, 2) and tuple(g[0]) == (0.0, 1.0) and tuple(g[-1]) == (2.0, 0.0)
    assert kit.grid((0, 2), (0, 1), 1, 1).tolist() == [[1.0, 0.5]]
    assert kit.row((0, 0), (4, 0), 5)[:, 0].tolist() == [0, 1, 2, 3, 4]
    rng = np.random.default_rng(2)
    pts = kit.scatter(rng, 30, (-3, -3), (3, 3), 0.4, taken=[(0.0, 0.0, 1.0)], gap=0.1)
    assert 5 <= len(pts) <= 30
    all_ = [(0.0, 0.0, 1.0)] + [(x, y, 0.4) for x, y in pts]
    for i, (x, y, r) in enumerate(all_):
        assert -3 + 0.4 <= x <= 3 - 0.4 or i == 0
        for x2, y2, r2 in all_[i + 1:]:
            assert np.hypot(x - x2, y - y2) >= r + r2 + 0.1 - 1e-12


def test_place_rotates_parts_about_their_origin():
    spec = SceneSpec(name="t")
    parts = [Box((0.5, 0.0, 0.4), (0.2, 0.1, 0.8), "m"), Cylinder((0.0, 0.5, 0.3), 0.1, 0.6, "m", axis="x"),
             Sphere((0.0, 0.0, 1.0), 0.2, "m", name="ball")]
    kit.place(spec, "thing", 2.0, 1.0, np.pi / 2, parts)
    assert np.allclose(spec.boxes[0].center, (2.0, 1.5, 0.4)) and spec.boxes[0].yaw == pytest.approx(np.pi / 2)
    assert np.allclose(spec.cylinders[0].center, (1.5, 1.0, 0.3)) and spec.cylinders[0].axis == "x"
    assert spec.spheres[0].name == "thing.ball" and spec.boxes[0].name == "thing.0"
    chair = kit.chair_parts("seat", "legs", round_legs=True)
    assert sum(isinstance(p, Cylinder) for p in chair) == 6
    assert all(p.center[2] > 0 for p in kit.round_table_parts(0.6, 0.75, "top", "stand"))

"""Shapes beyond boxes (cylinders, spheres) and difficulty tags in the scene model."""

from __future__ import annotations

import numpy as np
import pytest

from scenes.model import (
    DIFFICULTY_TAGS,
    Box,
    Cylinder,
    Material,
    SceneEntry,
    SceneError,
    SceneSpec,
    Sphere,
    choose_viewpoints,
)


def test_cylinder_contains_along_each_axis_and_yaw():
    z = Cylinder((1.0, 2.0, 0.5), radius=0.3, length=1.0, material="m")
    pts = np.array([[1.0, 2.0, 0.5], [1.29, 2.0, 0.99], [1.31, 2.0, 0.5], [1.0, 2.0, 1.01], [1.2, 2.2, 0.1]])
    assert z.contains(pts).tolist() == [True, True, False, False, True]
    # margin: (3,) per world axis, radial from x/y, axial from z
    assert z.contains(np.array([[1.45, 2.0, 0.5], [1.0, 2.0, 1.05]]), (0.2, 0.2, 0.0)).tolist() == [True, False]
    # a pipe along x, yawed 90 degrees: now along world y
    pipe = Cylinder((0.0, 0.0, 1.0), radius=0.1, length=2.0, material="m", axis="x", yaw=np.pi / 2)
    assert pipe.contains(np.array([[0.0, 0.95, 1.0], [0.95, 0.0, 1.0], [0.0, 0.5, 1.09]])).tolist() == \
        [True, False, True]
    np.testing.assert_allclose(pipe.frame()[:, 2], (0.0, 1.0, 0.0), atol=1e-12)
    along_y = Cylinder((0.0, 0.0, 1.0), radius=0.1, length=2.0, material="m", axis="y")
    assert along_y.contains(np.array([[0.0, 0.95, 1.0], [0.95, 0.0, 1.0]])).tolist() == [True, False]
    for c in (z, pipe, along_y):
        f = c.frame()
        np.testing.assert_allclose(f.T @ f, np.eye(3), atol=1e-12)
        assert np.linalg.det(f) == pytest.approx(1.0)


def test_sphere_contains():
    s = Sphere((0.0, 0.0, 1.0), 0.5, "m")
    assert s.contains(np.array([[0.0, 0.0, 1.49], [0.0, 0.36, 1.36], [0.0, 0.0, 1.55]])).tolist() == \
        [True, False, False]
    assert s.contains(np.array([[0.0, 0.0, 1.55]]), 0.1).tolist() == [True]


def _spec(**shapes) -> SceneSpec:
    spec = SceneSpec(name="t", materials={"m": Material("m")})
    spec.boxes.append(Box((0, 0, 1.5), (4, 4, 3), "m", inward=True))
    spec.boxes.append(Box((1, 1, 0.5), (0.5, 0.5, 1.0), "m", name="crate"))
    spec.cylinders.extend(shapes.get("cylinders", []))
    spec.spheres.extend(shapes.get("spheres", []))
    return spec


def test_solids_are_every_non_shell_shape_and_validation_names_the_culprit():
    cyl, sph = Cylinder((0, 0, 0.4), 0.6, 0.8, "m", name="table"), Sphere((-1, 1, 1), 0.2, "m", name="ball")
    spec = _spec(cylinders=[cyl], spheres=[sph])
    spec.validate()
    assert [s.name for s in spec.solids()] == ["crate", "table", "ball"]
    assert len(spec.shapes()) == 4
    for bad, match in [(Cylinder((0, 0, 1), 0.0, 1.0, "m", name="flat"), "cylinder flat has non-positive"),
                       (Cylinder((0, 0, 1), 0.1, -1.0, "m", name="neg"), "cylinder neg has non-positive"),
                       (Cylinder((0, 0, 1), 0.1, 1.0, "nope", name="c"), "cylinder c uses unknown material"),
                       (Cylinder((0, 0, 1), 0.1, 1.0, "m", axis="w", name="c"), "unknown axis 'w'")]:
        with pytest.raises(ValueError, match=match):
            _spec(cylinders=[bad]).validate()
    for bad, match in [(Sphere((0, 0, 1), float("nan"), "m", name="s"), "sphere s has non-positive"),
                       (Sphere((0, 0, 1), 0.2, "x", name="s"), "sphere s uses unknown material 'x'")]:
        with pytest.raises(ValueError, match=match):
            _spec(spheres=[bad]).validate()


def test_viewpoints_keep_clear_of_round_furniture():
    # a 1.2 m round table in the middle of a 4 x 4 m room: viewpoint 0 (nearest the centre) moves off it
    spec = _spec(cylinders=[Cylinder((0, 0, 0.375), 0.6, 0.75, "m")], spheres=[Sphere((-1, -1, 1.3), 0.3, "m")])
    spec.boxes.pop()  # no crate
    for rig in choose_viewpoints(spec, 4, seed=2):
        for pose in rig.poses().values():
            assert np.hypot(*pose.position[:2]) >= 0.6 + 0.35 - 1e-9  # the tripod column stands off the table
            assert np.linalg.norm(pose.position - (-1, -1, 1.3)) >= 0.3 + 0.3 - 1e-9


def test_tags_are_validated():
    build = lambda params, seed: SceneSpec(name="x")  # noqa: E731
    assert SceneEntry(name="x", build=build, tags=("weak_texture", "thin")).tags == ("weak_texture", "thin")
    with pytest.raises(SceneError, match="unknown tag\\(s\\) shiny"):
        SceneEntry(name="x", build=build, tags=("shiny",))
    with pytest.raises(SceneError, match="tags must be a tuple"):
        SceneEntry(name="x", build=build, tags="far")
    assert set(DIFFICULTY_TAGS) == {"weak_texture", "reflective", "repetitive", "far", "thin", "cluttered"}

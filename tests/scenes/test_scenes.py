"""Every registered scene and preset builds, validates and offers free rig placements; registry errors."""

from __future__ import annotations

import dataclasses
import hashlib
import importlib
import sys
from pathlib import Path

import numpy as np
import pytest

import scenes.families
import scenes.model
from scenes.families import classroom
from scenes.families.box_room import box_interior_distance
from scenes.model import (
    Box,
    Light,
    Material,
    ModelFile,
    ParameterError,
    SceneParams,
    SceneSpec,
    choose_viewpoints,
)
from scenes.registry import SceneEntry, SceneError, discover, get_scene

ENTRIES, LOAD_ERRORS = discover()
param = scenes.model.param
CASES = [(name, preset) for name, e in sorted(ENTRIES.items()) for preset in e.presets]
#: the presets whose viewpoints take a second or more to place (marked ``slow``; each family keeps a fast one)
SLOW_CASES = {("classroom", "lecture"), ("classroom", "standard"), ("library", "stacks"), ("library", "reading_room"),
              ("seminar", "large"), ("seminar", "default"), ("lab", "large"), ("lecture_hall", "steep"),
              ("office", "small")}


def test_every_scene_file_loads():
    assert LOAD_ERRORS == {}
    assert {"classroom", "box_room"} <= set(ENTRIES)


def test_every_slow_case_is_a_preset_and_every_family_keeps_a_fast_one():
    assert SLOW_CASES <= set(CASES)
    assert {name for name, _ in CASES} == {name for name, preset in CASES if (name, preset) not in SLOW_CASES}


@pytest.mark.parametrize(("name", "preset"), [pytest.param(*c, marks=pytest.mark.slow) if c in SLOW_CASES else c
                                              for c in CASES], ids=[f"{n}:{p}" for n, p in CASES])
def test_scene_builds_and_has_free_viewpoints(name, preset):
    entry, got = get_scene(f"{name}:{preset}")
    assert got == preset
    spec = entry.spec(preset, seed=0)
    spec.validate()
    assert spec.boxes, "a scene without geometry"
    assert spec.params["preset"] == preset and spec.params["seed"] == 0
    rigs = choose_viewpoints(spec, 3, seed=1)
    assert len(rigs) == 3
    solids = spec.solids()
    lo, hi = np.asarray(spec.bounds[0]), np.asarray(spec.bounds[1])
    for rig in rigs:
        pts = np.array([p.position for p in rig.poses().values()])
        assert np.all(pts > lo) and np.all(pts < hi)
        assert not any(b.contains(pts, 0.29).any() for b in solids)


@pytest.mark.parametrize("preset", sorted(ENTRIES["classroom"].presets))
def test_classroom_seed_jitters_layout_deterministically(preset):
    entry = ENTRIES["classroom"]
    a, b, c = entry.spec(preset, 0), entry.spec(preset, 0), entry.spec(preset, 1)
    centres = lambda s: np.array([bx.center for bx in s.boxes])  # noqa: E731
    assert np.array_equal(centres(a), centres(b))
    if preset != "empty":  # furniture moves with the seed
        assert len(a.boxes) != len(c.boxes) or not np.allclose(centres(a), centres(c))


def test_classroom_standard_is_paper_sized_and_furnished():
    spec = ENTRIES["classroom"].spec("standard", 0)
    (x0, y0, z0), (x1, y1, z1) = spec.bounds
    assert (x1 - x0, y1 - y0, z1 - z0) == (8.0, 7.0, 3.0)
    names = " ".join(b.name for b in spec.boxes)
    for part in ("desk", "chair", "teacher_desk", "chalkboard", "whiteboard", "window", "door", "lamp",
                 "locker", "shelf"):
        assert part in names, part
    kinds = {spec.materials[b.material].kind for b in spec.boxes}
    assert {"wood", "tiles", "paint", "board", "emission", "metal"} <= kinds
    assert any(spec.materials[b.material].contrast == 0 for b in spec.boxes), "no weak-texture surface"
    assert len(spec.lights) >= 4


def test_box_room_closed_form_distance():

    d = np.array([[1.0, 0, 0], [0, -1.0, 0], [0, 0, 1.0], [1 / np.sqrt(2), 1 / np.sqrt(2), 0]])
    t = box_interior_distance([0.0, 0.0, 1.0], d, (-3, -2, 0), (3, 2, 3))
    np.testing.assert_allclose(t, [3.0, 2.0, 2.0, 2 * np.sqrt(2)], atol=1e-12)


def test_unknown_scene_and_preset():
    with pytest.raises(SceneError, match="unknown scene 'nope'.*classroom"):
        get_scene("nope")
    with pytest.raises(SceneError, match="unknown preset 'huge'"):
        get_scene("classroom:huge")
    with pytest.raises(SceneError, match="unknown preset"):
        ENTRIES["classroom"].spec("huge")


def test_scene_that_raises_is_named():
    def broken(params, seed):
        raise RuntimeError("boom")

    entry = SceneEntry(name="broken", build=broken, source="scenes/broken.py")
    with pytest.raises(SceneError, match=r"scene 'broken' \(scenes/broken.py\) failed to build: RuntimeError: boom"):
        entry.spec()


def test_scene_with_bad_material_is_named():
    def bad(params, seed):
        spec = SceneSpec(name="bad")
        spec.add_material(Material("m"))
        spec.boxes.append(Box((0, 0, 1), (1, 1, 1), "missing"))
        return spec

    with pytest.raises(SceneError, match="unknown material 'missing'"):
        SceneEntry(name="bad", build=bad).spec()


def test_scene_file_that_fails_to_import_is_reported(monkeypatch, tmp_path):
    (tmp_path / "zz_broken_scene.py").write_text("raise ImportError('no such thing')\n")
    monkeypatch.setattr(scenes.families, "__path__", [*scenes.families.__path__, str(tmp_path)])
    entries, errors = discover()
    assert "classroom" in entries
    assert any("zz_broken_scene" in k and "no such thing" in v for k, v in errors.items())
    with pytest.raises(SceneError, match="zz_broken_scene"):
        get_scene("nope")


def test_code_version_is_the_declared_version_else_the_hash_of_the_family_source_and_the_shared_scene_code(
        tmp_path, monkeypatch):
    # a built-in family declares its version: what main recorded before the SceneParams refactor
    assert ENTRIES["classroom"].code_version == ENTRIES["classroom"].version == "sha256:1ed56314fc16eeec"
    assert ENTRIES["classroom"].spec("small", 0).code_version == "sha256:1ed56314fc16eeec"
    # one that declares none (an outside family): the source hash
    h = hashlib.sha256(Path(classroom.__file__).read_bytes())
    for path in (Path(scenes.model.__file__), Path(scenes.families.__file__).with_name("_kit.py")):
        h.update(b"\0" + path.name.encode() + b"\0" + path.read_bytes())
    unversioned = dataclasses.replace(ENTRIES["classroom"], version="")
    assert unversioned.code_version == unversioned.source_version == "sha256:" + h.hexdigest()[:16]
    assert unversioned.spec("small", 0).code_version == unversioned.source_version
    # an edited kit or model changes every unversioned family's version (not a declared one)
    monkeypatch.setattr(scenes.model, "SHARED_SOURCES", (*scenes.model.SHARED_SOURCES, Path(classroom.__file__)))
    assert unversioned.code_version != "sha256:" + h.hexdigest()[:16]
    assert ENTRIES["classroom"].code_version == "sha256:1ed56314fc16eeec"
    monkeypatch.undo()
    # an edited family file gets another version
    mod = tmp_path / "tri360_tmp_family.py"
    mod.write_text("def build(params, seed):\n    return None\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    entry = SceneEntry(name="tmp", build=importlib.import_module("tri360_tmp_family").build)
    before = entry.code_version
    mod.write_text("def build(params, seed):\n    return None  # edited\n")
    assert before.startswith("sha256:") and entry.code_version != before
    sys.modules.pop("tri360_tmp_family", None)


def test_undeclared_and_reserved_parameters_are_refused():
    def build(params, seed):
        spec = SceneSpec(name="p")
        spec.add_material(Material("m"))
        spec.boxes.append(Box((0, 0, 1), (1, 1, 1), "m"))
        return spec

    @dataclasses.dataclass(frozen=True)
    class Counts(SceneParams):
        n: int = param(0, "count")
        k: int = param(0, "other count")

    @dataclasses.dataclass(frozen=True)
    class Reserved(SceneParams):
        seed: int = param(0, "no")

    entry = SceneEntry(name="p", build=build, presets={"default": {"n": 1}}, parameters=Counts)
    assert entry.known_parameters == ["k", "n"]
    assert entry.spec(n=2).params == {"preset": "default", "seed": 0, "n": 2}
    with pytest.raises(ParameterError, match="^scene 'p': m: expected one of the keys n, k, got an unknown key$"):
        entry.spec(m=2)
    with pytest.raises(SceneError, match="'preset' is not a scene parameter \\(use --scene NAME:PRESET\\)"):
        entry.build_spec(overrides={"preset": "x"})
    with pytest.raises(SceneError, match="reserved"):
        SceneEntry(name="p", build=build, parameters=Reserved)
    # no parameters declared: none is known, and a preset may set none
    assert SceneEntry(name="q", build=build).known_parameters == []
    with pytest.raises(SceneError, match="^scene 'q': preset 'default': n: expected no keys, got an unknown key$"):
        SceneEntry(name="q", build=build, presets={"default": {"n": 1}})


def test_box_contains_follows_the_yaw():
    box = Box((1.0, 2.0, 0.5), (2.0, 0.4, 1.0), "m", yaw=np.pi / 2)  # long side now along world y
    inside = np.array([[1.0, 2.9, 0.5], [1.15, 2.0, 0.9]])
    outside = np.array([[1.9, 2.0, 0.5], [1.0, 3.1, 0.5], [1.0, 2.0, 1.1]])
    assert box.contains(inside).all() and not box.contains(outside).any()
    assert box.contains(np.array([[1.0, 3.15, 0.5]]), margin=0.2).all()


def test_validate_names_bad_lights_and_model_files(tmp_path):
    spec = SceneSpec(name="v")
    spec.add_material(Material("m"))
    spec.lights.append(Light("spot", position=(0, 0, 2)))
    with pytest.raises(ValueError, match="light 0 has unknown kind 'spot'"):
        spec.validate()
    spec.lights.clear()
    spec.models.append(ModelFile(path=tmp_path / "missing.glb"))
    with pytest.raises(ValueError, match="missing.glb does not exist"):
        spec.validate()
    spec.models[0] = ModelFile(path=tmp_path / "model.fbx")
    with pytest.raises(ValueError, match="unsupported format '.fbx'"):
        spec.validate()


# ------------------------------------------------------------------------------------------------ parameters


@pytest.mark.parametrize("name", sorted(ENTRIES))
def test_every_family_declares_a_frozen_parameters_dataclass(name):
    entry = ENTRIES[name]
    cls = entry.parameters
    assert issubclass(cls, SceneParams) and cls.__dataclass_params__.frozen
    defaults = cls()
    with pytest.raises(dataclasses.FrozenInstanceError):
        defaults.__setattr__(dataclasses.fields(cls)[0].name, None)
    for f in dataclasses.fields(cls):
        info = f.metadata[scenes.model.PARAM_METADATA]
        assert info.description and "\n" not in info.description, f.name
        assert "default" not in info.description, f"{f.name}: the default is the field's, not the text's"
    for preset, params in entry.presets.items():  # a preset is overrides of the defaults
        values = entry.parameter_values(params)
        assert isinstance(values, cls)
        for key, value in params.items():
            assert getattr(values, key) == value, (preset, key)
    assert list(entry.describe_parameters()) == [f.name for f in dataclasses.fields(cls)]


def test_families_read_no_untyped_parameters():
    for path in Path(scenes.families.__file__).parent.glob("*.py"):
        text = path.read_text()
        assert "params.get(" not in text and "PARAMETERS" not in text, path.name


@dataclasses.dataclass(frozen=True)
class _Params(SceneParams):
    size: tuple[float, float, float] = param((4.0, 3.0, 2.5), "room interior", unit="m", limits=(1.0, 50.0))
    n: int = param(2, "how many", limits=(0, 10))
    shiny: bool = param(False, "glossy floor")
    power: float | None = param(None, "light power (none: automatic)", unit="W", limits=(0.0, None))
    names: tuple[str, ...] = param(("a",), "parts, in order", choices=("a", "b"))


def _room(p, seed):
    spec = SceneSpec(name="t", params={"seen": p})
    spec.add_material(Material("m"))
    spec.boxes.append(Box((0, 0, 1), (1, 1, 1), "m"))
    return spec


def _entry(**kw):
    return SceneEntry(name="t", build=_room, parameters=_Params,
                      presets={"default": {}, "big": {"size": (8.0, 6.0, 3.0), "n": 3}}, **kw)


def test_build_gets_a_checked_instance_and_the_spec_records_the_values_as_given():
    entry = _entry()
    seen = {}

    def build(p, seed):
        seen["p"] = p
        return _room(p, seed)

    entry = SceneEntry(**{**entry.__dict__, "build": build})
    spec = entry.spec("big", 3, names=["b", "a"], power=40)
    p = seen["p"]
    assert p == _Params(size=(8.0, 6.0, 3.0), n=3, names=("b", "a"), power=40.0)
    assert isinstance(p.power, float) and isinstance(p.names, tuple)
    # what a frame records: preset and seed, then the preset's values and the overrides, as given, in order
    assert spec.params == {"preset": "big", "seed": 3, "size": (8.0, 6.0, 3.0), "n": 3, "names": ["b", "a"],
                           "power": 40}
    assert list(spec.params) == ["preset", "seed", "size", "n", "names", "power"]


@pytest.mark.parametrize(("overrides", "message"), [
    ({"n": "2"}, "n: expected an integer in [0, 10], got '2'"),
    ({"n": 2.0}, "n: expected an integer in [0, 10], got 2.0"),
    ({"n": True}, "n: expected an integer in [0, 10], got True"),
    ({"n": 11}, "n: expected an integer in [0, 10], got 11"),
    ({"size": [4, 3]}, "size: expected 3 numbers, each in [1, 50], got [4, 3]"),
    ({"size": [4, 3, 0.5]}, "size: expected 3 numbers, each in [1, 50], got [4, 3, 0.5]"),
    ({"size": 4}, "size: expected 3 numbers, each in [1, 50], got 4"),
    ({"shiny": 1}, "shiny: expected true or false, got 1"),
    ({"power": "high"}, "power: expected a number >= 0 or null, got 'high'"),
    ({"power": float("nan")}, "power: expected a number >= 0 or null, got nan"),
    ({"names": ["c"]}, "names: expected a list of strings, each one of a, b, got ['c']"),
    ({"names": "a"}, "names: expected a list of strings, each one of a, b, got 'a'"),
    ({"colour": "red"}, "colour: expected one of the keys size, n, shiny, power, names, got an unknown key"),
])
def test_an_ill_typed_parameter_is_one_line_naming_family_parameter_and_expectation(overrides, message):
    with pytest.raises(ParameterError) as info:
        _entry().spec("big", **overrides)
    assert str(info.value) == f"scene 't': {message}"
    assert info.value.where == "scene 't'" and info.value.detail == message


def test_parameters_are_checked_outside_an_entry_too():
    with pytest.raises(ParameterError, match=r"^n: expected an integer in \[0, 10\], got -1$"):
        _Params(n=-1)
    assert _Params(power=None).power is None


def test_describe_parameters_gives_unit_default_and_limits():
    lines = _entry().describe_parameters()
    assert lines == {
        "size": "room interior, m (default [4, 3, 2.5]; each in [1, 50])",
        "n": "how many (default 2; in [0, 10])",
        "shiny": "glossy floor (default false)",
        "power": "light power (none: automatic), W (default none; >= 0)",
        "names": "parts, in order (default a; each one of a, b)",
    }
    assert ENTRIES["classroom"].describe_parameters()["light_power"] == \
        "power per ceiling area light, W (default 35; >= 0)"


def test_bad_parameter_declarations_are_refused_at_registration():
    def entry(parameters, presets=None):
        return SceneEntry(name="t", build=_room, parameters=parameters, presets=presets or {"default": {}})

    with pytest.raises(SceneError, match=r"^scene 't': preset 'big': n: expected an integer in \[0, 10\], got '3'$"):
        entry(_Params, {"default": {}, "big": {"n": "3"}})
    with pytest.raises(SceneError, match=r"^scene 't': preset 'big': m: expected one of the keys size, .*, got an "):
        entry(_Params, {"default": {}, "big": {"m": 3}})

    class Undecorated(SceneParams):
        n: int = param(1, "n")

    with pytest.raises(SceneError, match=r"Undecorated is not decorated with @dataclass\(frozen=True\)"):
        entry(Undecorated)

    @dataclasses.dataclass(frozen=True)
    class Plain:
        n: int = 1

    with pytest.raises(SceneError, match="parameters must be a SceneParams dataclass, got Plain"):
        entry(Plain)

    @dataclasses.dataclass(frozen=True)
    class Bare(SceneParams):
        n: int = 1

    with pytest.raises(SceneError, match=r"parameter 'n' of Bare is not declared with scenes.model.param"):
        entry(Bare)

    @dataclasses.dataclass(frozen=True)
    class Undescribed(SceneParams):
        n: int = param(1)

    with pytest.raises(SceneError, match=r"parameter 'n' of Undescribed .* and a description"):
        entry(Undescribed)

    @dataclasses.dataclass(frozen=True)
    class BadDefault(SceneParams):
        n: int = param(-1, "n", limits=(0, 3))

    with pytest.raises(SceneError, match=r"^scene 't': defaults of BadDefault: n: expected an integer in \[0, 3\], "):
        entry(BadDefault)

    @dataclasses.dataclass(frozen=True)
    class Reserved(SceneParams):
        seed: int = param(1, "n")

    with pytest.raises(SceneError, match="reserved"):
        entry(Reserved)


def test_parameters_declared_as_a_dict_are_refused():
    """The untyped way (a dict of descriptions, ``build`` got a dict) is gone: the entry says how to declare them."""
    with pytest.raises(SceneError, match=r"parameters must be a SceneParams dataclass, got dict; declare them as"):
        SceneEntry(name="old", build=_room, presets={"default": {"n": 1}}, parameters={"n": "count (default 1)"})

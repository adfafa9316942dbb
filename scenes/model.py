"""The scene kit: a renderer-agnostic description of a scene (plain dataclasses, no bpy).

A scene family (a file in ``scenes/families/``) is a function ``build(params, seed) -> SceneSpec``.  A renderer
translates the spec: ``cycles`` (``harness.render.cycles``) path-traces it with Blender, ``raycast``
(``harness.render.raycast``) ray-casts its boxes analytically in numpy.  The spec knows nothing of either (the
kubric pattern).

A family registers itself with a :class:`SceneEntry` (its build function, presets, parameters and default
renderer); ``scenes.registry`` finds the entries.  A family's parameters are one frozen :class:`SceneParams`
dataclass whose fields are declared with :func:`param` (type, default, unit, limits, one-line description:
:mod:`reconstruction.params`); ``build`` gets a checked instance.

Units: metres, radians, linear RGB in [0, 1], watts.  World is right-handed, Z up, floor at z = 0.
"""

from __future__ import annotations

import hashlib
import inspect
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field, fields
from pathlib import Path
from typing import Any

import numpy as np

from reconstruction.camera.rig import Rig, yaw_rotation
from reconstruction.params import METADATA_KEY, ParamError, check_value, describe, from_mapping, info_of, type_hints
from reconstruction.params import param as param  # families declare their parameters with scenes.model.param

MATERIAL_KINDS = ("paint", "wood", "tiles", "board", "fabric", "metal", "plastic", "glass", "emission", "noise")
LIGHT_KINDS = ("area", "point", "sun")
DIFFICULTY_TAGS = ("weak_texture", "reflective", "repetitive", "far", "thin", "cluttered")
"""What a scene family is hard for (``SceneEntry.tags``): plain walls and ceilings, polished or glossy surfaces,
repeated structures, distances past 15 m, thin structures (legs, railings), clutter."""
CYLINDER_AXES = ("x", "y", "z")
MODEL_SUFFIXES = (".blend", ".glb", ".gltf", ".obj")


@dataclass(frozen=True)
class Material:
    """Surface appearance.

    Attributes:
        name: unique key within the scene.
        kind: one of ``MATERIAL_KINDS``; selects the procedural texture a backend builds.
        color: base colour, linear RGB in [0, 1].
        color2: secondary colour (wood's dark grain, tile grout, ...), linear RGB; defaults to a darker ``color``.
        scale: size of the texture's main feature, metres (tile size, grain spacing, noise blob size).
        contrast: texture amplitude in [0, 1]; 0 gives a uniform, texture-less surface.
        roughness: specular roughness in [0, 1] (1 = matte).
        emission: emission strength (Blender units, W/m^2-like) for ``kind == "emission"``.
    """

    name: str
    kind: str = "paint"
    color: tuple[float, float, float] = (0.8, 0.8, 0.8)
    color2: tuple[float, float, float] | None = None
    scale: float = 0.5
    contrast: float = 0.2
    roughness: float = 0.6
    emission: float = 0.0

    def __post_init__(self):
        if self.kind not in MATERIAL_KINDS:
            raise ValueError(f"material {self.name!r}: unknown kind {self.kind!r} (known: {MATERIAL_KINDS})")

    @property
    def secondary(self) -> tuple[float, float, float]:
        return self.color2 if self.color2 is not None else tuple(0.55 * c for c in self.color)


@dataclass(frozen=True)
class Box:
    """An oriented box.

    Attributes:
        center: (x, y, z) centre, metres.
        size: (sx, sy, sz) full extents along the box's own axes, metres.
        material: key into ``SceneSpec.materials``.
        yaw: rotation about +Z, radians.
        name: optional object name (shows in Blender).
        inward: True for a room shell seen from inside (normals point inwards).
    """

    center: tuple[float, float, float]
    size: tuple[float, float, float]
    material: str
    yaw: float = 0.0
    name: str = ""
    inward: bool = False

    def contains(self, points: np.ndarray, margin=0.0) -> np.ndarray:
        """Boolean (N,) mask of points (N, 3) inside the box grown by ``margin`` metres on every side
        (a scalar, or (3,) per box axis)."""
        rel = np.asarray(points, dtype=np.float64) - np.asarray(self.center)
        local = rel @ yaw_rotation(self.yaw)  # row vectors: R^T rel, the box's own axes
        half = np.asarray(self.size) / 2.0 + margin
        return np.all(np.abs(local) <= half, axis=1)


def _margins(margin) -> np.ndarray:
    """A scalar or (3,) margin (metres, per world axis x, y, z) -> (3,) float array."""
    return np.broadcast_to(np.asarray(margin, dtype=np.float64), (3,))


@dataclass(frozen=True)
class Cylinder:
    """A closed (capped) circular cylinder.

    Attributes:
        center: (x, y, z) centre of the axis segment, metres.
        radius: metres.
        length: extent along the axis, metres.
        material: key into ``SceneSpec.materials``.
        axis: "x", "y" or "z": the object axis the cylinder runs along, before ``yaw``.
        yaw: rotation about +Z, radians.
        name: optional object name (shows in Blender).
    """

    center: tuple[float, float, float]
    radius: float
    length: float
    material: str
    axis: str = "z"
    yaw: float = 0.0
    name: str = ""

    def frame(self) -> np.ndarray:
        """(3, 3) world-from-local rotation whose third column is the cylinder's axis (unit, world)."""
        rot = yaw_rotation(self.yaw)
        k = CYLINDER_AXES.index(self.axis)
        return rot[:, [(k + 1) % 3, (k + 2) % 3, k]]

    def contains(self, points: np.ndarray, margin=0.0) -> np.ndarray:
        """Boolean (N,) mask of points (N, 3) inside the cylinder grown by ``margin`` metres (a scalar, or (3,)
        per world axis: a vertical cylinder grows by the x/y margin radially and the z margin along its axis;
        a horizontal one by the largest margin radially and the largest horizontal one along its axis, which is
        conservative)."""
        m = _margins(margin)
        if self.axis == "z":
            m_axial, m_radial = m[2], max(m[0], m[1])
        else:
            m_axial, m_radial = max(m[0], m[1]), float(m.max())
        local = (np.asarray(points, dtype=np.float64) - np.asarray(self.center)) @ self.frame()
        radial = np.hypot(local[:, 0], local[:, 1])
        return (np.abs(local[:, 2]) <= self.length / 2.0 + m_axial) & (radial <= self.radius + m_radial)


@dataclass(frozen=True)
class Sphere:
    """A sphere: ``center`` (x, y, z) and ``radius``, metres; ``material`` a key into ``SceneSpec.materials``."""

    center: tuple[float, float, float]
    radius: float
    material: str
    name: str = ""

    def contains(self, points: np.ndarray, margin=0.0) -> np.ndarray:
        """Boolean (N,) mask of points (N, 3) inside the sphere grown by ``margin`` metres (a scalar, or (3,)
        per world axis, of which the largest is used: conservative)."""
        rel = np.asarray(points, dtype=np.float64) - np.asarray(self.center)
        return np.einsum("ij,ij->i", rel, rel) <= (self.radius + float(_margins(margin).max())) ** 2


@dataclass(frozen=True)
class Light:
    """A light source.

    Attributes:
        kind: "area" (rectangle facing -Z), "point" or "sun".
        position: (x, y, z), metres (direction is straight down for "sun").
        size: (sx, sy) of an area light, metres.
        power: watts (strength in W/m^2 for "sun").
        color: linear RGB.
    """

    kind: str
    position: tuple[float, float, float]
    size: tuple[float, float] = (0.6, 0.6)
    power: float = 100.0
    color: tuple[float, float, float] = (1.0, 1.0, 1.0)


@dataclass(frozen=True)
class ModelFile:
    """An external model (``.blend``, ``.glb``/``.gltf`` or ``.obj``) placed in the scene (Cycles only)."""

    path: Path
    location: tuple[float, float, float] = (0.0, 0.0, 0.0)
    rotation_euler: tuple[float, float, float] = (0.0, 0.0, 0.0)
    scale: float = 1.0


@dataclass
class SceneSpec:
    """Everything a backend needs to build a scene.

    Attributes:
        name: scene family name.
        params: what it was built from, as a frame records it (``frame.json`` ``renderer.scene.params``):
            ``preset`` and ``seed``, then the preset's parameter values and the overrides, as given (not the
            defaults; :meth:`SceneEntry.build_spec` sets it).
        materials: by name.
        boxes: geometry; the room shell (``inward=True``) included.
        cylinders: capped cylinders (round tables, legs, pipes, lamps).
        spheres: spheres (lamps, plants, balls).
        lights: light sources.
        models: external model files (the Cycles renderer only; the ray-caster refuses them).
        bounds: ((xmin, ymin, zmin), (xmax, ymax, zmax)) of the free interior, metres; viewpoints are drawn here.
        rig_height: (low, high) range of camera C's height above the floor, metres.
        viewpoints: explicit rigs; if given, ``choose_viewpoints`` uses these instead of sampling.
        background: world colour seen by rays that leave the scene, linear RGB.
        code_version: version of the code that built the spec (``SceneEntry.build_spec`` sets
            :attr:`SceneEntry.code_version`: the family's declared ``version``, else a hash of its source); recorded
            in frame provenance so a rerun notices a scene that builds differently.
    """

    name: str
    params: dict = field(default_factory=dict)
    materials: dict[str, Material] = field(default_factory=dict)
    boxes: list[Box] = field(default_factory=list)
    cylinders: list[Cylinder] = field(default_factory=list)
    spheres: list[Sphere] = field(default_factory=list)
    lights: list[Light] = field(default_factory=list)
    models: list[ModelFile] = field(default_factory=list)
    bounds: tuple[tuple[float, float, float], tuple[float, float, float]] = ((-2, -2, 0), (2, 2, 3))
    rig_height: tuple[float, float] = (1.1, 1.5)
    viewpoints: list[Rig] = field(default_factory=list)
    background: tuple[float, float, float] = (0.05, 0.05, 0.05)
    code_version: str = ""

    def add_material(self, material: Material) -> str:
        self.materials[material.name] = material
        return material.name

    def shapes(self) -> list:
        """Every shape: boxes (the room shell included), then cylinders, then spheres (the renderers' order)."""
        return [*self.boxes, *self.cylinders, *self.spheres]

    def solids(self) -> list:
        """Every shape that is not a room shell: boxes with ``inward=False``, cylinders and spheres."""
        return [b for b in self.boxes if not b.inward] + [*self.cylinders, *self.spheres]

    def validate(self) -> None:
        """Raise ValueError naming the culprit if a shape names an unknown material, a size is not positive or
        finite, a cylinder axis is unknown, a light is of an unknown kind, or a model file is missing or of an
        unsupported format."""
        for shape in self.shapes():
            kind = type(shape).__name__.lower()
            label = f"{kind} {shape.name or shape.center}"
            if shape.material not in self.materials:
                raise ValueError(f"scene {self.name!r}: {label} uses unknown material {shape.material!r}")
            sizes = (shape.size if isinstance(shape, Box) else
                     (shape.radius, shape.length) if isinstance(shape, Cylinder) else (shape.radius,))
            if not all(np.isfinite(v) and v > 0 for v in sizes):
                raise ValueError(f"scene {self.name!r}: {label} has non-positive size {tuple(sizes)}")
            if not np.all(np.isfinite(shape.center)):
                raise ValueError(f"scene {self.name!r}: {label} has a non-finite centre")
            if isinstance(shape, Cylinder) and shape.axis not in CYLINDER_AXES:
                raise ValueError(f"scene {self.name!r}: {label} has unknown axis {shape.axis!r} "
                                 f"(known: {', '.join(CYLINDER_AXES)})")
        for i, light in enumerate(self.lights):
            if light.kind not in LIGHT_KINDS:
                raise ValueError(f"scene {self.name!r}: light {i} has unknown kind {light.kind!r} "
                                 f"(known: {', '.join(LIGHT_KINDS)})")
        for model in self.models:
            path = Path(model.path).expanduser()
            if path.suffix.lower() not in MODEL_SUFFIXES:
                raise ValueError(f"scene {self.name!r}: model file {path} has unsupported format "
                                 f"{path.suffix!r} (known: {', '.join(MODEL_SUFFIXES)})")
            if not path.is_file():
                raise ValueError(f"scene {self.name!r}: model file {path} does not exist")


def choose_viewpoints(spec: SceneSpec, n: int, seed: int, baseline_m: float = 0.4,
                      clearance_m: float = 0.3, floor_clearance_m: float = 0.35,
                      max_tries: int = 20000, tilt_max_rad: float = 0.0,
                      height_range: tuple[float, float] | None = None) -> list[Rig]:
    """Pick ``n`` rig placements deterministically from ``seed``, never inside or too near furniture.

    Viewpoint 0 is the free position closest to the centre of ``spec.bounds`` (a stable default); the
    others are drawn uniformly in the bounds (rig yaw uniform) until every camera centre is at least
    ``clearance_m`` from every solid box and from the room shell, and the rig stands on free floor: the
    vertical column below each camera is at least ``floor_clearance_m`` (horizontally) from every solid
    box, as for a tripod or robot standing in an aisle.  (A rig hovering over a desk sees the floor under
    it from C but not from R 0.4 m away: measured on classroom frames, such placements leave only 88 % of
    C's pixels visible from R; in aisles 95 %+.)

    ``height_range`` ((low, high) metres) replaces ``spec.rig_height`` for camera C's height.  With
    ``tilt_max_rad`` > 0 every rig (viewpoint 0 included) is tilted: pitch and roll each uniform in
    [-tilt_max_rad, tilt_max_rad], drawn from a generator of their own (seeded by ``(seed, 1)``), so the
    placements' draw is the same stream as without tilt; with 0 (the default) the rigs are level and every
    placement is exactly what it always was.

    Raises:
        ValueError: if fewer than ``n`` free placements are found, or a bad tilt or height range.
    """
    if spec.viewpoints:
        if len(spec.viewpoints) < n:
            raise ValueError(f"scene {spec.name!r} defines {len(spec.viewpoints)} viewpoints, {n} requested")
        return list(spec.viewpoints[:n])
    if not 0.0 <= tilt_max_rad < np.pi / 2:
        raise ValueError(f"scene {spec.name!r}: tilt_max_rad must be in [0, pi/2), got {tilt_max_rad}")
    rig_height = spec.rig_height if height_range is None else tuple(float(x) for x in height_range)
    if len(rig_height) != 2 or not 0.0 < rig_height[0] <= rig_height[1]:
        raise ValueError(f"scene {spec.name!r}: height range must be (low, high) with 0 < low <= high, "
                         f"got {height_range}")
    tilt_rng = np.random.default_rng([seed, 1]) if tilt_max_rad > 0 else None

    def tilt() -> dict:
        if tilt_rng is None:
            return {}
        pitch, roll = tilt_rng.uniform(-tilt_max_rad, tilt_max_rad, size=2)
        return {"pitch_rad": float(pitch), "roll_rad": float(roll)}

    rng = np.random.default_rng(seed)
    lo, hi = np.asarray(spec.bounds[0], float), np.asarray(spec.bounds[1], float)
    solids = spec.solids()

    def free(rig: Rig) -> bool:
        pts = np.array([p.position for p in rig.poses().values()])
        inner_lo, inner_hi = lo + clearance_m, hi - clearance_m
        if np.any(pts < inner_lo) or np.any(pts > inner_hi):
            return False
        if any(b.contains(pts, clearance_m).any() for b in solids):
            return False
        # columns under the cameras, every 0.1 m from the floor up to the camera
        heights = np.arange(0.05, pts[:, 2].max(), 0.1)
        column = np.concatenate([np.column_stack([np.full(heights.size, p[0]), np.full(heights.size, p[1]),
                                                  np.minimum(heights, p[2])]) for p in pts])
        horizontal = np.array([floor_clearance_m, floor_clearance_m, 0.0])
        return not any(b.contains(column, horizontal).any() for b in solids)

    rigs: list[Rig] = []
    centre = (lo + hi) / 2.0
    h_mid = float(np.mean(rig_height))
    # viewpoint 0: nearest free spot to the room centre, on a fixed spiral (deterministic, seed-independent)
    for k in range(2000):
        r, a = 0.05 * k ** 0.5 * 3, 2.39996 * k
        cand = Rig(position=np.array([centre[0] + r * np.cos(a), centre[1] + r * np.sin(a), h_mid]),
                   yaw_rad=0.0, baseline_m=baseline_m, **tilt())
        if free(cand):
            rigs.append(cand)
            break
    for _ in range(max_tries):
        if len(rigs) >= n:
            break
        pos = rng.uniform(lo, hi)
        pos[2] = rng.uniform(*rig_height)
        cand = Rig(position=pos, yaw_rad=float(rng.uniform(-np.pi, np.pi)), baseline_m=baseline_m, **tilt())
        if free(cand):
            rigs.append(cand)
    if len(rigs) < n:
        raise ValueError(f"scene {spec.name!r}: found only {len(rigs)} free rig placements of {n} requested")
    return rigs[:n]


SHARED_SOURCES = (Path(__file__), Path(__file__).with_name("families") / "_kit.py")
"""Source files every family's :attr:`SceneEntry.source_version` includes (the scene model and the shared
randomisation kit): the code version of a family that declares no ``version``."""
RENDERERS = ("cycles", "raycast")
"""Renderer names a scene may name as its default (``harness.render.registry`` implements them)."""
RESERVED_PARAMETERS = ("preset", "seed")
"""Keys of ``SceneSpec.params`` set by the registry itself; not scene parameters."""


class SceneError(ValueError):
    """Unknown scene, unknown preset, or a scene file/build function that failed."""


# ------------------------------------------------------------------------------------------------ parameters

PARAM_METADATA = METADATA_KEY
"""Key of a scene parameter's :class:`reconstruction.params.ParamInfo` in its dataclass field's ``metadata``
(:data:`reconstruction.params.METADATA_KEY`)."""


class ParameterError(SceneError, ParamError):
    """A scene parameter that is unknown, of the wrong type or out of its limits: one line,
    ``scene 'classroom': rows: expected an integer in [0, 100], got 'many'`` (:class:`reconstruction.params.ParamError`;
    ``where`` is empty for parameters built outside a :class:`SceneEntry`)."""


@dataclass(frozen=True)
class SceneParams:
    """Base class of a scene family's parameters: a frozen dataclass whose fields are declared with :func:`param`.

    A family subclasses it (decorated with ``@dataclass(frozen=True)``); ``build`` gets an instance.  Making
    one checks every field against its annotation and its limits and choices, and normalises it (a list becomes a
    tuple, an int given for a float a float): :func:`reconstruction.params.check_value`.  Annotations understood:
    ``float``, ``int``, ``bool``, ``str``, ``tuple[T, T, ...]`` of a fixed length and ``tuple[T, ...]`` (T one of
    these), each optionally ``| None``.  The values come from JSON or TOML (``--set``, a suite's ``params``), so a
    bool is no number and 2.0 no whole number.  The base class itself declares no parameters (a family that has
    none).

    Raises:
        ParameterError: the first field that is of the wrong type or out of range.
    """

    def __post_init__(self):
        hints = type_hints(type(self))
        for f in fields(self):
            try:
                checked = check_value(getattr(self, f.name), hints[f.name], info_of(f), name=f.name)
            except ParamError as exc:
                raise exc.at("", ParameterError) from None
            object.__setattr__(self, f.name, checked)


@dataclass(frozen=True)
class SceneEntry:
    """A registered scene family.

    Attributes:
        name: what users type after ``--scene``.
        build: ``build(params, seed: int) -> SceneSpec``; ``params`` is an instance of ``parameters`` (a
            :class:`SceneParams` dataclass).
        description: one line for ``tri360 scenes``.
        presets: named parameter sets: each a dict of overrides of the parameters' defaults, in the order a frame
            records them (``SceneSpec.params``); ``default_preset`` is used when none is given.
        default_preset: key into ``presets``.
        parameters: the family's parameters: a frozen :class:`SceneParams` dataclass (each field's type, default,
            unit, limits and description; ``--set``, suites and presets may use only its fields and values of
            its types); default :class:`SceneParams` itself, no parameters.
        renderer: the default renderer, "cycles" (Blender) or "raycast" (the numpy ray-caster, boxes only,
            no Blender needed); ``tri360 render --renderer`` picks another.
        source: where it was found (file or entry point), for error messages.
        tags: what the family is hard for, each one of ``DIFFICULTY_TAGS``.
        version: the family's scene code version, as frames and suite ids record it (:attr:`code_version`):
            declared by every built-in family (an opaque string, e.g. ``"sha256:1ed56314fc16eeec"``; change it
            whenever what the family builds changes, and only then: ``tests/scenes/scene_fingerprints.json``
            checks that).  Empty (an outside family that declares none): the hash of its source,
            :attr:`source_version`.
    """

    name: str
    build: Callable[[Any, int], SceneSpec]
    description: str = ""
    presets: dict[str, dict] = field(default_factory=lambda: {"default": {}})
    default_preset: str = "default"
    parameters: type[SceneParams] = SceneParams
    renderer: str = "cycles"
    source: str = ""
    tags: tuple[str, ...] = ()
    version: str = ""

    def __post_init__(self):
        if not isinstance(self.version, str) or self.version != self.version.strip() or \
                any(c.isspace() for c in self.version):
            raise SceneError(f"scene {self.name!r}: version must be a string without spaces (e.g. "
                             f"'sha256:1ed56314fc16eeec'), got {self.version!r}")
        if self.renderer not in RENDERERS:
            raise SceneError(f"scene {self.name!r}: renderer must be one of {RENDERERS}, got {self.renderer!r}")
        if self.default_preset not in self.presets:
            raise SceneError(f"scene {self.name!r}: default preset {self.default_preset!r} not in presets")
        if isinstance(self.tags, str) or not all(isinstance(t, str) for t in self.tags):
            raise SceneError(f"scene {self.name!r}: tags must be a tuple of strings, got {self.tags!r}")
        unknown = sorted(set(self.tags) - set(DIFFICULTY_TAGS))
        if unknown:
            raise SceneError(f"scene {self.name!r}: unknown tag(s) {', '.join(unknown)} "
                             f"(known: {', '.join(DIFFICULTY_TAGS)})")
        self._check_parameter_class()
        reserved = sorted(set(self.known_parameters) & set(RESERVED_PARAMETERS))
        if reserved:
            raise SceneError(f"scene {self.name!r}: parameter name(s) {reserved} are reserved")
        for preset, params in self.presets.items():
            try:
                from_mapping(self.parameters, params, where=f"scene {self.name!r}: preset {preset!r}")
            except ParamError as exc:
                raise exc.at(exc.where, ParameterError) from None

    def _check_parameter_class(self) -> None:
        """Refuse ``parameters`` that is not a frozen :class:`SceneParams` dataclass with a default and a
        :func:`param` declaration for every field; check the dataclass's defaults."""
        cls = self.parameters
        hint = "declare them as a frozen dataclass deriving from scenes.model.SceneParams (see scenes/README.md)"
        if not isinstance(cls, type) or not issubclass(cls, SceneParams):
            raise SceneError(f"scene {self.name!r}: parameters must be a SceneParams dataclass, got "
                             f"{type(cls).__name__ if not isinstance(cls, type) else cls.__name__}; {hint}")
        own = vars(cls).get("__dataclass_params__")
        if own is None or not own.frozen:
            raise SceneError(f"scene {self.name!r}: parameters {cls.__name__} is not decorated with "
                             f"@dataclass(frozen=True); {hint}")
        for f in fields(cls):
            if PARAM_METADATA not in f.metadata or not info_of(f).description:
                raise SceneError(f"scene {self.name!r}: parameter {f.name!r} of {cls.__name__} is not declared with "
                                 f"scenes.model.param(default, description, unit=..., limits=...) and a description")
        try:
            cls()
        except TypeError as exc:  # a field without a default
            raise SceneError(f"scene {self.name!r}: every parameter of {cls.__name__} needs a default "
                             f"({exc})") from None
        except ParameterError as exc:
            raise exc.at(f"scene {self.name!r}: defaults of {cls.__name__}") from None

    @property
    def known_parameters(self) -> list[str]:
        """Sorted names of the declared parameters: the keys ``--set`` accepts."""
        return sorted(f.name for f in fields(self.parameters))

    def describe_parameters(self) -> dict[str, str]:
        """Parameter name -> one line (description, unit, default, allowed values) for ``tri360 scenes
        --params``, in declaration order (:func:`reconstruction.params.describe`)."""
        return describe(self.parameters)

    def parameter_values(self, params: Mapping) -> SceneParams:
        """What ``build`` gets for the parameter dict ``params`` (a preset's merged with overrides): an instance
        of the parameters dataclass (:func:`reconstruction.params.from_mapping`).

        Raises:
            SceneError: a reserved key (``preset``, ``seed``).
            ParameterError: an unknown parameter (listing the declared ones), a value of the wrong type or out of
                range (naming the family, the parameter and what it expects).
        """
        for key in params:
            if key in RESERVED_PARAMETERS:
                hint = "--scene NAME:PRESET" if key == "preset" else "--seed"
                raise SceneError(f"scene {self.name!r}: {key!r} is not a scene parameter (use {hint})")
        try:
            return from_mapping(self.parameters, params, where=f"scene {self.name!r}")
        except ParamError as exc:
            raise exc.at(exc.where, ParameterError) from None

    @property
    def code_version(self) -> str:
        """The version frames record (``scene.code_version``) and suite ids include: the declared ``version``
        (every built-in family declares one; it changes only when what the family builds changes), else
        :attr:`source_version`."""
        return self.version or self.source_version

    @property
    def source_version(self) -> str:
        """``"sha256:<16 hex>"`` of the source file defining ``build`` (of its source code when the file
        cannot be read; ``""`` if neither can) together with the shared code every family builds with (this
        file, ``scenes/model.py``, and the randomisation kit ``scenes/families/_kit.py``): changes whenever the
        family's code or the shared scene code is edited, even when what it builds does not.  The code version
        of a family that declares no ``version`` (an outside family)."""
        try:
            data = Path(inspect.getsourcefile(self.build) or "").read_bytes()
        except (OSError, TypeError):
            try:
                data = inspect.getsource(self.build).encode("utf-8")
            except (OSError, TypeError):
                return ""
        h = hashlib.sha256(data)
        for path in SHARED_SOURCES:
            h.update(b"\0" + path.name.encode() + b"\0")
            h.update(path.read_bytes() if path.is_file() else b"")
        return "sha256:" + h.hexdigest()[:16]

    def spec(self, preset: str | None = None, seed: int = 0, **overrides) -> SceneSpec:
        """Build the scene for a preset (default if None), with parameter ``overrides`` (see :meth:`build_spec`)."""
        return self.build_spec(preset, seed, overrides)

    def build_spec(self, preset: str | None = None, seed: int = 0, overrides: Mapping | None = None) -> SceneSpec:
        """Build the scene for a preset (default if None), with parameter ``overrides`` (a dict, so that any key,
        even ``seed``, is checked as a parameter name).  The spec records ``{"preset", "seed"}`` then the preset's
        parameters and the overrides as given (``SceneSpec.params``), not the defaults.

        Raises:
            SceneError: unknown preset, a parameter that is unknown, of the wrong type or out of range
                (:class:`ParameterError`), or a build function or spec that fails.
        """
        preset = preset or self.default_preset
        if preset not in self.presets:
            raise SceneError(f"scene {self.name!r}: unknown preset {preset!r} (known: {sorted(self.presets)})")
        params = {**self.presets[preset], **dict(overrides or {})}
        values = self.parameter_values(params)
        try:
            spec = self.build(values, int(seed))
            spec.validate()
        except SceneError:
            raise
        except Exception as exc:
            raise SceneError(f"scene {self.name!r} ({self.source}) failed to build: "
                             f"{type(exc).__name__}: {exc}") from exc
        spec.params = {"preset": preset, "seed": int(seed), **params}
        spec.code_version = self.code_version
        return spec

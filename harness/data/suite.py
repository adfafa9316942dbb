"""Benchmark suites (``tri360-suite/1``): a versioned TOML file that lists frames by recipe, split into dev, test
and train.

A suite file ``suites/<name>.toml`` (format and rationale: ``docs/suites.md``)::

    format = "tri360-suite/1"
    name = "tri360-v1"
    description = "one line"

    [render]                    # render settings of every frame (harness.render.base.RenderSettings fields but
    width = 1000                # threads, which is this machine's business: `tri360 render --threads`)
    samples = 20

    [[frames]]                  # one group of viewpoints of one scene: family, preset, parameters, seed
    family = "classroom"
    preset = "lecture"          # optional: the family's default preset
    seed = 101                  # scene layout, viewpoint draw and render noise (as `tri360 render --seed`)
    viewpoints = 2
    split = "dev"               # "dev", "test" or "train" (:data:`SPLITS`)
    name = "classroom-lecture-s101"   # optional: the scene directory of its frames (default shown)
    params = { rows = 5 }       # optional: scene parameter overrides (the family's declared parameters, of their types)
    renderer = "cycles"         # optional: the family's default renderer
    tags = ["far"]              # optional: difficulty tags (scenes.model.DIFFICULTY_TAGS), default the family's
    rig = { baseline_m = 0.3, height_m = [1.0, 1.6], tilt_max_rad = 0.1 }   # optional, defaults 0.4, the
                                # family's height range, 0 (level)

Frames land in ``<data root>/<name>/vp000 ...``.  A published suite file is never edited: a change is a new file
(``tri360-v2.toml``).  The **suite id** (:func:`suite_id`) hashes the file's bytes, the code version of every
family it uses and the complete render settings (with tri360's defaults for what the file leaves out): two results
with the same suite id and split were measured on the same frames.

Twins under a condition live in ``<data root>/<name>.<condition>/vp000 ...``: no group may be named like another
group's twin directory.  A condition with ``held_out = true`` is rendered, checked and reported like any other, but
no selection (of defaults, parameters or methods) may use its frames: :meth:`Suite.selectable_conditions`.  A
condition's calibration error is checked against every group's rig when the file is read
(:func:`told_rig_problem`): the largest error the condition can draw, in the worst direction, must leave a told rig
that frame validation (``harness.data.frame``) accepts.

Every problem is one :class:`UserError` line naming the file and the key, as a TOML dotted key
(``frames[0].rig.baseline_m``, ``conditions.captured.jpeg_quality``); a key or value of the wrong type or out of
range in the one format of :mod:`reconstruction.params` (``<file>: <key>: expected <what>, got <value>``), checked
against the fields of :class:`SuiteRig`, :class:`CameraDistribution` and the scene family's parameters.  This
module reads and checks only; the render settings' names and defaults come from the caller
(``harness.commands.parts.suite``, which owns ``RenderSettings``).
"""

from __future__ import annotations

import hashlib
import itertools
import json
import math
import tomllib
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from harness.data.errors import FrameError, UserError
from harness.data.frame import FORMAT as FRAME_FORMAT
from harness.data.frame import baseline_tolerance_m, validate_metadata
from harness.data.names import check_name
from harness.data.photometric import CameraDistribution
from reconstruction.camera.rig import CameraPose, Rig, yaw_rotation
from reconstruction.params import REQUIRED, ParamError, check_keys, check_value, from_mapping, param, shown
from scenes.model import DIFFICULTY_TAGS, RENDERERS, SceneEntry, SceneError
from scenes.registry import discover

__all__ = ["FORMAT", "SPLITS", "IDEAL", "SuiteRig", "SuiteEntry", "SuiteFrame", "Suite", "load_suite", "suite_id",
           "told_rig_problem"]

FORMAT = "tri360-suite/1"
SPLITS = ("dev", "test", "train")
"""dev: choose defaults; test: report once; train: train learned methods (``suites/tri360-train-v1.toml``).
No two splits of a suite share a seed."""
TOP_KEYS = ("format", "name", "description", "render", "frames", "conditions")
IDEAL = "ideal"
"""The condition of the rendered frames themselves: three identical, perfectly exposed cameras."""
#: render settings a suite may not fix: ``threads`` changes no pixel (this machine's choice), ``seed`` is each
#: ``[[frames]]`` group's own (as ``tri360 render --seed`` sets both the scene's and the render noise's seed)
MACHINE_SETTINGS = ("threads", "seed")
#: safe names (the directory level of a suite's frames): the character set of tri360's names, no leading dot
MAX_VIEWPOINTS = 1000


@dataclass(frozen=True)
class SuiteRig:
    """The rig of a frame group: baseline (metres), C's height range (metres, None = the family's), tilt bound
    (radians: pitch and roll each uniform in [-t, t]; 0 = level); a group's ``rig`` table is checked against the
    fields' limits."""

    baseline_m: float = param(0.4, unit="m", limits=(0.0, 100.0), exclusive=(True, True))
    height_m: tuple[float, float] | None = param(None, unit="m", limits=(0.0, 100.0), exclusive=(True, True),
                                                 ordered=True)
    tilt_max_rad: float = param(0.0, unit="rad", limits=(0.0, math.pi / 2), exclusive=(False, True))


@dataclass(frozen=True, kw_only=True)
class _Group:
    """A ``[[frames]]`` table as the file gives it (None: the family's; :class:`SuiteEntry` has the meanings)."""

    family: str = param(REQUIRED)
    preset: str | None = None
    seed: int = param(REQUIRED, limits=(0, 2 ** 32), exclusive=(False, True))
    viewpoints: int = param(REQUIRED, limits=(1, MAX_VIEWPOINTS))
    split: str = param(REQUIRED, choices=SPLITS)
    name: str | None = None
    params: dict | None = None
    renderer: str | None = param(None, choices=RENDERERS)
    tags: tuple[str, ...] | None = param(None, choices=DIFFICULTY_TAGS)
    rig: SuiteRig = SuiteRig()


@dataclass(frozen=True)
class SuiteEntry:
    """One ``[[frames]]`` group: ``viewpoints`` rig placements of one scene (family, preset, params, seed)."""

    name: str
    family: str
    preset: str
    seed: int
    viewpoints: int
    split: str
    params: Mapping = field(default_factory=dict)
    renderer: str = ""
    tags: tuple[str, ...] = ()
    rig: SuiteRig = SuiteRig()

    def viewpoint_names(self) -> list[str]:
        return [f"vp{i:03d}" for i in range(self.viewpoints)]


@dataclass(frozen=True)
class SuiteFrame:
    """One frame of a suite: its group, viewpoint index and condition; it lives in
    ``<root>/<entry.name>/<viewpoint>`` (the rendered frame, condition ``ideal``) or
    ``<root>/<entry.name>.<condition>/<viewpoint>`` (its twin under another condition, derived from it)."""

    entry: SuiteEntry
    index: int
    condition: str = IDEAL

    @property
    def scene(self) -> str:
        return self.entry.name if self.condition == IDEAL else f"{self.entry.name}.{self.condition}"

    @property
    def twin_seed(self) -> int:
        """The seed of this frame's twins (the group's seed and the viewpoint index: unique within a suite)."""
        return self.entry.seed * MAX_VIEWPOINTS + self.index

    @property
    def source(self) -> SuiteFrame:
        """The rendered frame a twin is derived from (itself for an ideal frame)."""
        return SuiteFrame(self.entry, self.index)

    @property
    def viewpoint(self) -> str:
        return f"vp{self.index:03d}"

    @property
    def label(self) -> str:
        return f"{self.scene}/{self.viewpoint}"


@dataclass(frozen=True)
class Suite:
    """A loaded, checked suite.

    Attributes:
        path: the file.  name, description: from the file.  render: every render setting (the file's over the
        defaults, without :data:`MACHINE_SETTINGS`).  entries: the frame groups in file order.  code_versions:
        family -> code version (``SceneEntry.code_version``).  id: :func:`suite_id`.  conditions: the conditions
        beside ``ideal`` (name -> the distribution its cameras are drawn from, whose ``held_out`` says that no
        selection may use it), in file order.
    """

    path: Path
    name: str
    description: str
    render: Mapping
    entries: tuple[SuiteEntry, ...]
    code_versions: Mapping
    id: str
    conditions: Mapping[str, CameraDistribution] = field(default_factory=dict)

    def condition_names(self) -> list[str]:
        """``ideal`` and the declared conditions, in that order."""
        return [IDEAL, *self.conditions]

    def selectable_conditions(self) -> list[str]:
        """``ideal`` and the declared conditions a selection may use (not ``held_out``), in that order."""
        return [IDEAL, *(k for k, v in self.conditions.items() if not v.held_out)]

    def held_out_conditions(self) -> list[str]:
        """The conditions marked ``held_out``: results report them, no selection (of defaults, parameters, methods)
        may use their frames."""
        return [k for k, v in self.conditions.items() if v.held_out]

    def splits(self) -> list[str]:
        return [s for s in SPLITS if any(e.split == s for e in self.entries)]

    def frames(self, split: str) -> list[SuiteFrame]:
        """Every frame of ``split``, in file order (UserError naming the file for an unknown or empty split)."""
        if split not in SPLITS:
            raise UserError(f"{self.path}: unknown split {split!r} (a suite has {', '.join(SPLITS)})")
        out = [SuiteFrame(e, i) for e in self.entries if e.split == split for i in range(e.viewpoints)]
        if not out:
            raise UserError(f"{self.path}: split {split!r} has no frames")
        return out + [SuiteFrame(f.entry, f.index, c) for c in self.conditions for f in out]

    def describe(self, split: str) -> dict:
        """What results record about the suite: ``{format, name, id, split, file, code_versions, render,
        conditions, frames: [{scene, viewpoint, family, preset, seed, tags, condition}]}``."""
        return {"format": FORMAT, "name": self.name, "id": self.id, "split": split,
                "file": str(Path(self.path).resolve()), "code_versions": dict(self.code_versions),
                "render": dict(self.render),
                "conditions": {k: v.to_json() for k, v in self.conditions.items()},
                "frames": [{"scene": f.scene, "viewpoint": f.viewpoint, "family": f.entry.family,
                            "preset": f.entry.preset, "seed": f.entry.seed, "tags": list(f.entry.tags),
                            "condition": f.condition}
                           for f in self.frames(split)]}


def _fail(path: Path, where: str, what: str):
    raise UserError(f"{path}: {where}: {what}")


def _render(path: Path, raw, defaults: Mapping) -> dict:
    """The ``[render]`` table over ``defaults``: each key one of theirs (not :data:`MACHINE_SETTINGS`), each value
    of its default's type."""
    if isinstance(raw, dict):
        if "threads" in raw:
            _fail(path, "render.threads", "is this machine's choice, not the suite's (use `tri360 render --threads`)")
        if "seed" in raw:
            _fail(path, "render.seed", "is set per [[frames]] group (its seed also seeds the render noise)")
    out = {k: v for k, v in defaults.items() if k not in MACHINE_SETTINGS}
    for key, value in check_keys(raw, list(out), name="render", where=str(path)).items():
        out[key] = check_value(value, type(defaults[key]), name=f"render.{key}", where=str(path), null=False)
    return out


def _entry(path: Path, i: int, raw, scenes: dict[str, SceneEntry], errors: dict[str, str]) -> SuiteEntry:
    """One ``[[frames]]`` table: its keys and values (:class:`_Group`), then what depends on its family."""
    where = f"frames[{i}]"
    g = from_mapping(_Group, raw, where=str(path), name=where, null=False)
    if g.family not in scenes:
        hint = f"; failed scene files: {', '.join(sorted(errors))}" if errors else ""
        raise ParamError(f"{where}.family", f"one of {', '.join(sorted(scenes))}{hint}", shown(g.family), str(path))
    scene = scenes[g.family]
    preset = scene.default_preset if g.preset is None else g.preset
    if preset not in scene.presets:
        raise ParamError(f"{where}.preset", f"a preset of {g.family}: one of {', '.join(sorted(scene.presets))}",
                         shown(preset), str(path))
    params = g.params or {}
    try:
        scene.parameter_values({**scene.presets[preset], **params})
    except ParamError as exc:
        raise ParamError(f"{where}.params.{exc.name}", exc.expected, exc.got, str(path)) from None
    except SceneError as exc:
        _fail(path, f"{where}.params", str(exc))
    default_name = f"{g.family}-s{g.seed}" if preset == scene.default_preset else f"{g.family}-{preset}-s{g.seed}"
    name = default_name if g.name is None else g.name
    check_name(name, f"{path}: {where}.name")
    tags = scene.tags if g.tags is None else g.tags
    return SuiteEntry(name=name, family=g.family, preset=preset, seed=g.seed, viewpoints=g.viewpoints, split=g.split,
                      params=dict(params), renderer=scene.renderer if g.renderer is None else g.renderer,
                      tags=tuple(dict.fromkeys(tags)), rig=g.rig)


def _condition(path: Path, name, raw) -> CameraDistribution:
    """One ``[conditions.<name>]`` table -> its :class:`CameraDistribution` (defaults for what it leaves out): each
    key and value checked against the distribution's fields, then the rules between keys."""
    where = f"conditions.{name}"
    check_name(name, f"{path}: [{where}]")
    if name == IDEAL:
        _fail(path, f"[{where}]", "'ideal' is the rendered frames' own condition; name the other one otherwise")
    d = from_mapping(CameraDistribution, raw, where=str(path), name=where, null=False)
    if d.jpeg_quality[0] == 0 and d.jpeg_quality[1] != 0:
        raise ParamError(f"{where}.jpeg_quality", "[0, 0] (no compression) or a range of qualities in [1, 100]",
                         shown(raw["jpeg_quality"]), str(path))
    if "responses" in raw and "response" in raw:
        _fail(path, f"{where}.responses", "each camera's response is drawn from responses: leave response out")
    lenses = d.falloff[1] > 0 or d.lens_mismatch[1] > 0
    if d.lens_tilt_deg[1] > 0 and not lenses:
        _fail(path, f"{where}.lens_tilt_deg", "tilts the lens axis of falloff and lens_mismatch: give one of them")
    if d.lens_mismatch[1] > 0 and d.seam_blend_deg[0] <= 0:
        raise ParamError(f"{where}.seam_blend_deg", "[low, high] degrees with 0 < low (the stitch cross-fades the "
                         "lenses over a band)", shown(list(d.seam_blend_deg)), str(path))
    if d.lens_mismatch[1] == 0 and d.seam_blend_deg[1] > 0:
        _fail(path, f"{where}.seam_blend_deg", "is the width of the cross-fade of lens_mismatch: give lens_mismatch")
    worst = (1.0 + d.chromatic[1]) * max(d.vignetting[1], d.falloff[1])
    if worst > 0.999:
        _fail(path, f"{where}.chromatic", f"red's loss (1 + {d.chromatic[1]:g}) x the largest edge loss "
                                          f"({max(d.vignetting[1], d.falloff[1]):g}) is {worst:g}, more than 0.999")
    return d


_TOLD_RIG_PATH = Path("told-rig")


def _worst_told_rigs(baseline_m: float, translation_mm: float,
                     rotation_deg: float) -> list[dict[str, CameraPose]]:
    """The told rigs of a level rig of ``baseline_m`` whose U and R are each off by ``translation_mm`` and
    ``rotation_deg``, their errors in the directions worst for frame validation: one baseline longer and the other
    shorter (baseline tolerance), both shorter (camera separation), U and R moved towards each other (their
    separation) and turned towards each other (colinearity).  C is exact, as in a twin."""
    true = Rig(baseline_m=baseline_m).poses()
    up, right = true["U"].position - true["C"].position, true["R"].position - true["C"].position
    up, right = up / np.linalg.norm(up), right / np.linalg.norm(right)
    diagonal = (right - up) / math.sqrt(2.0)
    turn = yaw_rotation(math.radians(rotation_deg))
    out = []
    for d_u, d_r in ((up, -right), (-up, -right), (diagonal, -diagonal), (right, up)):
        out.append({"C": true["C"],
                    "U": CameraPose(true["U"].position + d_u * translation_mm / 1000.0, turn @ true["U"].rotation),
                    "R": CameraPose(true["R"].position + d_r * translation_mm / 1000.0, turn @ true["R"].rotation)})
    return out


def told_rig_problem(baseline_m: float, translation_mm: float, rotation_deg: float) -> str | None:
    """Why frame validation (:func:`harness.data.frame.validate_metadata`) could refuse the told rig of a twin whose
    rig has baseline ``baseline_m`` and whose U and R calibration errors reach ``translation_mm`` and
    ``rotation_deg`` (the worst directions, :func:`_worst_told_rigs`; the told ``baseline_m`` is the mean of the
    told ``|U - C|`` and ``|R - C|``, as a twin records it), or None if no such draw can make an invalid frame."""
    for cameras in _worst_told_rigs(baseline_m, translation_mm, rotation_deg):
        told = [float(np.linalg.norm(cameras[k].position - cameras["C"].position)) for k in ("U", "R")]
        meta = {"format": FRAME_FORMAT, "scene": "told-rig", "viewpoint": "vp000", "width": 2, "height": 1,
                "baseline_m": sum(told) / 2.0, "cameras": {k: v.to_json() for k, v in cameras.items()}}
        try:
            validate_metadata(meta, _TOLD_RIG_PATH)
        except FrameError as exc:
            return str(exc).removeprefix(str(_TOLD_RIG_PATH)).lstrip(": ")
    return None


def _check_calibration(path: Path, name: str, dist: CameraDistribution, entries: list[SuiteEntry]) -> None:
    """Refuse a condition whose largest calibration error could make a twin's told rig invalid in some group."""
    problems: dict[tuple[float, float], str | None] = {}

    def problem(baseline_m: float, translation_mm: float) -> str | None:
        key = (baseline_m, translation_mm)
        if key not in problems:
            problems[key] = told_rig_problem(baseline_m, translation_mm, dist.rotation_deg[1])
        return problems[key]

    for key, mm, what in (("rotation_deg", 0.0, f"{dist.rotation_deg[1]:g} degrees"),
                          ("translation_mm", dist.translation_mm[1], f"{dist.translation_mm[1]:g} mm")):
        for i, e in enumerate(entries):
            reason = problem(e.rig.baseline_m, mm)
            if reason is None:
                continue
            hint = ""
            if key == "translation_mm":  # the frame format's baseline tolerance of the tightest group
                fits = min(baseline_tolerance_m(x.rig.baseline_m) * 1000.0 for x in entries)
                if all(problem(x.rig.baseline_m, fits * (1.0 - 1e-6)) is None for x in entries):
                    hint = f"; keep the high end below {fits:g} mm (the tolerance of the tightest group's baseline)"
            _fail(path, f"[conditions.{name}] {key}",
                  f"a calibration error of up to {what} can make a told rig that frame validation refuses, in "
                  f"frames[{i}] ({e.name}, baseline {e.rig.baseline_m:g} m): {reason}{hint}")


def _check_directories(path: Path, entries: list[SuiteEntry], conditions: Mapping) -> None:
    """Refuse a suite whose groups and twins would share a scene directory (``<group>`` and ``<group>.<condition>``)
    or whose twin directory is not a safe name."""
    owners = {e.name: (f"frames[{i}] name", f"the name of frames[{i}]") for i, e in enumerate(entries)}
    for i, e in enumerate(entries):
        for c in conditions:
            d = f"{e.name}.{c}"
            twins = f"the directory of frames[{i}]'s {c} twins ({e.name!r} under [conditions.{c}])"
            check_name(d, f"{path}: frames[{i}] name: {twins}")
            if d in owners:
                where, other = owners[d]
                _fail(path, where, f"{d!r} is {other} and also {twins}: their frames would overwrite each other; "
                                   "rename one")
            owners[d] = (f"[conditions.{c}]", twins)


def suite_id(file_bytes: bytes, code_versions: Mapping, render: Mapping) -> str:
    """``"sha256:<16 hex>"`` of the suite file's bytes, every family's code version and the render settings.

    Args:
        file_bytes: the suite file as stored.
        code_versions: family -> ``SceneEntry.code_version``, of every family the suite uses.
        render: the complete render settings (the file's over tri360's defaults).
    """
    blob = json.dumps({"format": FORMAT, "file_sha256": hashlib.sha256(file_bytes).hexdigest(),
                       "code_versions": dict(sorted(code_versions.items())), "render": dict(sorted(render.items()))},
                      sort_keys=True)
    return "sha256:" + hashlib.sha256(blob.encode("utf-8")).hexdigest()[:16]


def load_suite(path: Path, render_defaults: Mapping, scenes: dict[str, SceneEntry] | None = None) -> Suite:
    """Read and check a suite file.

    Args:
        path: the ``.toml`` file.
        render_defaults: every render setting's name and default (``dataclasses.asdict(RenderSettings())``); the
            ``[render]`` keys must be among them and of the same type.
        scenes: the scene registry (``scenes.registry.discover()[0]``); None = discover it.
    Raises:
        UserError: one line naming the file and the key: unreadable file, bad TOML, wrong format, unknown key,
            wrong type, unknown family/preset/parameter, a scene parameter of the wrong type or out of range,
            duplicate frame names, a group named like another group's twin directory, a seed used by two splits,
            or a condition whose calibration error could make an impossible told rig (:func:`told_rig_problem`).
    """
    try:
        return _load_suite(Path(path), render_defaults, scenes)
    except ParamError as exc:  # a key or value the declared parameters refuse (reconstruction.params)
        raise UserError(str(exc)) from None


def _load_suite(path: Path, render_defaults: Mapping, scenes: dict[str, SceneEntry] | None) -> Suite:
    """:func:`load_suite`, raising :class:`ParamError` for a key or value of the wrong type or out of range."""
    try:
        data = path.read_bytes()
    except FileNotFoundError:
        raise UserError(f"{path}: suite file does not exist") from None
    except IsADirectoryError:
        raise UserError(f"{path}: is a directory, not a suite file") from None
    except OSError as exc:
        raise UserError(f"{path}: cannot read the suite file ({exc.strerror or exc})") from None
    try:
        raw = tomllib.loads(data.decode("utf-8"))
    except (UnicodeDecodeError, tomllib.TOMLDecodeError) as exc:
        raise UserError(f"{path}: not valid TOML ({exc})") from None
    check_keys(raw, TOP_KEYS, where=str(path))
    if raw.get("format") != FORMAT:
        _fail(path, "format", f"must be {FORMAT!r}, got {raw.get('format')!r}")
    name = raw.get("name")
    check_name(name, f"{path}: name")
    description = check_value(raw.get("description", ""), str, name="description", where=str(path), null=False)
    render = _render(path, raw.get("render", {}), render_defaults)
    frames = raw.get("frames")
    if not isinstance(frames, list) or not frames:
        _fail(path, "frames", "must be a non-empty array of tables ([[frames]])")
    if scenes is None:
        scenes, errors = discover()
    else:
        errors = {}
    entries = [_entry(path, i, f, scenes, errors) for i, f in enumerate(frames)]
    seen: dict[str, int] = {}
    for i, e in enumerate(entries):
        if e.name in seen:
            _fail(path, f"frames[{i}] name", f"{e.name!r} is also the name of frames[{seen[e.name]}] (their frames "
                                             "would share a directory); give one a distinct name")
        seen[e.name] = i
    seeds = {s: {e.seed for e in entries if e.split == s} for s in SPLITS}
    for a, b in itertools.combinations(SPLITS, 2):
        shared = sorted(seeds[a] & seeds[b])
        if shared:
            i = next(i for i, e in enumerate(entries) if e.split == b and e.seed == shared[0])
            also = f"; also {', '.join(map(str, shared[1:]))}" if shared[1:] else ""
            _fail(path, f"frames[{i}] seed", f"seed {shared[0]} is used by both splits {a} and {b} (no two splits "
                                             f"may share a seed{also})")
    raw_conditions = check_value(raw.get("conditions", {}), dict, name="conditions", where=str(path))
    conditions = {k: _condition(path, k, v) for k, v in raw_conditions.items()}
    _check_directories(path, entries, conditions)
    for k, dist in conditions.items():
        _check_calibration(path, k, dist, entries)
    code_versions = {e.family: scenes[e.family].code_version for e in entries}
    return Suite(path=path, name=name, description=description, render=render, entries=tuple(entries),
                 code_versions=code_versions, id=suite_id(data, code_versions, render), conditions=conditions)

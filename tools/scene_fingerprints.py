"""Fingerprints of what each built-in scene family builds, stored beside the family's declared version.

A built-in family declares its scene code version (``SceneEntry.version``); frames (``scene.code_version``),
the frame identity ``tri360 render`` compares and suite ids record it.  It must change when, and only when, what
the family builds changes.  The fingerprints make that checkable: for every preset at seeds ``SEEDS``, a hash of a
canonical JSON of the built :class:`~scenes.model.SceneSpec` (parameters as recorded, materials, geometry, lights,
models, bounds, rig height, explicit viewpoints, background), and for the default preset at the first seed one of
its first ``VIEWPOINTS`` rig placements (:func:`~scenes.model.choose_viewpoints`, which depends only on the spec
and the seed: one case per family notices a change of the placement code, and placing rigs in the dense presets
takes half a minute).  ``tests/scenes/test_scene_fingerprints.py`` fails when a family builds
something else while its version stayed the same, when its version changed but the fingerprints were not
rewritten, and when a family has no fingerprints or fingerprints name no family.

Floats are rounded to ``DIGITS`` significant digits (and magnitudes below ``TINY`` to 0) before hashing, and ints
count as floats (``0`` and ``0.0`` place a box alike): numpy's SIMD maths differs in the last bits between CPUs,
which must not change a fingerprint.

    python -m tools.scene_fingerprints            # check; exit 1 with one line per problem
    python -m tools.scene_fingerprints --update   # rewrite the file (refused for a family whose scenes
                                                         # changed while its version did not)
    python -m tools.scene_fingerprints --update --force   # rewrite anyway: only when the fingerprint
                                                         # recipe itself changed, not the scenes
"""

from __future__ import annotations

from harness.runtime import startup

if __name__ == "__main__":  # run as a script: Ctrl-C during the imports below is one line and 130
    startup.guard("scene_fingerprints")

import dataclasses
import hashlib
import json
import math
import sys
from collections.abc import Mapping
from pathlib import Path

import numpy as np

from harness.data.atomic import atomic_write_text
from scenes.model import SceneEntry, SceneSpec, choose_viewpoints
from scenes.registry import discover
from tools.common import ArgumentParser, read_json_file, user_error

FILE = Path(__file__).resolve().parents[1] / "tests" / "scenes" / "scene_fingerprints.json"
"""The repository's fingerprints (``--file`` picks another)."""
UPDATE_COMMAND = "python -m tools.scene_fingerprints --update"
FORMAT = 1
SEEDS = (0, 1, 7)
VIEWPOINTS = 3
DIGITS = 9
TINY = 1e-9
BUILTIN_SOURCE = "scenes/families/"
"""``SceneEntry.source`` prefix of the built-in families (the ones fingerprinted)."""


def _number(x: float) -> float | str:
    x = float(x)
    if not math.isfinite(x):
        return repr(x)
    if abs(x) < TINY:
        return 0.0
    return float(f"{x:.{DIGITS}g}")


def canonical(obj):
    """A JSON-able form of a spec part, stable across CPUs: dataclasses by type name and field, paths and other
    objects as strings, numbers (ints included, bools not) rounded by :func:`_number`."""
    if dataclasses.is_dataclass(obj) and not isinstance(obj, type):
        return {"type": type(obj).__name__,
                **{f.name: canonical(getattr(obj, f.name)) for f in dataclasses.fields(obj)}}
    if isinstance(obj, Mapping):
        return {str(k): canonical(v) for k, v in obj.items()}
    if isinstance(obj, list | tuple):
        return [canonical(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return canonical(obj.tolist())
    if obj is None or isinstance(obj, str | bool | np.bool_):
        return obj if not isinstance(obj, np.bool_) else bool(obj)
    if isinstance(obj, int | float | np.integer | np.floating):
        return _number(obj)
    return str(obj)


def _hash(data) -> str:
    blob = json.dumps(data, sort_keys=True, separators=(",", ":"))
    return "sha256:" + hashlib.sha256(blob.encode("utf-8")).hexdigest()[:16]


def scene_fingerprint(spec: SceneSpec) -> str:
    """``"sha256:<16 hex>"`` of the canonical JSON of a built spec (without its ``code_version``)."""
    return _hash({f.name: canonical(getattr(spec, f.name)) for f in dataclasses.fields(spec)
                  if f.name != "code_version"})


def rigs_fingerprint(spec: SceneSpec, seed: int) -> str:
    """``"sha256:<16 hex>"`` of the canonical JSON of the spec's first ``VIEWPOINTS`` rig placements."""
    return _hash(canonical([{"position": r.position, "yaw_rad": r.yaw_rad, "baseline_m": r.baseline_m,
                             "pitch_rad": r.pitch_rad, "roll_rad": r.roll_rad}
                            for r in choose_viewpoints(spec, VIEWPOINTS, seed)]))


def builtin_families() -> dict[str, SceneEntry]:
    """The built-in scene families (``scenes/families/*.py``) by name; an outside (plugin) family is left out."""
    entries, errors = discover()
    broken = {k: v for k, v in errors.items() if k.startswith(BUILTIN_SOURCE)}
    if broken:
        raise RuntimeError(f"scene files fail to load: {broken}")
    return {n: e for n, e in sorted(entries.items()) if e.source.startswith(BUILTIN_SOURCE)}


def family_record(entry: SceneEntry) -> dict:
    """``{"version", "scenes": {"<preset>@<seed>": fingerprint}, "rigs": {"<default preset>@<first seed>":
    fingerprint}}`` of one family now."""
    scenes = {}
    for preset in sorted(entry.presets):
        for seed in SEEDS:
            spec = entry.build_spec(preset, seed)
            scenes[f"{preset}@{seed}"] = scene_fingerprint(spec)
            if preset == entry.default_preset and seed == SEEDS[0]:
                rigs = {f"{preset}@{seed}": rigs_fingerprint(spec, seed)}
    return {"version": entry.version, "scenes": scenes, "rigs": rigs}


def compute(families: Mapping[str, SceneEntry] | None = None) -> dict[str, dict]:
    """Family name -> :func:`family_record`, of ``families`` (default: the built-in ones)."""
    families = builtin_families() if families is None else families
    return {name: family_record(entry) for name, entry in sorted(families.items())}


def _read(path: Path) -> dict:
    """A fingerprint file's JSON, of any recipe.

    Raises:
        FileNotFoundError: ``path`` is missing.
        ValueError: one line naming ``path``: a directory, not JSON, or not a fingerprint file.
    """
    data = read_json_file(path, "fingerprint file", f"no fingerprint file (write it with `{UPDATE_COMMAND}`)")
    if "format" not in data or not isinstance(data.get("families"), dict):
        raise ValueError(f"{path}: not a fingerprint file (no \"format\" and \"families\")")
    return data


def load(path: Path = FILE) -> dict[str, dict]:
    """The stored family records of a fingerprint file."""
    data = _read(path)
    if data.get("format") != FORMAT or data.get("seeds") != list(SEEDS) or data.get("viewpoints") != VIEWPOINTS:
        raise ValueError(f"{path}: written by another fingerprint recipe (format/seeds/viewpoints); rewrite it: "
                         f"{UPDATE_COMMAND} --force")
    return data["families"]


def unchanged_version_problem(name: str, entry: SceneEntry, stored: dict, now: dict) -> str | None:
    """The one-line message for a family that builds other scenes than ``stored`` records under the same
    version, else None."""
    if stored.get("version") != now["version"]:
        return None
    changed = [f"{prefix}{k}" for part, prefix in (("scenes", ""), ("rigs", "rig placements of "))
               for k in sorted(set(stored.get(part, {})) | set(now[part]))
               if stored.get(part, {}).get(k) != now[part].get(k)]
    if not changed:
        return None
    where = entry.source or f"the SceneEntry of {name!r}"
    hint = f" (e.g. its source hash {entry.source_version!r})" if entry.source_version != now["version"] else ""
    return (f"scene family {name!r} builds different scenes than its fingerprints record ({', '.join(changed[:4])}"
            f"{', ...' if len(changed) > 4 else ''}) but its version is still {now['version']!r}: change its version "
            f"(SceneEntry(version=...) in {where}){hint}, so that frames and suite data rendered with the old version "
            f"are refused, as they should be; then rewrite the fingerprints: {UPDATE_COMMAND}")


def check(stored: Mapping[str, dict], families: Mapping[str, SceneEntry],
          now: Mapping[str, dict] | None = None) -> list[str]:
    """Every problem, one line each: a family without a declared version, without fingerprints, building other
    scenes under the same version, or declaring another version than its fingerprints record; fingerprints of a
    name that is no family."""
    now = compute(families) if now is None else now
    problems = []
    for name, entry in sorted(families.items()):
        if not entry.version:
            problems.append(f"built-in scene family {name!r} declares no version: add SceneEntry(version=...) in "
                            f"{entry.source} (scenes/README.md), then rewrite the fingerprints: {UPDATE_COMMAND}")
        elif name not in stored:
            problems.append(f"scene family {name!r} has no fingerprints in {FILE.name}: record them: {UPDATE_COMMAND}")
        elif (msg := unchanged_version_problem(name, entry, stored[name], now[name])) is not None:
            problems.append(msg)
        elif stored[name] != now[name]:
            problems.append(f"scene family {name!r} declares version {entry.version!r}, its fingerprints record "
                            f"{stored[name].get('version')!r}: rewrite the fingerprints: {UPDATE_COMMAND}")
    for name in sorted(set(stored) - set(families)):
        problems.append(f"{FILE.name} has fingerprints of {name!r}, which is no built-in scene family: remove them: "
                        f"{UPDATE_COMMAND}")
    return problems


def update(path: Path, families: Mapping[str, SceneEntry], force: bool = False) -> list[str]:
    """Rewrite the fingerprint file from ``families``; without ``force``, refuse (returning the problems, writing
    nothing) when a family builds other scenes under the version its fingerprints record.

    Raises:
        ValueError: ``path`` exists and is not a fingerprint file (of any recipe), or its folder does not exist.
    """
    path = Path(path)
    if path.exists() or path.is_symlink():
        _read(path)  # only a fingerprint file is ever replaced
    elif not path.parent.is_dir():
        raise ValueError(f"{path}: its folder does not exist")
    now = compute(families)
    if not force and path.is_file():
        stored = load(path)
        refused = [msg for name, entry in families.items() if name in stored
                   if (msg := unchanged_version_problem(name, entry, stored[name], now[name])) is not None]
        if refused:
            return refused
    data = {"format": FORMAT, "about": f"what each built-in scene family builds, beside its version; rewritten by "
                                      f"`{UPDATE_COMMAND}` (tools/scene_fingerprints.py)",
            "seeds": list(SEEDS), "viewpoints": VIEWPOINTS, "families": now}
    atomic_write_text(Path(path), json.dumps(data, indent=1) + "\n")
    return []


def main(argv: list[str] | None = None) -> int:
    parser = ArgumentParser(prog="python -m tools.scene_fingerprints",
                            description=__doc__.split("\n\n")[0])
    parser.add_argument("--file", type=Path, default=FILE, help="the fingerprint file (default: %(default)s)")
    parser.add_argument("--update", action="store_true", help="rewrite the file from the scenes as they build now")
    parser.add_argument("--force", action="store_true",
                        help="with --update: also for a family whose scenes changed while its version did not (only "
                             "when the fingerprint recipe changed, never to let changed scenes keep their version)")
    args = parser.parse_args(argv)
    families = builtin_families()
    try:
        if args.update:
            problems = update(args.file, families, force=args.force)
            if not problems:
                print(f"wrote {args.file} ({len(families)} families)")
        else:
            problems = check(load(args.file), families)
    except (OSError, ValueError) as exc:
        return user_error("python -m tools.scene_fingerprints", exc)
    for line in problems:
        print(line, file=sys.stderr)
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(startup.run_main(main, "scene_fingerprints"))

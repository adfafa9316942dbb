"""Scene registry.

A scene family is one Python file in ``scenes/families/`` that defines ``SCENES``: a list of
:class:`scenes.model.SceneEntry` (re-exported here).
Files are found automatically; outside packages register through the entry-point group
``tri360.scenes`` (each entry point loads to a ``SceneEntry`` or a list of them).  See ``scenes/README.md``.

Scene names may carry a preset: ``classroom:large`` is the family ``classroom`` with its preset ``large``.
"""

from __future__ import annotations

import importlib
import pkgutil

import scenes.families
from reconstruction.plugins import Registry, collect_registry, load_entry_points, shadow_message, unknown_name_message
from scenes.model import RENDERERS, RESERVED_PARAMETERS, SceneEntry, SceneError

__all__ = ["ENTRY_POINT_GROUP", "RENDERERS", "RESERVED_PARAMETERS", "SceneEntry", "SceneError", "discover",
           "get_scene", "scene_registry"]

ENTRY_POINT_GROUP = "tri360.scenes"


def _collect(obj, source: str) -> list[SceneEntry]:
    items = obj if isinstance(obj, list | tuple) else [obj]
    out = []
    for item in items:
        if not isinstance(item, SceneEntry):
            raise SceneError(f"{source}: expected SceneEntry objects, got {type(item).__name__}")
        out.append(SceneEntry(**{**item.__dict__, "source": item.source or source}))
    return out


def scene_registry() -> Registry:
    """The scene files of this package, then the entry points; an outside scene whose name is taken is refused."""
    entries: dict[str, SceneEntry] = {}
    errors: dict[str, str] = {}
    for info in sorted(pkgutil.iter_modules(scenes.families.__path__), key=lambda i: i.name):
        if info.name.startswith("_"):
            continue
        modname = f"{scenes.families.__name__}.{info.name}"
        source = f"scenes/families/{info.name}.py"
        try:
            module = importlib.import_module(modname)
            found = _collect(getattr(module, "SCENES", []), source)
        except Exception as exc:
            errors[source] = f"{type(exc).__name__}: {exc}"
            continue
        for entry in found:
            entries[entry.name] = entry
    found, ep_errors = load_entry_points(ENTRY_POINT_GROUP, lambda e: isinstance(e, SceneEntry), "SceneEntry")
    return collect_registry(entries.values(), ENTRY_POINT_GROUP, lambda e: isinstance(e, SceneEntry), "scene",
                            key=lambda e: e.name, found=[(src, _collect(e, src)[0]) for src, e in found],
                            errors={**errors, **ep_errors})


def discover() -> tuple[dict[str, SceneEntry], dict[str, str]]:
    """Find every scene: files in this package, then entry points.

    Returns:
        ``(entries by name, errors by source)``; a file that raises on import is reported in ``errors``
        rather than hiding the other scenes, and so is an outside scene whose name a built-in (or an earlier
        plugin's) scene has: it is refused, never replacing the other.
    """
    reg = scene_registry()
    return reg.entries, reg.errors


def get_scene(name: str) -> tuple[SceneEntry, str]:
    """Resolve ``"family"`` or ``"family:preset"`` -> (entry, preset name).

    Raises:
        SceneError: naming the unknown scene and listing the known ones (and any scene file that failed), or a
            name that a refused outside scene also has (naming its plugin).
    """
    family, _, preset = name.partition(":")
    reg = scene_registry()
    entries, errors = reg.entries, reg.errors
    if family in reg.refused:
        raise SceneError(shadow_message("scene", family, reg))
    if family not in entries:
        raise SceneError(unknown_name_message("scene", family, sorted(entries), errors, "scene files"))
    entry = entries[family]
    preset = preset or entry.default_preset
    if preset not in entry.presets:
        raise SceneError(f"scene {family!r}: unknown preset {preset!r} (known: {', '.join(sorted(entry.presets))})")
    return entry, preset

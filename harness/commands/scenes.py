"""``tri360 scenes``: the registered scenes as text: their presets, default renderer, description and (on request)
parameters: each parameter's line (description, unit, default, allowed values: from the family's parameters
dataclass, ``SceneEntry.describe_parameters``) and each preset's overrides."""

from __future__ import annotations

from harness.commands.parts.plugins import unusable
from scenes.registry import scene_registry

__all__ = ["scene_listing"]


def scene_listing(params: bool = False) -> tuple[list[str], list[str]]:
    """The lines ``tri360 scenes`` prints (with ``params``: every scene's parameters and every preset's values),
    and its warnings, one line each: every scene plugin that failed to load and every outside scene that cannot be
    selected (:func:`harness.commands.parts.plugins.unusable`), none of which is listed."""
    reg = scene_registry()
    bad, warnings = unusable("scene", reg)
    entries = {k: v for k, v in reg.entries.items() if k not in bad}
    out = []
    for name in sorted(entries):
        e = entries[name]
        presets = ", ".join(f"{p}*" if p == e.default_preset else p for p in e.presets)
        out.append(f"{name:<16} [{e.renderer}] presets: {presets}")
        if e.description:
            out.append(f"{'':<16} {e.description}")
        if params:
            for key, meaning in sorted(e.describe_parameters().items()):
                out.append(f"{'':<16}   --set {key}=...: {meaning}")
            for p, values in e.presets.items():
                out.append(f"{'':<16}   {p}: {values}")
    if not entries:
        out.append("no scenes registered")
    out.append("(* = default preset; use --scene NAME:PRESET; [renderer] = the default of --renderer)")
    return out, warnings

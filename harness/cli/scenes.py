"""``tri360 scenes``: list the registered scenes, their presets, default renderer, parameters and description.

``--params`` adds each parameter's line (description, unit, default, allowed values: from the family's parameters
dataclass, ``SceneEntry.describe_parameters``) and each preset's overrides."""

from __future__ import annotations

import sys

from scenes.registry import discover

HELP = "list the registered scenes and their presets"


def add_arguments(parser) -> None:
    parser.add_argument("--params", action="store_true",
                        help="also print every scene's parameters (what --set accepts) and every preset's values")


def run(args) -> int:
    entries, errors = discover()
    for name in sorted(entries):
        e = entries[name]
        presets = ", ".join(f"{p}*" if p == e.default_preset else p for p in e.presets)
        print(f"{name:<16} [{e.renderer}] presets: {presets}")
        if e.description:
            print(f"{'':<16} {e.description}")
        if args.params:
            for key, meaning in sorted(e.describe_parameters().items()):
                print(f"{'':<16}   --set {key}=...: {meaning}")
            for p, params in e.presets.items():
                print(f"{'':<16}   {p}: {params}")
    if not entries:
        print("no scenes registered")
    print("(* = default preset; use --scene NAME:PRESET; [renderer] = the default of --renderer)")
    for source, msg in errors.items():
        print(f"warning: {source} failed to load: {msg}", file=sys.stderr)
    return 0

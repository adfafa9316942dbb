"""``tri360 scenes``: list the registered scenes, their presets, default renderer, parameters and description
(:func:`harness.commands.scenes.scene_listing`)."""

from __future__ import annotations

import sys

from harness.commands.scenes import scene_listing

HELP = "list the registered scenes and their presets"


def add_arguments(parser) -> None:
    parser.add_argument("--params", action="store_true",
                        help="also print every scene's parameters (what --set accepts) and every preset's values")


def run(args) -> int:
    lines, warnings = scene_listing(args.params)
    for line in lines:
        print(line)
    for line in warnings:
        print(line, file=sys.stderr)
    return 0

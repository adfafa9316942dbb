"""``tri360 methods``: list the methods ``--method`` accepts (:func:`harness.commands.methods.method_listing`)."""

from __future__ import annotations

import sys

from harness.commands.methods import method_listing

HELP = "list the methods: named ones (the default marked), the flow pipeline's flows and variants, plugins' methods"


def add_arguments(parser) -> None:
    parser.description = (HELP + ". Each line says what the method does and how it differs from the others; "
                          "choose with --method LABEL (tri360 reconstruct / evaluate).")


def run(args) -> int:
    lines, warnings = method_listing()
    print("\n".join(lines))
    for line in warnings:
        print(line, file=sys.stderr)
    return 0

"""``tri360 methods``: list the methods ``--method`` accepts (:func:`harness.commands.methods.method_listing`), or
print one's whole configuration (``--show LABEL``, :func:`harness.commands.methods.method_config_text`)."""

from __future__ import annotations

import sys

from harness.commands.methods import method_config_text, method_listing

HELP = ("list the methods: named ones (the default marked), the flow pipeline's flows and variants, plugins' methods; "
        "or print one's whole configuration (--show LABEL)")


def add_arguments(parser) -> None:
    parser.description = (HELP + ". Each line says what the method does and how it differs from the others; "
                          "choose with --method LABEL (tri360 reconstruct / evaluate).")
    parser.add_argument("--show", default=None, metavar="LABEL",
                        help="instead of the list: print the method's whole configuration as JSON, every parameter "
                             "that changes its result (DeepFlow's and DeepMatching's included), the same that "
                             "config.json of a results set records for it")


def run(args) -> int:
    if args.show is not None:
        sys.stdout.write(method_config_text(args.show))
        return 0
    lines, warnings = method_listing()
    print("\n".join(lines))
    for line in warnings:
        print(line, file=sys.stderr)
    return 0

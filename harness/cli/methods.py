"""Method selection options shared by ``reconstruct`` (one method) and ``evaluate`` (several)."""

from __future__ import annotations

import argparse
from pathlib import Path

from harness.data.errors import UserError
from reconstruction.flow.backends import available_flows
from reconstruction.methods.base import Method
from reconstruction.methods.flow_pipeline import DEFAULT_FLOW, available_variants
from reconstruction.methods.registry import DEFAULT_METHOD, default_methods, flow_methods, get_methods

__all__ = ["add_method_options", "add_results_options", "selected_methods"]


def add_method_options(parser: argparse.ArgumentParser, multiple: bool) -> None:
    """``--method``, and the flow-pipeline shorthands ``--flow``, ``--rectify/--no-rectify``, ``--variant(s)``."""
    flows = ", ".join(available_flows())
    variants = ", ".join(available_variants())
    if multiple:
        parser.add_argument("--method", nargs="+", default=None, metavar="LABEL",
                            help="methods by label, e.g. dis-rect:gradient deepflow-plain:average, or outside methods' "
                                 "labels (default: tri360's flow pipeline and the paper's set-up, every variant)")
        parser.add_argument("--flow", nargs="+", default=None, metavar="NAME",
                            help=f"instead of --method: flow-pipeline methods with these flows ({flows})")
        parser.add_argument("--variants", nargs="+", default=None, metavar="NAME",
                            help=f"with --flow: these variants (default: all of {variants})")
    else:
        parser.add_argument("--method", default=None, metavar="LABEL",
                            help=f"the method, by label (default: {DEFAULT_METHOD})")
        parser.add_argument("--flow", default=None, metavar="NAME",
                            help=f"instead of --method: the flow pipeline with this flow ({flows}; default "
                                 f"{DEFAULT_FLOW})")
        parser.add_argument("--variant", default=None, metavar="NAME",
                            help=f"with --flow: the variant ({variants}; default gradient)")
    parser.add_argument("--rectify", action=argparse.BooleanOptionalAction, default=None,
                        help="with --flow: flow on rectified pairs (baseline = polar axis; the default) or, with "
                             "--no-rectify, on the plain equirect images as the paper does")


def add_results_options(parser: argparse.ArgumentParser, what: str) -> None:
    """``--out``, ``--scene``, ``--report/--no-report`` and ``--quiet``, shared by ``evaluate`` and ``score``."""
    parser.add_argument("--out", type=Path, default=Path("results"),
                        help="results directory, replaced as a whole: it must be absent, empty or a results set "
                             "tri360 wrote (holding nothing else); never the data root, a frame or predictions "
                             "root, inside one or a parent of one")
    parser.add_argument("--scene", nargs="+", default=None, metavar="NAME", help=f"{what} only these scenes")
    parser.add_argument("--report", action=argparse.BooleanOptionalAction, default=True,
                        help="write the report with the results (--no-report: results only)")
    parser.add_argument("--quiet", action="store_true", help="no progress bar")


def selected_methods(args, multiple: bool) -> list[Method]:
    """The methods the options select (exactly one when ``multiple`` is False).

    Raises:
        UserError: an unknown method label, flow or variant name, or --method mixed with the shorthands.
    """
    variants = getattr(args, "variants", None) if multiple else (
        [args.variant] if getattr(args, "variant", None) else None)
    shorthand = args.flow is not None or args.rectify is not None or variants is not None
    try:
        if args.method:
            if shorthand:
                raise UserError("--method selects methods by label; do not combine it with --flow, --rectify or "
                                f"--variant{'s' if multiple else ''}")
            return get_methods(args.method if multiple else [args.method])
        if not shorthand:
            return default_methods() if multiple else get_methods([DEFAULT_METHOD])
        flows = (args.flow if multiple else [args.flow]) if args.flow is not None else [DEFAULT_FLOW]
        rectify = [True if args.rectify is None else args.rectify]
        if not multiple and variants is None:
            variants = ["gradient"]
        return flow_methods(flows, rectify, variants)
    except ValueError as exc:
        raise UserError(str(exc)) from None

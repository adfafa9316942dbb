"""Method selection options shared by ``reconstruct`` (one method) and ``evaluate`` (several)."""

from __future__ import annotations

import argparse
from pathlib import Path

from harness.runtime.options import MethodSelection
from reconstruction.flow.backends import available_flows
from reconstruction.methods.base import Method
from reconstruction.methods.flow_pipeline import DEFAULT_FLOW, FlowMethod, available_variants, config_label
from reconstruction.methods.registry import DEFAULT_CONFIGS, DEFAULT_METHOD, DEFAULT_VARIANTS, evaluate_default_methods

__all__ = ["add_method_options", "add_results_options", "selected_methods"]


def add_method_options(parser: argparse.ArgumentParser, multiple: bool) -> None:
    """``--method``, and the flow-pipeline shorthands ``--flow``, ``--rectify/--no-rectify``, ``--variant(s)``."""
    flows = ", ".join(available_flows())
    variants = ", ".join(available_variants())
    if multiple:
        named = [m.label for m in evaluate_default_methods() if not isinstance(m, FlowMethod)]
        configs = ", ".join(f"{config_label(f, r)}:*" for f, r in DEFAULT_CONFIGS)
        parser.add_argument("--method", nargs="+", action="extend", default=None, metavar="LABEL",
                            help="methods by label, e.g. fused-mirror dis-rect:gradient deepflow-rect:average, or "
                                 f"plugins' labels; 'tri360 methods' lists them (default: {', '.join(named)}, then "
                                 f"{configs}: tri360's flow pipeline and the paper's set-up, each with the variants "
                                 f"{', '.join(DEFAULT_VARIANTS)})")
        parser.add_argument("--flow", nargs="+", action="extend", default=None, metavar="NAME",
                            help=f"instead of --method: flow-pipeline methods with these flows ({flows})")
        parser.add_argument("--variants", nargs="+", action="extend", default=None, metavar="NAME",
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
                             "--no-rectify, on the plain equirect images (an ablation)")


def add_results_options(parser: argparse.ArgumentParser, what: str) -> None:
    """``--out``, ``--scene``, ``--report/--no-report`` and ``--quiet``, shared by ``evaluate`` and ``score``."""
    parser.add_argument("--out", type=Path, default=Path("results"),
                        help="results directory, replaced as a whole: it must be absent, empty or a results set "
                             "tri360 wrote (holding nothing else); never the data root, a frame or predictions "
                             "root, inside one or a parent of one")
    parser.add_argument("--scene", nargs="+", action="extend", default=None, metavar="NAME",
                        help=f"{what} only these scenes")
    parser.add_argument("--report", action=argparse.BooleanOptionalAction, default=True,
                        help="write the report with the results (--no-report: results only)")
    parser.add_argument("--quiet", action="store_true", help="no progress bar")


def selected_methods(args, multiple: bool) -> list[Method]:
    """The methods the options select (exactly one when ``multiple`` is False): :class:`MethodSelection`.

    Raises:
        UserError: an unknown method label, flow or variant name, or --method mixed with the shorthands.
    """
    variants = getattr(args, "variants", None) if multiple else (
        [args.variant] if getattr(args, "variant", None) else None)

    def as_tuple(v):
        return None if v is None else tuple([v] if isinstance(v, str) else v)

    selection = MethodSelection(method=as_tuple(args.method), flow=as_tuple(args.flow), variants=as_tuple(variants),
                                rectify=args.rectify)
    plural = "s" if multiple else ""
    return selection.methods(single=not multiple,
                             spell=lambda n: f"--variant{plural}" if n == "variants" else f"--{n}")

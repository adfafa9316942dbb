"""``tri360 methods``: the methods ``--method`` accepts, as text: the named ones (the default marked), the default's
ablations, the flows and
variants that the flow pipeline's labels combine, what ``evaluate`` runs by default, and plugins' methods; with
``--show LABEL``, one method's whole configuration (:func:`method_config_text`).

Only what can be selected is listed.  Every plugin that failed to load, every outside method, flow or variant that
its registry refused (a name a built-in or an earlier plugin has, or no string name: each refused name of an entry
point, :attr:`reconstruction.plugins.Registry.refusals`) and every accepted one whose name cannot become a path
component (:func:`harness.data.names.check_name`: ``evaluate`` and ``reconstruct`` refuse it) is a warning line of
its own instead.
"""

from __future__ import annotations

from harness.commands.evaluate import method_configs
from harness.commands.parts.plugins import unusable
from harness.data import jsonio
from harness.data.errors import UserError
from reconstruction.flow.backends import ORACLE, flow_registry
from reconstruction.methods.base import Method
from reconstruction.methods.flow_pipeline import DEFAULT_FLOW, FlowMethod, config_label
from reconstruction.methods.registry import (
    ABLATIONS,
    DEFAULT_CONFIGS,
    DEFAULT_METHOD,
    DEFAULT_VARIANTS,
    ENTRY_POINT_GROUP,
    PAPER_CONFIG,
    PRESETS,
    builtin_methods,
    get_methods,
)
from reconstruction.plugins import collect_registry
from reconstruction.refine.lm import variant_registry

__all__ = ["AVERAGE", "ORACLE_TEXT", "method_listing", "method_config_text"]

#: what ``average`` is (it is no refinement variant, so it has no registry entry of its own)
AVERAGE = "no refinement: the mean of the two pairs' triangulated distances (the paper's \"before optimisation\")"
#: what the ``oracle`` flow is (not an image backend)
ORACLE_TEXT = "exact correspondences from C's true distance (needs ground truth: an upper bound, not a method)"


def _rows(pairs: list[tuple[str, str]], indent: str = "  ") -> list[str]:
    width = max((len(a) for a, _ in pairs), default=0)
    return [f"{indent}{a:<{width}}  {b}".rstrip() for a, b in pairs]


def method_listing() -> tuple[list[str], list[str]]:
    """The lines ``tri360 methods`` prints, and its warnings, one line each: every plugin that failed to load and
    every outside method, flow or variant that cannot be selected (module doc), none of which is listed."""
    reg = collect_registry(builtin_methods(), ENTRY_POINT_GROUP, lambda m: isinstance(m, Method), "Method",
                           key=lambda m: m.label)
    flow_reg, variant_reg = flow_registry(), variant_registry()
    bad_methods, warnings = unusable("method", reg)
    bad_flows, flow_warnings = unusable("flow", flow_reg)
    bad_variants, variant_warnings = unusable("variant", variant_reg)
    flows = {k: v for k, v in flow_reg.entries.items() if k not in bad_flows}
    variants = {k: v for k, v in variant_reg.entries.items() if k not in bad_variants}
    out = ["named methods (* = the default, what 'tri360 reconstruct' runs):"]
    out += _rows([(p.label + ("*" if p.label == DEFAULT_METHOD else ""), p.description) for p in PRESETS])
    out += ["", f"ablations ({DEFAULT_METHOD} with one part switched off, and the methods it grew from):"]
    out += _rows([(p.label, p.description) for p in ABLATIONS])
    out += ["", "the flow pipeline: FLOW-rect:VARIANT or FLOW-plain:VARIANT (e.g. dis-rect:gradient): flow C->U and "
            "C->R, triangulate each pair, then a variant",
            "  rect: flow on pairs rotated so that the baseline is the polar axis; plain: on the equirect images "
            "(an ablation)", "  flows:"]
    marks = {DEFAULT_FLOW: " (tri360's flow)", PAPER_CONFIG[0]: f" (the paper's set-up: {config_label(*PAPER_CONFIG)})"}
    out += _rows([(name, b.description + marks.get(name, "")) for name, b in sorted(flows.items())]
                 + [(ORACLE, ORACLE_TEXT)], indent="    ")
    out.append("  variants:")
    out += _rows([("average", AVERAGE), *((name, v.description) for name, v in variants.items())], indent="    ")
    configs = ", ".join(f"{config_label(f, r)}:{{{','.join(DEFAULT_VARIANTS)}}}" for f, r in DEFAULT_CONFIGS)
    named = [p.label for p in (*PRESETS, *ABLATIONS)]
    plugins = [(label, getattr(m, "description", "") or type(m).__name__) for label, m in sorted(reg.entries.items())
               if not isinstance(m, FlowMethod) and label not in named and label not in bad_methods]
    out += ["", f"'tri360 evaluate' runs by default: {DEFAULT_METHOD}, sweep, {configs}"]
    out += ["", "plugins' methods (entry points of tri360.methods):" if plugins else "plugins' methods: none"]
    out += _rows(plugins)
    return out, [*warnings, *flow_warnings, *variant_warnings]


def method_config_text(label: str) -> str:
    """The whole configuration of the method ``label`` as JSON text: what ``config.json`` records for it
    (:func:`harness.commands.evaluate.method_configs`), every parameter that changes its result.

    Raises:
        UserError: an unknown label (one line naming the known ones, :func:`reconstruction.methods.registry.
            get_methods`).
    """
    try:
        method = get_methods([label])[0]
    except ValueError as exc:
        raise UserError(str(exc)) from None
    return jsonio.dumps(method_configs([method])[method.label])

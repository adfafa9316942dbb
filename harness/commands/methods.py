"""``tri360 methods``: the methods ``--method`` accepts, as text: the named ones (the default marked), the flows and
variants that the flow pipeline's labels combine, what ``evaluate`` runs by default, and plugins' methods.

Only what can be selected is listed.  Every plugin that failed to load, every outside method, flow or variant that
its registry refused (a name a built-in or an earlier plugin has, or no string name: each refused name of an entry
point, :attr:`reconstruction.plugins.Registry.refusals`) and every accepted one whose name cannot become a path
component (:func:`harness.data.names.check_name`: ``evaluate`` and ``reconstruct`` refuse it) is a warning line of
its own instead.
"""

from __future__ import annotations

from harness.data.errors import UserError
from harness.data.names import check_name
from reconstruction.flow.backends import ORACLE, flow_registry
from reconstruction.methods.base import Method
from reconstruction.methods.flow_pipeline import DEFAULT_FLOW, FlowMethod, config_label
from reconstruction.methods.registry import (
    DEFAULT_CONFIGS,
    DEFAULT_METHOD,
    DEFAULT_VARIANTS,
    ENTRY_POINT_GROUP,
    PAPER_CONFIG,
    PRESETS,
    builtin_methods,
)
from reconstruction.plugins import Registry, collect_registry
from reconstruction.refine.lm import variant_registry

__all__ = ["AVERAGE", "ORACLE_TEXT", "method_listing"]

#: what ``average`` is (it is no refinement variant, so it has no registry entry of its own)
AVERAGE = "no refinement: the mean of the two pairs' triangulated distances (the paper's \"before optimisation\")"
#: what the ``oracle`` flow is (not an image backend)
ORACLE_TEXT = "exact correspondences from C's true distance (needs ground truth: an upper bound, not a method)"


def _rows(pairs: list[tuple[str, str]], indent: str = "  ") -> list[str]:
    width = max((len(a) for a, _ in pairs), default=0)
    return [f"{indent}{a:<{width}}  {b}".rstrip() for a, b in pairs]


def _unusable(what: str, reg: Registry) -> tuple[set[str], list[str]]:
    """The accepted outside names of ``reg`` that cannot be selected, and one warning line for each of them, each
    refused name and each plugin that failed to load (``what``: ``method``, ``flow``, ``variant``)."""
    lines, refused_sources = [], set()
    for name, source, why in reg.refusals:
        refused_sources.add(source)
        lines.append(f"warning: {what} {name!r} of {source} cannot be selected: {why}")
    lines += [f"warning: {source} failed to load: {msg}" for source, msg in reg.errors.items()
              if source not in refused_sources]
    bad = set()
    for name, source in reg.sources.items():
        try:
            check_name(name, f"{what} {name!r} of {source} cannot be selected")
        except UserError as exc:
            bad.add(name)
            lines.append(f"warning: {exc}")
    return bad, lines


def method_listing() -> tuple[list[str], list[str]]:
    """The lines ``tri360 methods`` prints, and its warnings, one line each: every plugin that failed to load and
    every outside method, flow or variant that cannot be selected (module doc), none of which is listed."""
    reg = collect_registry(builtin_methods(), ENTRY_POINT_GROUP, lambda m: isinstance(m, Method), "Method",
                           key=lambda m: m.label)
    flow_reg, variant_reg = flow_registry(), variant_registry()
    bad_methods, warnings = _unusable("method", reg)
    bad_flows, flow_warnings = _unusable("flow", flow_reg)
    bad_variants, variant_warnings = _unusable("variant", variant_reg)
    flows = {k: v for k, v in flow_reg.entries.items() if k not in bad_flows}
    variants = {k: v for k, v in variant_reg.entries.items() if k not in bad_variants}
    out = ["named methods (* = the default, what 'tri360 reconstruct' runs):"]
    out += _rows([(p.label + ("*" if p.label == DEFAULT_METHOD else ""), p.description) for p in PRESETS])
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
    named = [p.label for p in PRESETS]
    plugins = [(label, getattr(m, "description", "") or type(m).__name__) for label, m in sorted(reg.entries.items())
               if not isinstance(m, FlowMethod) and label not in named and label not in bad_methods]
    out += ["", f"'tri360 evaluate' runs by default: {DEFAULT_METHOD}, sweep, {configs}"]
    out += ["", "plugins' methods (entry points of tri360.methods):" if plugins else "plugins' methods: none"]
    out += _rows(plugins)
    return out, [*warnings, *flow_warnings, *variant_warnings]

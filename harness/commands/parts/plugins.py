"""What the listing commands (``methods``, ``scenes``) say about plugins: one warning line for every plugin that failed
to load, every outside entry its registry refused (:attr:`reconstruction.plugins.Registry.refusals`: each refused
name of an entry point) and every accepted one whose name cannot become a path component
(:func:`harness.data.names.check_name`); none of those is listed."""

from __future__ import annotations

from harness.data.errors import UserError
from harness.data.names import check_name
from reconstruction.plugins import Registry

__all__ = ["unusable"]


def unusable(what: str, reg: Registry) -> tuple[set[str], list[str]]:
    """The accepted outside names of ``reg`` that cannot be selected, and one warning line for each of them, each
    refused name and each plugin that failed to load (``what``: ``method``, ``flow``, ``variant``, ``scene``)."""
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

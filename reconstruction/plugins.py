"""Entry-point discovery shared by every tri360 registry (scenes, flows, refinement variants, methods).

A registry is never filled at import time: each ``discover_*`` function builds it anew from the built-in
entries plus what outside packages declare in their ``pyproject.toml``::

    [project.entry-points."tri360.methods"]
    my_method = "my_package.tri360_plugin:METHODS"   # an object, a list of objects, or a callable returning them

A plugin that fails to load never hides the others: its error is returned next to the entries, keyed by
its source, so that commands can warn about it and unknown-name errors can mention it.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
from importlib.metadata import entry_points
from typing import Any

__all__ = ["load_entry_points", "merge_registry", "unknown_name_message"]


def _items(obj: Any) -> list:
    if callable(obj) and not isinstance(obj, type) and not hasattr(obj, "__dataclass_fields__"):
        obj = obj()
    return list(obj) if isinstance(obj, list | tuple) else [obj]


def load_entry_points(group: str, accept: Callable[[Any], bool],
                      what: str) -> tuple[list[tuple[str, Any]], dict[str, str]]:
    """Load every entry point of ``group``.

    Args:
        group: entry-point group, e.g. ``"tri360.flows"``.
        accept: ``accept(item) -> bool``, whether a loaded object is of the registry's kind.
        what: the kind's name for error messages (e.g. ``"FlowBackend"``).
    Returns:
        ``([(source, item), ...], {source: error message})``.
    """
    found, errors = [], {}
    for ep in entry_points(group=group):
        source = f"entry point {ep.name} ({ep.value})"
        try:
            items = _items(ep.load())
            bad = [type(i).__name__ for i in items if not accept(i)]
            if bad:
                raise TypeError(f"expected {what} objects, got {', '.join(bad)}")
        except Exception as exc:  # a broken plugin is reported, never fatal for the others
            errors[source] = f"{type(exc).__name__}: {exc}"
            continue
        found.extend((source, i) for i in items)
    return found, errors


def merge_registry(builtins: Iterable[Any], group: str, accept: Callable[[Any], bool], what: str,
                   key: Callable[[Any], str]) -> tuple[dict[str, Any], dict[str, str]]:
    """Built-in entries plus those of ``group``'s entry points, by ``key(entry)``; later ones win.

    Returns:
        ``(entries by key, errors by source)``.
    """
    out = {key(b): b for b in builtins}
    found, errors = load_entry_points(group, accept, what)
    for _source, item in found:
        out[key(item)] = item
    return out, errors


def unknown_name_message(what: str, name: str, known, errors: dict[str, str], failed: str = "plugins") -> str:
    """One line for an unknown registry name: ``unknown <what> '<name>' (known: ...)``, plus the plugins that
    failed to load (one of them may have been meant)."""
    msg = f"unknown {what} {name!r} (known: {', '.join(known) or 'none'})"
    if errors:
        msg += f"; {failed} that failed to load: " + "; ".join(f"{k}: {v}" for k, v in errors.items())
    return msg

"""Entry-point discovery shared by every tri360 registry (scenes, flows, refinement variants, methods).

A registry is never filled at import time: each ``discover_*`` function builds it anew from the built-in
entries plus what outside packages declare in their ``pyproject.toml``::

    [project.entry-points."tri360.methods"]
    my_method = "my_package.tri360_plugin:METHODS"   # an object, a list of objects, or a callable returning them

A plugin that fails to load never hides the others: its error is returned next to the entries, keyed by
its source, so that commands can warn about it and unknown-name errors can mention it.  An outside entry never
replaces another: one whose name a built-in entry or an earlier plugin already holds is refused, reported the
same way (naming the plugin and who holds the name), and asking for that name is an error
(:func:`shadow_message`), never a silent choice between the two.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from importlib.metadata import entry_points
from typing import Any

__all__ = ["Registry", "load_entry_points", "collect_registry", "merge_registry", "unknown_name_message",
           "shadow_message"]


@dataclass
class Registry:
    """A registry's entries and where the outside ones come from.

    Attributes:
        entries: entries by name (the built-ins, then the accepted outside entries).
        errors: error message by plugin source: plugins that failed to load and outside entries refused because
            their name was taken or is not a string; one plugin's refusals are joined by ``"; "``, so every refused
            name is in its message.
        sources: plugin source (``entry point NAME (VALUE)``) of each accepted outside entry, by name.
        refused: by name, ``(plugin source, holder)`` of the first refused outside entry of that name; holder is
            ``"built in"`` or the source of the plugin that holds the name.
        refusals: every refused outside entry in the order met: ``(name, plugin source, why)``, ``why`` the
            refusal's message (as in ``errors``).
    """

    entries: dict[str, Any] = field(default_factory=dict)
    errors: dict[str, str] = field(default_factory=dict)
    sources: dict[str, str] = field(default_factory=dict)
    refused: dict[str, tuple[str, str]] = field(default_factory=dict)
    refusals: list[tuple[Any, str, str]] = field(default_factory=list)

    def refuse(self, name, source: str, why: str) -> None:
        """Record that ``source``'s entry ``name`` is refused because of ``why`` (added to ``source``'s error, after
        any earlier refusal of the same plugin)."""
        self.refusals.append((name, source, why))
        self.errors[source] = f"{self.errors[source]}; {why}" if source in self.errors else why


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


def collect_registry(builtins: Iterable[Any], group: str, accept: Callable[[Any], bool], what: str,
                     key: Callable[[Any], str], found: list[tuple[str, Any]] | None = None,
                     errors: dict[str, str] | None = None) -> Registry:
    """Built-in entries plus those of ``group``'s entry points, by ``key(entry)``.  An outside entry whose name is
    taken (by a built-in or by a plugin loaded before it), or is not a non-empty string, is refused: it stays out,
    and ``errors`` (and :attr:`Registry.refusals`) name it, every refused entry of a plugin in its one message.

    Args:
        found, errors: the loaded outside entries ``[(source, entry)]`` and load errors, when the caller loaded
            them (default: :func:`load_entry_points` of ``group``).
    """
    if found is None:
        found, errors = load_entry_points(group, accept, what)
    reg = Registry(errors=dict(errors or {}))
    for b in builtins:
        reg.entries[key(b)] = b
    for source, item in found:
        try:
            name = key(item)
        except Exception as exc:  # an outside object without the name attribute: reported, never fatal
            reg.refuse(None, source, f"refused: its {what} has no usable name ({type(exc).__name__}: {exc})")
            continue
        if not isinstance(name, str) or not name:
            reg.refuse(name, source, f"refused: it provides {what} named {name!r}, not a non-empty string")
            continue
        if name in reg.entries:
            holder = reg.sources.get(name, "built in")
            reg.refused.setdefault(name, (source, holder))
            taken = "the built-in one" if holder == "built in" else holder
            reg.refuse(name, source, f"refused: it provides {what} {name!r}, a name {taken} already has "
                                     "(an outside entry never replaces another; rename it)")
            continue
        reg.entries[name] = item
        reg.sources[name] = source
    return reg


def merge_registry(builtins: Iterable[Any], group: str, accept: Callable[[Any], bool], what: str,
                   key: Callable[[Any], str]) -> tuple[dict[str, Any], dict[str, str]]:
    """:func:`collect_registry` as ``(entries by key, errors by source)``: built-ins first, an outside entry with a
    name that is taken is refused (in the errors)."""
    reg = collect_registry(builtins, group, accept, what, key)
    return reg.entries, reg.errors


def shadow_message(what: str, name: str, reg: Registry) -> str:
    """One line for asking for a name that a refused plugin also provides (:attr:`Registry.refused`)."""
    source, holder = reg.refused[name]
    held = "a built-in one" if holder == "built in" else f"the one of {holder}"
    return (f"{what} {name!r}: {source} also provides one, refused because {held} has that name; rename the "
            f"outside {what} or uninstall its package")


def unknown_name_message(what: str, name: str, known, errors: dict[str, str], failed: str = "plugins") -> str:
    """One line for an unknown registry name: ``unknown <what> '<name>' (known: ...)``, plus the plugins that
    failed to load (one of them may have been meant)."""
    msg = f"unknown {what} {name!r} (known: {', '.join(known) or 'none'})"
    if errors:
        msg += f"; {failed} that failed to load: " + "; ".join(f"{k}: {v}" for k, v in errors.items())
    return msg

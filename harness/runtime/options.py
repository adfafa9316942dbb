"""Options shared by the command line and study files: typed values and method selection, each rule once.

- :func:`typed_value` checks a value from outside (a study file's TOML) against a type annotation -- of a
  :class:`harness.render.base.RenderSettings` field, a job's parameter or a :class:`MethodSelection` field -- so
  the types of every option are written once, where the option is defined.  Booleans must be booleans
  (``"false"`` is refused, never read as ``bool("false")``), integers integers (``128.0`` and ``"128"`` are
  refused), a float may be written as an integer.
- :class:`MethodSelection` turns ``--method`` / ``--flow`` / ``--variants`` / ``--rectify`` (or a study's
  ``[evaluate]`` keys of the same names) into methods.
"""

from __future__ import annotations

import math
import types
import typing
from collections.abc import Callable
from dataclasses import dataclass, fields

from harness.data.errors import UserError
from reconstruction.methods.base import Method
from reconstruction.methods.flow_pipeline import DEFAULT_FLOW
from reconstruction.methods.registry import DEFAULT_METHOD, evaluate_default_methods, flow_methods, get_methods

__all__ = ["typed_value", "type_name", "annotations_of", "MethodSelection"]


def annotations_of(obj) -> dict[str, object]:
    """The evaluated type annotations of a dataclass or function (``typing.get_type_hints``)."""
    return typing.get_type_hints(obj)


def _args(hint) -> tuple:
    return typing.get_args(hint)


def _is_union(hint) -> bool:
    return typing.get_origin(hint) in (typing.Union, types.UnionType)


def type_name(hint) -> str:
    """What a user must write for ``hint``: ``"an integer"``, ``"true or false"``, ``"a string or a list of
    strings"``..."""
    if _is_union(hint):
        return " or ".join(type_name(a) for a in _args(hint) if a is not type(None))
    if hint is bool:
        return "true or false"
    if hint is int:
        return "an integer"
    if hint is float:
        return "a number"
    if hint is str:
        return "a string"
    if typing.get_origin(hint) is tuple:
        return f"{type_name(_args(hint)[0])} or a non-empty list of them"
    if typing.get_origin(hint) is dict or hint is dict:
        return "a table"
    return str(hint)


def typed_value(value, hint, source: str):
    """``value`` checked against the annotation ``hint``; returns it (a float for an integer given where a
    number is asked for, a tuple for ``tuple[X, ...]``, which also takes a single X).

    Supported annotations: ``bool``, ``int``, ``float``, ``str``, ``tuple[X, ...]``, ``dict`` and unions of them
    with None (None itself is never accepted from outside: a study file has no null).

    Raises:
        UserError: ``"<source> must be <type>, got <value>"`` (one line).
    """
    def bad():
        shown = repr(value) if not isinstance(value, dict | list) else type(value).__name__
        return UserError(f"{source} must be {type_name(hint)}, got {shown}")

    if _is_union(hint):
        for option in (a for a in _args(hint) if a is not type(None)):
            try:
                return typed_value(value, option, source)
            except UserError:
                continue
        raise bad()
    if hint is bool:
        if not isinstance(value, bool):
            raise bad()
        return value
    if hint is int:
        if not isinstance(value, int) or isinstance(value, bool):
            raise bad()
        return value
    if hint is float:
        if not isinstance(value, int | float) or isinstance(value, bool) or not math.isfinite(value):
            raise bad()
        return float(value)
    if hint is str:
        if not isinstance(value, str):
            raise bad()
        return value
    if typing.get_origin(hint) is tuple:
        item = _args(hint)[0]
        items = value if isinstance(value, list) else [value]
        if not items:
            raise bad()
        try:
            return tuple(typed_value(v, item, source) for v in items)
        except UserError:
            raise bad() from None
    if hint is dict or typing.get_origin(hint) is dict:
        if not isinstance(value, dict):
            raise bad()
        return dict(value)
    raise TypeError(f"typed_value: unsupported annotation {hint!r} for {source}")


@dataclass(frozen=True)
class MethodSelection:
    """Which methods to run: by label (``method``), or the flow-pipeline shorthands (every ``flow`` x ``rectify``
    x ``variants``); nothing given: the default methods.

    Attributes:
        method: method labels, e.g. ``("dis-rect:gradient", "fused")``.
        flow: flow backend names (default :data:`DEFAULT_FLOW`) of flow-pipeline methods.
        variants: their variants (default: every variant; one method: ``gradient``).
        rectify: flow on rectified pairs (True, the default) or on the plain images.
    """

    method: tuple[str, ...] | None = None
    flow: tuple[str, ...] | None = None
    variants: tuple[str, ...] | None = None
    rectify: bool | None = None

    @classmethod
    def from_mapping(cls, values: dict, where: str) -> MethodSelection:
        """From a study's ``[evaluate]`` keys (each checked against the field's type, :func:`typed_value`)."""
        hints = annotations_of(cls)
        return cls(**{f.name: typed_value(values[f.name], hints[f.name], f"{where}: {f.name}")
                      for f in fields(cls) if f.name in values})

    def methods(self, single: bool = False, spell: Callable[[str], str] = str) -> list[Method]:
        """The selected methods (exactly one when ``single``: ``tri360 reconstruct``).

        Args:
            single: one method (default :data:`DEFAULT_METHOD`; the shorthands default to variant gradient).
            spell: a field name -> how the user wrote it, for messages (``"--flow"``, or the study key).
        Raises:
            UserError: an unknown method label, flow or variant name, or ``method`` mixed with the shorthands.
        """
        shorthand = [name for name in ("flow", "rectify", "variants") if getattr(self, name) is not None]
        try:
            if self.method:
                if shorthand:
                    raise UserError(f"{spell('method')} selects methods by label; do not combine it with "
                                    f"{spell('flow')}, {spell('rectify')} or {spell('variants')}")
                return get_methods(list(self.method))
            if not shorthand:
                return get_methods([DEFAULT_METHOD]) if single else evaluate_default_methods()
            variants = list(self.variants) if self.variants is not None else (["gradient"] if single else None)
            return flow_methods(list(self.flow or (DEFAULT_FLOW,)), [True if self.rectify is None else self.rectify],
                                variants)
        except ValueError as exc:
            raise UserError(str(exc)) from None

"""Typed parameters: declared once as dataclass fields, checked wherever values come from outside.

Declaring: the fields of a dataclass, each annotated with its type and (optionally) declared with :func:`param`:
default, one-line description, unit, limits, choices, an extra validity test.  Annotations understood: ``bool``,
``int``, ``float``, ``str``, ``dict`` (a table, not looked into), ``tuple[T, T, ...]`` of a fixed length,
``tuple[T, ...]``, a dataclass (a nested table, checked field by field), ``X | None`` and unions of these.

Checking (:func:`check_value` one value against an annotation, :func:`from_mapping` a raw mapping from JSON, TOML
or the command line against a dataclass, then building the instance): the values are as JSON and TOML give them,
so a bool is no number and a number no bool, ``2.0`` is no integer, an integer is accepted for a float (and becomes
a float), NaN and infinities are no numbers, a list is accepted for a tuple (and becomes a tuple).  Limits are
inclusive unless declared ``exclusive``; a tuple's limits and choices hold for each element.  Two switches follow
the source of the values: ``single`` (command line and study files: a tuple type also takes one element, never an
empty list) and ``null`` (whether ``X | None`` takes None: JSON has null, TOML has not).

Errors: :class:`ParamError` (a ``ValueError``), whose message is one line in one format::

    <where>: <name>: expected <what>, got <value>

``where`` names the file, record or scene family (left out when empty); ``name`` the key (dotted inside a nested
table: ``vignetting.edge_loss``; left out for the table itself); ``what`` the values allowed, in words
(:func:`expects`: ``an integer in [0, 10]``, ``3 numbers, each in [1, 50]``, ``one of dev, test, train``); ``value``
the value given (its ``repr``), ``nothing`` for a missing key or ``an unknown key`` for a key the dataclass does
not have (``what`` then lists the keys it has).  Callers that need their own exception type (the CLI maps some to
exit status 2) subclass :class:`ParamError` or wrap its message, so that every caller's message has this format.

Describing: :func:`describe` gives one line per field (description, unit, default, allowed values) for listings
such as ``tri360 scenes --params``.
"""

from __future__ import annotations

import dataclasses
import functools
import math
import numbers
import types
import typing
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, field, fields
from typing import Any

__all__ = ["METADATA_KEY", "REQUIRED", "ParamInfo", "ParamError", "param", "info_of", "type_hints", "shown",
           "expects", "check_value", "check_keys", "from_mapping", "describe"]

METADATA_KEY = "tri360"
"""Key of a field's :class:`ParamInfo` in its dataclass field's ``metadata``."""
REQUIRED = dataclasses.MISSING
"""The ``default`` of :func:`param` for a field without one: :func:`from_mapping` refuses a mapping without it."""


@dataclass(frozen=True)
class ParamInfo:
    """What a parameter's field says about it besides its name, type and default (:func:`param`).

    Attributes:
        description: one line: what the parameter is (listings show it; ``""``: none given).
        unit: e.g. ``"m"``, ``"W"``, ``"rad"``; ``""`` for counts, shares and switches.
        limits: ``(low, high)`` of a number, or of every number of a tuple (None: no bound on that side).
        exclusive: ``(low, high)``: whether that limit itself is excluded (default: both included).
        choices: the allowed strings of a ``str``, or of every string of a tuple.
        ordered: a tuple's elements never decrease (``[low, high]`` pairs).
        valid: a further test of the whole checked value (after its type, limits and choices), or None.
        expects: what the value must be, in words, when ``valid`` is given (replaces the text :func:`expects`
            makes from the type).
    """

    description: str = ""
    unit: str = ""
    limits: tuple[float | None, float | None] | None = None
    exclusive: tuple[bool, bool] = (False, False)
    choices: tuple[str, ...] | None = None
    ordered: bool = False
    valid: Callable[[Any], bool] | None = None
    expects: str = ""


_NO_INFO = ParamInfo()


def param(default: Any = REQUIRED, description: str = "", *, unit: str = "", limits: tuple | None = None,
          exclusive: tuple[bool, bool] = (False, False), choices: Iterable[str] | None = None, ordered: bool = False,
          valid: Callable[[Any], bool] | None = None, expects: str = "") -> Any:
    """One field of a parameters dataclass: its ``default`` (immutable: a number, string, bool, tuple, None or a
    frozen dataclass instance; :data:`REQUIRED` for none) and its :class:`ParamInfo` (the other arguments)."""
    info = ParamInfo(description, unit, None if limits is None else tuple(limits), tuple(exclusive),
                     None if choices is None else tuple(choices), ordered, valid, expects)
    return field(default=default, metadata={METADATA_KEY: info})


class ParamError(ValueError):
    """A value that is not what its parameter allows: ``<where>: <name>: expected <what>, got <value>`` (module doc).

    Attributes:
        name: the key (dotted inside nested tables); ``""`` for a whole table.
        expected: what the values must be, in words.
        got: the value given as shown (:func:`shown`), ``nothing`` or ``an unknown key``.
        where: the file, record or family (``""``: none).
    """

    def __init__(self, name: str, expected: str, got: str, where: str = ""):
        self.name, self.expected, self.got, self.where = name, expected, got, where
        super().__init__(": ".join(p for p in (where, self.detail) if p))

    @property
    def detail(self) -> str:
        """The message without ``where``: ``<name>: expected <what>, got <value>``."""
        return ": ".join(p for p in (self.name, f"expected {self.expected}, got {self.got}") if p)

    def __reduce__(self):  # pickles (a Dask worker's or subprocess's error) with every attribute
        return type(self), (self.name, self.expected, self.got, self.where)

    def at(self, where: str, cls: type[ParamError] | None = None) -> ParamError:
        """The same error at ``where`` (replacing this one's), as a ``cls`` (default: this error's class)."""
        return (cls or type(self))(self.name, self.expected, self.got, where)


def info_of(f: dataclasses.Field) -> ParamInfo:
    """The :class:`ParamInfo` of a dataclass field (an empty one for a field not declared with :func:`param`)."""
    return f.metadata.get(METADATA_KEY) or _NO_INFO


@functools.cache
def type_hints(obj) -> Mapping[str, Any]:
    """The evaluated type annotations of a dataclass or function (``typing.get_type_hints``, cached; read-only)."""
    return types.MappingProxyType(typing.get_type_hints(obj))


#: the longest value an error message shows, characters (a longer one is cut and ends with "...")
SHOWN_MAX = 80


def shown(value) -> str:
    """A value as an error message shows it: its ``repr``, on one line, cut after :data:`SHOWN_MAX` characters."""
    text = repr(value)
    text = " ".join(text.split()) if "\n" in text else text
    return text if len(text) <= SHOWN_MAX else text[:SHOWN_MAX - 3] + "..."


# ------------------------------------------------------------------------------------------------ the words


def _number(v) -> str:
    return f"{v:g}" if isinstance(v, float) else str(v)


def _allowed(info: ParamInfo) -> str:
    """``"in [0, 1]"``, ``"in (0, 100)"``, ``">= 0"``, ``"one of a, b"`` or ``""``: what limits the values."""
    if info.choices is not None:
        return "one of " + ", ".join(info.choices)
    if info.limits is None:
        return ""
    (lo, hi), (open_lo, open_hi) = info.limits, info.exclusive
    if lo is not None and hi is not None:
        return f"in {'(' if open_lo else '['}{_number(lo)}, {_number(hi)}{')' if open_hi else ']'}"
    if lo is not None:
        return f"{'>' if open_lo else '>='} {_number(lo)}"
    return f"{'<' if open_hi else '<='} {_number(hi)}" if hi is not None else ""


_NOUNS = {float: ("a number", "numbers"), int: ("an integer", "integers"), bool: ("true or false", "booleans"),
          str: ("a string", "strings"), dict: ("a table", "tables")}


def _is_union(tp) -> bool:
    return typing.get_origin(tp) in (typing.Union, types.UnionType)


def _elements(tp) -> tuple[Any, int | None] | None:
    """``tuple[T, T]`` -> ``(T, 2)``, ``tuple[T, ...]`` -> ``(T, None)``; None if ``tp`` is no tuple type."""
    if typing.get_origin(tp) is not tuple:
        return None
    args = typing.get_args(tp)
    if len(args) == 2 and args[1] is Ellipsis:
        return args[0], None
    if not args or any(a != args[0] for a in args):
        raise TypeError(f"parameter type {tp} is not supported (a tuple of one element type)")
    return args[0], len(args)


def _table(cls) -> str:
    return "a table with keys " + ", ".join(f.name for f in fields(cls) if f.init)


def _plain(tp, info: ParamInfo, single: bool, null: bool) -> str:
    """:func:`expects` for a type that is no union."""
    allowed = _allowed(info)
    element = _elements(tp)
    if element is not None:
        etype, n = element
        noun = _NOUNS[etype][1] if etype in _NOUNS else f"values ({_plain(etype, info, single, null)})"
        if n is not None:
            text = f"{n} {noun}" + (" (low <= high)" if info.ordered and n == 2 else
                                     " (in increasing order)" if info.ordered else "")
        elif single:
            text = f"{_NOUNS.get(etype, ('a value',))[0]} or a non-empty list of {noun}"
        else:
            text = f"a list of {noun}"
        return text + (f", each {allowed}" if allowed and etype in _NOUNS else "")
    if dataclasses.is_dataclass(tp):
        return _table(tp)
    if tp is str and info.choices is not None:
        return allowed
    return _NOUNS.get(tp, (str(tp),))[0] + (f" {allowed}" if allowed and tp in (int, float) else "")


def expects(hint, info: ParamInfo | None = None, *, single: bool = False, null: bool = True) -> str:
    """What a value of type ``hint`` must be, in words: ``"an integer in [0, 10]"``, ``"3 numbers, each in [1,
    50]"``, ``"a string or a non-empty list of strings"`` (``single``), ``"a number >= 0 or null"`` (``null``)."""
    info = info or _NO_INFO
    options = typing.get_args(hint) if _is_union(hint) else (hint,)
    kinds = [a for a in options if a is not type(None)]
    text = info.expects or " or ".join(_plain(a, info, single, null) for a in kinds)
    return text + (" or null" if null and len(kinds) < len(options) else "")


# ------------------------------------------------------------------------------------------------ checking


class _Bad(Exception):
    """The value being checked is not of its type (:func:`check_value` turns it into a :class:`ParamError`)."""


def _scalar(value, tp, info: ParamInfo):
    if tp is bool:
        ok = isinstance(value, bool)
    elif tp is int:
        ok = isinstance(value, numbers.Integral) and not isinstance(value, bool)
        value = int(value) if ok else value
    elif tp is float:
        ok = isinstance(value, numbers.Real) and not isinstance(value, bool) and math.isfinite(value)
        value = float(value) if ok else value
    elif tp is str:
        ok = isinstance(value, str) and (info.choices is None or value in info.choices)
    elif tp is dict:
        ok = isinstance(value, dict)
        value = dict(value) if ok else value
    else:
        raise TypeError(f"parameter type {tp} is not supported (bool, int, float, str, dict, a tuple, a dataclass "
                        "or a union of them)")
    if ok and tp in (int, float) and info.limits is not None:
        (lo, hi), (open_lo, open_hi) = info.limits, info.exclusive
        ok = (lo is None or (value > lo if open_lo else value >= lo)) and \
             (hi is None or (value < hi if open_hi else value <= hi))
    if not ok:
        raise _Bad
    return value


def _check(value, tp, info: ParamInfo, single: bool, null: bool, name: str, where: str):
    if _is_union(tp):
        options = [a for a in typing.get_args(tp) if a is not type(None)]
        if value is None:
            if null and len(options) < len(typing.get_args(tp)):
                return None
            raise _Bad
        if len(options) == 1:
            return _check(value, options[0], info, single, null, name, where)
        for option in options:
            try:
                return _check(value, option, info, single, null, name, where)
            except (_Bad, ParamError):
                continue
        raise _Bad
    element = _elements(tp)
    if element is not None:
        etype, n = element
        if isinstance(value, list | tuple):
            items = list(value)
        elif single and value is not None and not isinstance(value, dict):
            items = [value]
        else:
            raise _Bad
        if (n is not None and len(items) != n) or (single and not items):
            raise _Bad
        out = tuple(_check(v, etype, info, single, null, name, where) for v in items)
        if info.ordered and any(a > b for a, b in zip(out, out[1:], strict=False)):
            raise _Bad
        return out
    if dataclasses.is_dataclass(tp):
        if isinstance(value, tp):
            return value
        if not isinstance(value, Mapping):
            raise _Bad
        return from_mapping(tp, value, where=where, name=name, single=single, null=null)
    return _scalar(value, tp, info)


def check_value(value, hint, info: ParamInfo | None = None, *, name: str = "", where: str = "",
                single: bool = False, null: bool = True):
    """``value`` checked against the annotation ``hint`` and ``info``'s limits, choices and ``valid`` test; returns
    it normalised (a float for an integer given for a float, a tuple for a list, a dataclass instance for a table).

    Args:
        name, where: what an error names (module doc).
        single: a tuple type also takes one element (which becomes a 1-tuple), never an empty list.
        null: ``X | None`` takes None.
    Raises:
        ParamError: the value is not what ``hint`` and ``info`` allow.
        TypeError: an annotation this module does not support.
    """
    info = info or _NO_INFO
    try:
        out = _check(value, hint, info, single, null, name, where)
        if out is not None and info.valid is not None and not info.valid(out):
            raise _Bad
    except _Bad:
        raise ParamError(name, expects(hint, info, single=single, null=null), shown(value), where) from None
    return out


def check_keys(raw, known: Iterable[str], *, name: str = "", where: str = "") -> Mapping:
    """``raw`` if it is a mapping whose keys are all in ``known`` (the first other key, in ``raw``'s order, is the
    error's culprit).

    Raises:
        ParamError: ``raw`` is no mapping, or has a key not in ``known``.
    """
    known = list(known)
    if not isinstance(raw, Mapping):
        raise ParamError(name, "a table with keys " + ", ".join(known), shown(raw), where)
    for key in raw:
        if key not in known:
            culprit = f"{name}.{key}" if name else str(key)
            raise ParamError(culprit, "one of the keys " + ", ".join(known) if known else "no keys", "an unknown key",
                             where)
    return raw


def from_mapping(cls: type, raw, *, where: str = "", name: str = "", single: bool = False, null: bool = True):
    """An instance of the dataclass ``cls`` from the raw mapping ``raw``: its keys must be fields of ``cls``, its
    values of their types (:func:`check_value`), every field without a default present; the others keep their
    defaults.  Checked in this order: unknown keys, the values given (in field order), missing keys.

    Args:
        name: the key of ``raw`` itself inside an outer table (the prefix of its keys' dotted names), or ``""``.
        where, single, null: as for :func:`check_value`.
    Raises:
        ParamError: the first problem (module doc).
    """
    flds = [f for f in fields(cls) if f.init]
    check_keys(raw, [f.name for f in flds], name=name, where=where)
    hints = type_hints(cls)
    prefix = f"{name}." if name else ""
    values = {f.name: check_value(raw[f.name], hints[f.name], info_of(f), name=prefix + f.name, where=where,
                                  single=single, null=null)
              for f in flds if f.name in raw}
    for f in flds:
        if f.name not in raw and f.default is dataclasses.MISSING and f.default_factory is dataclasses.MISSING:
            raise ParamError(prefix + f.name, expects(hints[f.name], info_of(f), single=single, null=null),
                             "nothing", where)
    return cls(**values)


# ------------------------------------------------------------------------------------------------ listings


def _show_default(value) -> str:
    """A default as a listing shows it: ``35``, ``[8, 7, 3]``, ``true``, ``none``, ``table, cube``."""
    if value is None:
        return "none"
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, tuple | list):
        items = [_show_default(v) for v in value]
        return ", ".join(items) if all(isinstance(v, str) for v in value) and value else f"[{', '.join(items)}]"
    return _number(value)


def describe(cls: type) -> dict[str, str]:
    """Name -> one line for each field of the dataclass ``cls``, in declaration order: description, unit, default
    and allowed values, e.g. ``"ceiling height, m (default 2.8; in [1.8, 20])"``."""
    hints = type_hints(cls)
    out = {}
    for f in fields(cls):
        info = info_of(f)
        hint = hints[f.name]
        if _is_union(hint):
            hint = next((a for a in typing.get_args(hint) if a is not type(None)), hint)
        allowed = _allowed(info)
        if allowed and _elements(hint) is not None:
            allowed = "each " + allowed
        unit = f", {info.unit}" if info.unit else ""
        default = "required" if f.default is dataclasses.MISSING else f"default {_show_default(f.default)}"
        text = f"{info.description}{unit}"
        out[f.name] = f"{text} ({default}{'; ' + allowed if allowed else ''})" if text else \
            f"{default}{'; ' + allowed if allowed else ''}"
    return out

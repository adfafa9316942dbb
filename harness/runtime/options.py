"""Options shared by the command line and study files: typed values and method selection, each rule once.

- :func:`typed_value` checks a value from outside (a study file's TOML, a command-line option) against a type
  annotation -- of a :class:`harness.render.base.RenderSettings` field, a job's parameter or a
  :class:`MethodSelection` field -- so the types of every option are written once, where the option is defined
  (:func:`reconstruction.params.check_value`).  Booleans must be booleans (``"false"`` is refused, never read as
  ``bool("false")``), integers integers (``128.0`` and ``"128"`` are refused), a float may be written as an
  integer.
- :class:`MethodSelection` turns ``--method`` / ``--flow`` / ``--variants`` / ``--rectify`` (or a study's
  ``[evaluate]`` keys of the same names) into methods.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, fields

from harness.data.errors import UserError
from reconstruction.methods.base import Method
from reconstruction.methods.flow_pipeline import DEFAULT_FLOW
from reconstruction.methods.registry import DEFAULT_METHOD, evaluate_default_methods, flow_methods, get_methods
from reconstruction.params import ParamError, check_value, type_hints

__all__ = ["typed_value", "MethodSelection"]


def typed_value(value, hint, source: str):
    """``value`` checked against the annotation ``hint`` as an option's value: a float for an integer given where a
    number is asked for, a tuple for ``tuple[X, ...]``, which also takes a single X (never an empty list); None is
    never accepted (a study file has no null).

    Supported annotations: those of :func:`reconstruction.params.check_value` (here ``bool``, ``int``, ``float``,
    ``str``, ``tuple[X, ...]``, ``dict`` and unions of them with None).

    Raises:
        UserError: ``"<source>: expected <what>, got <value>"`` (one line, :mod:`reconstruction.params`).
    """
    try:
        return check_value(value, hint, name=source, single=True, null=False)
    except ParamError as exc:
        raise UserError(str(exc)) from None


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
        hints = type_hints(cls)
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

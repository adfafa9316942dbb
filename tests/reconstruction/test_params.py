"""reconstruction.params: typed parameter declaration, checking a raw mapping against a dataclass, the one-line
error format, and the listing."""

from __future__ import annotations

import dataclasses
import math
import pickle

import pytest

from reconstruction.params import (
    REQUIRED,
    ParamError,
    check_keys,
    check_value,
    describe,
    expects,
    from_mapping,
    param,
)


@dataclasses.dataclass(frozen=True)
class Inner:
    axis: str = param(REQUIRED, "lens axis", choices=("x", "y", "z"))
    loss: float = param(REQUIRED, "light lost", limits=(0.0, 1.0), exclusive=(False, True))


@dataclasses.dataclass(frozen=True)
class Record:
    count: int = param(REQUIRED, "how many", limits=(0, 10))
    size: tuple[float, float, float] = param((4.0, 3.0, 2.5), "room", unit="m", limits=(1.0, 50.0))
    shiny: bool = param(False, "glossy floor")
    power: float | None = param(None, "light power (none: automatic)", unit="W", limits=(0.0, None))
    names: tuple[str, ...] = param(("a",), "parts, in order", choices=("a", "b"))
    span: tuple[float, float] = param((0.0, 1.0), "range", limits=(0.0, 2.0), ordered=True)
    odd: int = param(1, "an odd number", valid=lambda n: n % 2 == 1, expects="an odd integer")
    inner: Inner | None = None
    grid: tuple[tuple[int, int], ...] = param((), "cells", limits=(0, 9))


class Mine(ParamError):
    """A caller's own error type (as scenes.model.ParameterError)."""


def _error(raw: dict, **kw) -> str:
    with pytest.raises(ParamError) as info:
        from_mapping(Record, raw, where="f.json", **kw)
    text = str(info.value)
    assert "\n" not in text and text.startswith("f.json: ")
    return text


@pytest.mark.parametrize(("raw", "message"), [
    ({"count": "2"}, "count: expected an integer in [0, 10], got '2'"),
    ({"count": 2.0}, "count: expected an integer in [0, 10], got 2.0"),
    ({"count": True}, "count: expected an integer in [0, 10], got True"),
    ({"count": 11}, "count: expected an integer in [0, 10], got 11"),
    ({"count": 1, "size": [4, 3]}, "size: expected 3 numbers, each in [1, 50], got [4, 3]"),
    ({"count": 1, "size": [4, 3, 0.5]}, "size: expected 3 numbers, each in [1, 50], got [4, 3, 0.5]"),
    ({"count": 1, "size": [4, True, 3]}, "size: expected 3 numbers, each in [1, 50], got [4, True, 3]"),
    ({"count": 1, "shiny": 1}, "shiny: expected true or false, got 1"),
    ({"count": 1, "power": "high"}, "power: expected a number >= 0 or null, got 'high'"),
    ({"count": 1, "power": math.nan}, "power: expected a number >= 0 or null, got nan"),
    ({"count": 1, "power": math.inf}, "power: expected a number >= 0 or null, got inf"),
    ({"count": 1, "names": ["c"]}, "names: expected a list of strings, each one of a, b, got ['c']"),
    ({"count": 1, "names": "a"}, "names: expected a list of strings, each one of a, b, got 'a'"),
    ({"count": 1, "span": [1.5, 0.5]}, "span: expected 2 numbers (low <= high), each in [0, 2], got [1.5, 0.5]"),
    ({"count": 1, "odd": 2}, "odd: expected an odd integer, got 2"),
    ({"count": 1, "inner": {"axis": "w", "loss": 0.5}}, "inner.axis: expected one of x, y, z, got 'w'"),
    ({"count": 1, "inner": {"axis": "x", "loss": 1.0}}, "inner.loss: expected a number in [0, 1), got 1.0"),
    ({"count": 1, "inner": {"axis": "x"}}, "inner.loss: expected a number in [0, 1), got nothing"),
    ({"count": 1, "inner": {"axis": "x", "loss": 0, "k": 1}},
     "inner.k: expected one of the keys axis, loss, got an unknown key"),
    ({"count": 1, "inner": 3}, "inner: expected a table with keys axis, loss or null, got 3"),
    ({"count": 1, "grid": [[1, 2], [3]]},
     "grid: expected a list of values (2 integers, each in [0, 9]), got [[1, 2], [3]]"),
    ({"count": 1, "colour": "red"},
     "colour: expected one of the keys count, size, shiny, power, names, span, odd, inner, grid, got an unknown key"),
    ({}, "count: expected an integer in [0, 10], got nothing"),
])
def test_each_kind_of_bad_value_is_one_line_in_the_one_format(raw, message):
    assert _error(raw) == f"f.json: {message}"


def test_the_error_keeps_its_parts_and_moves_and_pickles():
    with pytest.raises(ParamError) as info:
        from_mapping(Record, {"count": -1}, where="f.json")
    exc = info.value
    assert isinstance(exc, ValueError)
    assert (exc.where, exc.name, exc.expected, exc.got) == ("f.json", "count", "an integer in [0, 10]", "-1")
    assert exc.detail == "count: expected an integer in [0, 10], got -1"
    assert str(exc.at("g.toml")) == "g.toml: count: expected an integer in [0, 10], got -1"
    assert str(exc.at("")) == exc.detail

    moved = exc.at("h", Mine)
    assert isinstance(moved, Mine) and str(moved) == "h: " + exc.detail
    again = pickle.loads(pickle.dumps(moved))
    assert type(again) is Mine and str(again) == str(moved) and again.name == "count"
    assert str(ParamError("", "a table", "3")) == "expected a table, got 3"


def test_good_values_round_trip_normalised():
    raw = {"count": 3, "size": [8, 6, 3.5], "shiny": True, "power": 40, "names": ["b", "a"], "span": [0.5, 0.5],
           "odd": 5, "inner": {"axis": "y", "loss": 0}, "grid": [[1, 2], [3, 4]]}
    r = from_mapping(Record, raw)
    assert r == Record(count=3, size=(8.0, 6.0, 3.5), shiny=True, power=40.0, names=("b", "a"), span=(0.5, 0.5),
                       odd=5, inner=Inner("y", 0.0), grid=((1, 2), (3, 4)))
    assert isinstance(r.power, float) and isinstance(r.size[0], float) and isinstance(r.inner.loss, float)
    assert isinstance(r.count, int) and isinstance(r.names, tuple)
    assert from_mapping(Record, dataclasses.asdict(r) | {"inner": {"axis": "y", "loss": 0.0}}) == r
    defaults = from_mapping(Record, {"count": 0})
    assert defaults == Record(count=0) and defaults.power is None and defaults.inner is None
    assert from_mapping(Record, {"count": 0, "power": None}).power is None  # JSON null
    assert from_mapping(Record, {"count": 0, "inner": Inner("x", 0.5)}).inner == Inner("x", 0.5)  # an instance


def test_bool_is_no_integer_and_no_number_and_no_integer_is_a_bool():
    for hint in (int, float):
        for value in (True, False):
            with pytest.raises(ParamError, match=r"^x: expected (an integer|a number), got (True|False)$"):
                check_value(value, hint, name="x")
    with pytest.raises(ParamError, match=r"^x: expected true or false, got 0$"):
        check_value(0, bool, name="x")
    assert check_value(True, bool) is True
    assert check_value(3, float) == 3.0 and isinstance(check_value(3, float), float)


@pytest.mark.parametrize("value", [math.nan, math.inf, -math.inf])
def test_nan_and_infinities_are_no_numbers(value):
    with pytest.raises(ParamError, match=r"^w: x: expected a number, got (nan|inf|-inf)$"):
        check_value(value, float, name="x", where="w")
    with pytest.raises(ParamError, match=r"^x: expected 2 numbers, got \[1\.0, (nan|inf|-inf)\]$"):
        check_value([1.0, value], tuple[float, float], name="x")


def test_single_and_null_follow_the_source_of_the_values():
    assert check_value("a", tuple[str, ...], single=True) == ("a",)
    assert check_value(["a", "b"], tuple[str, ...], single=True) == ("a", "b")
    with pytest.raises(ParamError, match=r"^m: expected a string or a non-empty list of strings, got \[\]$"):
        check_value([], tuple[str, ...], name="m", single=True)
    assert check_value([], tuple[str, ...]) == ()
    with pytest.raises(ParamError, match=r"^m: expected a list of strings, got 'a'$"):
        check_value("a", tuple[str, ...], name="m")
    assert check_value(None, bool | None) is None
    with pytest.raises(ParamError, match=r"^r: expected true or false, got None$"):
        check_value(None, bool | None, name="r", null=False)
    assert check_value({"k": 1}, dict | tuple[str, ...], single=True) == {"k": 1}
    with pytest.raises(ParamError, match=r"^s: expected a table or a string or a non-empty list of strings, got 5$"):
        check_value(5, dict | tuple[str, ...], name="s", single=True)


def test_expects_and_check_keys():
    assert expects(int) == "an integer" and expects(str | None) == "a string or null"
    assert expects(str | None, null=False) == "a string"
    assert expects(tuple[int, ...], single=True) == "an integer or a non-empty list of integers"
    assert check_keys({"a": 1}, ("a", "b")) == {"a": 1}
    with pytest.raises(ParamError, match=r"^t: c: expected one of the keys a, b, got an unknown key$"):
        check_keys({"a": 1, "c": 2}, ("a", "b"), where="t")
    with pytest.raises(ParamError, match=r"^t: render\.c: expected one of the keys a, b, got an unknown key$"):
        check_keys({"c": 2}, ("a", "b"), name="render", where="t")
    with pytest.raises(ParamError, match=r"^t: render: expected a table with keys a, b, got \[1\]$"):
        check_keys([1], ("a", "b"), name="render", where="t")
    with pytest.raises(ParamError, match=r"^c: expected no keys, got an unknown key$"):
        check_keys({"c": 2}, ())


def test_unsupported_annotations_are_a_type_error():
    with pytest.raises(TypeError, match="not supported"):
        check_value(1, list[int])
    with pytest.raises(TypeError, match="one element type"):
        check_value((1, "a"), tuple[int, str])


def test_describe_gives_unit_default_and_allowed_values():
    lines = describe(Record)
    assert lines["count"] == "how many (required; in [0, 10])"
    assert lines["size"] == "room, m (default [4, 3, 2.5]; each in [1, 50])"
    assert lines["shiny"] == "glossy floor (default false)"
    assert lines["power"] == "light power (none: automatic), W (default none; >= 0)"
    assert lines["names"] == "parts, in order (default a; each one of a, b)"
    assert lines["inner"] == "default none"  # no description: no leading space
    assert list(lines) == [f.name for f in dataclasses.fields(Record)]

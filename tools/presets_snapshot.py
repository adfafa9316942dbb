"""The reviewed snapshot of every built-in method's configuration, keyed by label.

A built-in method's configuration (``Method.config()``: every parameter of every stage, as a results set's
``config.json`` records it) changes only on purpose.  ``tests/reconstruction/methods/presets_snapshot.json`` holds the
configuration of each built-in method (:func:`snapshot_methods`: the named methods and ablations of
:data:`~reconstruction.methods.registry.PRESETS` and :data:`~reconstruction.methods.registry.ABLATIONS`, then every
configuration of the flow pipeline with tri360's own flows and variants; outside plugins are left out), and
``tests/reconstruction/methods/test_presets_snapshot.py`` fails when a method's configuration differs from it, with
one line per differing key (``[fused-mirror] sweep.planes.mirror_tolerance: 0.2 in the snapshot, 0.25 live``; the
methods that differ alike share a line).  A tuning change rewrites the file with this tool, and the file's diff is
reviewed with the change.

Values are compared by JSON type and value (``1`` and ``1.0`` differ, as do ``true`` and ``1``); floats are written
as Python's ``repr``, which reads back to the same float.

    python -m tools.presets_snapshot            # check; exit 1 with one line per difference
    python -m tools.presets_snapshot --update   # rewrite the file from the methods as they are now
                                                # (make presets-update); then review its diff
"""

from __future__ import annotations

from harness.runtime import startup

if __name__ == "__main__":  # run as a script: Ctrl-C during the imports below is one line and 130
    startup.guard("presets_snapshot")

import json
import sys
from collections.abc import Mapping
from pathlib import Path

from harness.data.atomic import atomic_write_text
from reconstruction.flow.backends import ORACLE, builtin_flows
from reconstruction.methods.base import Method
from reconstruction.methods.flow_pipeline import FlowMethod
from reconstruction.methods.registry import builtin_methods
from reconstruction.refine.lm import builtin_variants
from tools.common import ArgumentParser, read_json_file, user_error

FILE = Path(__file__).resolve().parents[1] / "tests" / "reconstruction" / "methods" / "presets_snapshot.json"
"""The repository's snapshot (``--file`` picks another)."""
UPDATE_COMMAND = "python -m tools.presets_snapshot --update"
FORMAT = 1
SHOWN_CHARS = 80
"""A value longer than this (as JSON) is shown cut to this many characters in a difference line."""
SHOWN_LABELS = 4
"""A difference line names at most this many of the methods that differ alike."""


def snapshot_methods() -> list[Method]:
    """The built-in methods (:func:`~reconstruction.methods.registry.builtin_methods`, in its order) without the
    flow-pipeline configurations of an outside flow or variant (entry points of an installed plugin)."""
    flows = {b.name for b in builtin_flows()} | {ORACLE}
    variants = {"average"} | {v.name for v in builtin_variants()}
    return [m for m in builtin_methods()
            if not isinstance(m, FlowMethod) or (m.flow_name in flows and m.variant in variants)]


def as_json(config: Mapping) -> dict:
    """``config`` as it reads back from the snapshot file (tuples become lists).

    Raises:
        ValueError: it holds a NaN or an infinity (not JSON) or a value JSON cannot hold.
    """
    return json.loads(json.dumps(config, allow_nan=False))


def compute(methods: list[Method] | None = None) -> dict[str, dict]:
    """Label -> :func:`as_json` of ``Method.config()`` of ``methods`` (default: :func:`snapshot_methods`).

    Raises:
        ValueError: a configuration is not JSON (the message names its method).
    """
    methods = snapshot_methods() if methods is None else methods
    out = {}
    for m in methods:
        try:
            out[m.label] = as_json(m.config())
        except (TypeError, ValueError) as exc:
            raise ValueError(f"the configuration of {m.label} is not JSON: {exc}") from None
    return out


def _read(path: Path) -> dict:
    """A snapshot file's JSON.

    Raises:
        FileNotFoundError: ``path`` is missing.
        ValueError: one line naming ``path``: a directory, not JSON, or not a snapshot file.
    """
    data = read_json_file(path, "presets snapshot", f"no presets snapshot (write it with `{UPDATE_COMMAND}`)")
    if data.get("format") != FORMAT or not isinstance(data.get("methods"), dict):
        raise ValueError(f"{path}: not a presets snapshot of format {FORMAT} (no \"format\": {FORMAT} and "
                         f"\"methods\")")
    return data


def load(path: Path = FILE) -> dict[str, dict]:
    """The stored configurations of a snapshot file, by label."""
    return _read(path)["methods"]


def _shown(value) -> str:
    text = json.dumps(value)
    return text if len(text) <= SHOWN_CHARS else text[:SHOWN_CHARS - 3] + "..."


def _same(a, b) -> bool:
    """Equal JSON values of the same JSON type (``1`` is not ``1.0``, ``true`` is not ``1``)."""
    if type(a) is not type(b):
        return False
    if isinstance(a, dict):
        return a.keys() == b.keys() and all(_same(a[k], b[k]) for k in a)
    if isinstance(a, list):
        return len(a) == len(b) and all(_same(x, y) for x, y in zip(a, b, strict=True))
    return a == b


def _walk(stored, live, path: str, out: list[tuple[str, str, str]]) -> None:
    if isinstance(stored, dict) and isinstance(live, dict):
        for k in [*stored, *(k for k in live if k not in stored)]:
            where = f"{path}.{k}" if path else str(k)
            if k not in live:
                out.append((where, _shown(stored[k]), "absent"))
            elif k not in stored:
                out.append((where, "absent", _shown(live[k])))
            else:
                _walk(stored[k], live[k], where, out)
    elif isinstance(stored, list) and isinstance(live, list) and len(stored) == len(live):
        for i, (a, b) in enumerate(zip(stored, live, strict=True)):
            _walk(a, b, f"{path}[{i}]", out)
    elif not _same(stored, live):
        out.append((path or "configuration", _shown(stored), _shown(live)))


def differences(stored: Mapping[str, dict], live: Mapping[str, dict]) -> list[str]:
    """Every difference between the snapshot ``stored`` and the configurations ``live``, one line each, in the
    snapshot's order of methods and keys: ``[labels] path: <snapshot value> in the snapshot, <live value> live``
    (``absent`` for a key only one side has; one line for all methods that differ alike at the same path, their
    labels listed up to :data:`SHOWN_LABELS`), then one line per method only one side has."""
    alike: dict[tuple[str, str, str], list[str]] = {}
    lines = []
    for label in [*stored, *(k for k in live if k not in stored)]:
        if label not in live:
            lines.append(f"[{label}] is in the snapshot but is no built-in method")
        elif label not in stored:
            lines.append(f"[{label}] is a built-in method missing from the snapshot")
        else:
            found: list[tuple[str, str, str]] = []
            _walk(stored[label], live[label], "", found)
            for key in found:
                alike.setdefault(key, []).append(label)
    out = []
    for (where, a, b), labels in alike.items():
        more = f", +{len(labels) - SHOWN_LABELS} more" if len(labels) > SHOWN_LABELS else ""
        out.append(f"[{', '.join(labels[:SHOWN_LABELS])}{more}] {where}: {a} in the snapshot, {b} live")
    return out + lines


def update(path: Path, live: Mapping[str, dict] | None = None) -> None:
    """Rewrite the snapshot file ``path`` with ``live`` (default: :func:`compute`).

    Raises:
        ValueError: ``path`` exists and is not a presets snapshot, or its folder does not exist.
    """
    path = Path(path)
    if path.exists() or path.is_symlink():
        _read(path)  # only a snapshot file is ever replaced
    elif not path.parent.is_dir():
        raise ValueError(f"{path}: its folder does not exist")
    live = compute() if live is None else live
    data = {"format": FORMAT, "about": f"the configuration of every built-in method, by label; rewritten on purpose "
                                      f"by `{UPDATE_COMMAND}` (tools/presets_snapshot.py) and reviewed in its diff",
            "methods": dict(live)}
    atomic_write_text(path, json.dumps(data, indent=1, allow_nan=False) + "\n")


def main(argv: list[str] | None = None) -> int:
    parser = ArgumentParser(prog="python -m tools.presets_snapshot", description=__doc__.split("\n\n")[0])
    parser.add_argument("--file", type=Path, default=FILE, help="the snapshot file (default: %(default)s)")
    parser.add_argument("--update", action="store_true", help="rewrite the file from the methods as they are now")
    args = parser.parse_args(argv)
    try:
        live = compute()
        if args.update:
            update(args.file, live)
            print(f"wrote {args.file} ({len(live)} methods)")
            return 0
        problems = differences(load(args.file), live)
    except (OSError, ValueError) as exc:
        return user_error("python -m tools.presets_snapshot", exc)
    for line in problems:
        print(line, file=sys.stderr)
    if problems:
        print(f"{len(problems)} differences; if they are meant, rewrite the snapshot: {UPDATE_COMMAND}",
              file=sys.stderr)
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(startup.run_main(main, "presets_snapshot"))

"""CI accuracy regression: a small fixed data set, upper bounds on MAE, and a check against them.

The data set (:func:`build_dataset`) is one real Cycles frame of ``classroom`` and two ray-cast
``synthetic_box`` frames, all ``REGRESSION_WIDTH`` x ``REGRESSION_WIDTH / 2``.  It is evaluated
(:func:`run_regression`) with the default method (``DEFAULT_METHOD``), ``fused``, tri360's flow
configuration (``DEFAULT_FLOW``, rectified) and OpenCV's variational-only DeepFlow on plain equirect images
(``deepflow-opencv-plain``) over every variant.

A bounds file (``--bounds``; the repository's is ``tests/regression_bounds.json``, which ``make regress-update``
rewrites and the tests read) holds an upper bound on the MAE (metres, mean over that scene's frames) per scene x
configuration label (``dis-rect``) x variant, and per scene x method label (the default, ``fused``) x
``final``: the measured MAE x (1 + margin).  :func:`check` reports every bound exceeded,
every key missing on either side, and every configuration whose best refined variant does not beat ``average``
on a scene (unless the file waives that scene/configuration, with a reason; a waiver that is no longer needed is
reported too).

    python -m tools.regression --bounds FILE                 # run and check; exit 1 listing the violations
    python -m tools.regression --bounds FILE --update        # re-run and rewrite the bounds (margin 0.15)
    python -m tools.regression --bounds FILE --data DIR      # keep/reuse the rendered frames in DIR
    python -m tools.regression --bounds FILE --update --waive classroom/dis-rect="why"   # a known exception
"""

from __future__ import annotations

from harness.runtime import startup

if __name__ == "__main__":  # run as a script: Ctrl-C during the imports below is one line and 130
    startup.guard("regression")

import datetime
import json
import math
import sys
import tempfile
import time
from collections.abc import Mapping
from pathlib import Path

import pandas as pd

from harness.commands.evaluate import config_keys, evaluate
from harness.commands.render import render_frames
from harness.data.atomic import atomic_write_text
from harness.render.base import RenderSettings
from harness.runtime.context import QUIET, RunContext
from reconstruction.methods.flow_pipeline import DEFAULT_FLOW
from reconstruction.methods.registry import DEFAULT_METHOD, DEFAULT_VARIANTS, flow_methods, get_methods
from tools.common import ArgumentParser, read_json_file, user_error

PROG = "python -m tools.regression"

#: panorama width of every regression frame, pixels (height = width / 2)
REGRESSION_WIDTH = 400
#: Cycles samples of the classroom frame (the render default is 20 at 1000 x 500; fewer keep CI short, and
#: distance is exact either way)
BLENDER_SAMPLES = 12
#: seed of layout jitter, viewpoints and render noise
SEED = 0
#: (scene name for render_frames, number of viewpoints)
SCENES = (("classroom", 1), ("synthetic_box", 2))
#: default relative margin of a bound over the measured MAE
DEFAULT_MARGIN = 0.15


#: the flow configurations of the regression run: tri360's and OpenCV's variational-only DeepFlow on plain pairs (a
#: flow whose failures near the poles and the seam the refinement variants must keep reducing)
REGRESSION_CONFIGS = ((DEFAULT_FLOW, True), ("deepflow-opencv", False))


def regression_configs() -> list[tuple[str, bool]]:
    """:data:`REGRESSION_CONFIGS`: ``[(DEFAULT_FLOW, True), ("deepflow-opencv", False)]``."""

    return list(REGRESSION_CONFIGS)


def build_dataset(root: Path | str, width: int = REGRESSION_WIDTH, samples: int = BLENDER_SAMPLES,
                  threads: int = 0, ctx: RunContext = QUIET) -> Path:
    """Render the regression frames into ``root`` (resumable: complete frames are kept) and return it.

    Args:
        root: data root; frames land in ``<root>/<scene>/vp00N``.
        width: panorama width, pixels.
        samples: Cycles samples of the Blender frame.
        threads: Cycles threads (0 = all cores).
        ctx: how the renders run (progress bars or none: the default).
    """

    root = Path(root)
    for scene, viewpoints in SCENES:
        render_frames(RenderSettings(width=width, samples=samples, seed=SEED, threads=threads), scene,
                      viewpoints=viewpoints, out_root=root, ctx=ctx)
    return root


#: the methods besides the flow configurations: the default and ``fused`` (kept with its numbers)
REGRESSION_METHODS = (DEFAULT_METHOD, "fused")


def run_regression(workdir: Path | str, data: Path | str | None = None, width: int = REGRESSION_WIDTH,
                   samples: int = BLENDER_SAMPLES, threads: int = 0, ctx: RunContext = QUIET) -> pd.DataFrame:
    """Build the data set (into ``data``, default ``<workdir>/data``) and evaluate it into ``<workdir>/results``.

    Returns:
        The results table (``harness.commands.evaluate`` schema): the default method, ``fused`` and the default variants
        (``DEFAULT_VARIANTS``) of every regression configuration.
    """

    workdir = Path(workdir)
    root = build_dataset(Path(data) if data is not None else workdir / "data", width, samples, threads, ctx)
    variants = list(DEFAULT_VARIANTS)
    methods = [*get_methods(list(REGRESSION_METHODS)),
               *(m for flow, rect in regression_configs() for m in flow_methods([flow], [rect], variants))]
    return evaluate(root, workdir / "results", methods, scenes=[s for s, _ in SCENES], report=False,
                    ctx=ctx)


#: the "variant" key of a method that is not a flow configuration (e.g. ``fused``) in the bounds file
FINAL = "final"


def measured_mae(table: pd.DataFrame) -> dict[str, dict[str, dict[str, float]]]:
    """``{scene: {config label or method label: {variant or "final": MAE}}}``, metres, mean over the frames."""

    out: dict[str, dict[str, dict[str, float]]] = {}
    config, variant = config_keys(table, other=FINAL)
    keyed = pd.DataFrame({"scene": table["scene"], "config": config, "variant": variant, "mae_m": table["mae_m"]})
    groups = keyed.groupby(["scene", "config", "variant"], sort=True)["mae_m"]
    for (scene, config, variant), mae in groups.apply(lambda s: s.mean(skipna=False)).items():
        out.setdefault(scene, {}).setdefault(config, {})[variant] = float(mae)
    return out


def measured_text(table: pd.DataFrame) -> str:
    """:func:`measured_mae` as text, one ``scene/config/variant  MAE`` line per bounds key (metres)."""
    flat = _flatten(measured_mae(table)) if len(table) else {}
    width = max((len("/".join(k)) for k in flat), default=0)
    return "\n".join(f"  {'/'.join(k):<{width}s}  {v:.4f}" for k, v in sorted(flat.items()))


def _flatten(nested: Mapping) -> dict[tuple[str, str, str], float]:
    return {(s, c, v): float(x) for s, cs in nested.items() for c, vs in cs.items() for v, x in vs.items()}


def check(table: pd.DataFrame, bounds: Mapping[str, Mapping[str, Mapping[str, float]]],
          resolution: tuple[int, int] | None = None, waivers: Mapping[str, str] | None = None) -> list[str]:
    """Every violation of ``bounds`` by ``table`` (empty list: no regression).

    Args:
        table: results table (columns scene, method, flow, rectify, variant, mae_m, width, height at least).
        bounds: ``{scene: {config label: {variant: max MAE in metres}}}``, a method that is no flow configuration
            as ``{method label: {"final": ...}}`` (the file's ``"bounds"``).
        resolution: optional ``(width, height)`` every row must have (the bounds' resolution).
        waivers: ``{"scene/config label": reason}``: known cases where refinement does not beat ``average``
            (the file's ``"waivers"``); their MAE bounds still apply, and a waiver that is no longer needed
            is itself reported (remove it, e.g. with ``make regress-update``).
    Returns:
        One line per violation: an MAE above its bound (or not finite), a bound with no result, a result
        with no bound, a configuration whose best refined variant does not beat ``average`` on a scene
        (unless waived), a stale waiver, and rows at another resolution.
    """
    problems = []
    if resolution is not None and len(table):
        bad = table[(table.width != resolution[0]) | (table.height != resolution[1])]
        for (scene, w, h), _ in bad.groupby(["scene", "width", "height"]):
            problems.append(f"{scene}: frames are {w}x{h}, bounds were measured at {resolution[0]}x{resolution[1]}")
    got = measured_mae(table) if len(table) else {}
    have, want = _flatten(got), _flatten(bounds)
    for key in sorted(want.keys() | have.keys()):
        name = "/".join(key)
        if key not in have:
            problems.append(f"{name}: no result (bound {want[key]:.4f} m)")
        elif key not in want:
            problems.append(f"{name}: no bound (measured {have[key]:.4f} m; run `make regress-update`)")
        elif not math.isfinite(have[key]) or have[key] > want[key]:
            problems.append(f"{name}: MAE {have[key]:.4f} m > bound {want[key]:.4f} m "
                            f"({100 * (have[key] / want[key] - 1):+.1f}%)")
    for scene, configs in sorted(got.items()):
        for label, variants in sorted(configs.items()):
            if set(variants) == {FINAL}:  # a method, not a flow configuration: only its bound applies
                continue
            refined = {v: x for v, x in variants.items() if v != "average"}
            if "average" not in variants or not refined:
                problems.append(f"{scene}/{label}: cannot compare refinement with average "
                                f"(variants: {', '.join(sorted(variants))})")
                continue
            best = min(refined, key=lambda v: (refined[v], v))
            beats = refined[best] < variants["average"]
            waived = f"{scene}/{label}" in (waivers or {})
            if not beats and not waived:
                problems.append(f"{scene}/{label}: best refined variant {best} (MAE {refined[best]:.4f} m) "
                                f"does not beat average ({variants['average']:.4f} m)")
            elif beats and waived:
                problems.append(f"{scene}/{label}: waiver no longer needed, best refined variant {best} "
                                f"(MAE {refined[best]:.4f} m) beats average ({variants['average']:.4f} m); "
                                "remove it (make regress-update)")
    return problems


def needed_waivers(table: pd.DataFrame, waivers: Mapping[str, str]) -> dict[str, str]:
    """The subset of ``waivers`` still needed by ``table``: refinement still does not beat average there."""
    got = measured_mae(table) if len(table) else {}
    out = {}
    for key, reason in waivers.items():
        scene, _, label = key.partition("/")
        variants = got.get(scene, {}).get(label, {})
        refined = [x for v, x in variants.items() if v != "average"]
        if "average" in variants and refined and not min(refined) < variants["average"]:
            out[key] = reason
    return out


def make_bounds(table: pd.DataFrame, margin: float = DEFAULT_MARGIN, samples: int = BLENDER_SAMPLES,
                waivers: Mapping[str, str] | None = None) -> dict:
    """The bounds file's content: bound = measured MAE x (1 + margin), rounded up to 0.1 mm.

    ``waivers`` (``{"scene/config label": reason}``) are kept only where still needed (:func:`needed_waivers`).
    """
    if not margin >= 0:
        raise ValueError(f"margin must be >= 0, got {margin}")
    measured = measured_mae(table)
    bounds = {s: {c: {v: math.ceil(round(x * (1 + margin) * 1e4, 6)) / 1e4 for v, x in vs.items()}
                  for c, vs in cs.items()} for s, cs in measured.items()}
    rounded = {s: {c: {v: round(x, 6) for v, x in vs.items()} for c, vs in cs.items()} for s, cs in measured.items()}
    sizes = sorted({(int(w), int(h)) for w, h in zip(table.width, table.height, strict=True)})
    if len(sizes) != 1:
        raise ValueError(f"regression frames at several resolutions: {sizes}")
    frames = table.groupby("scene")["viewpoint"].nunique().sort_index()
    return {
        "format": "tri360-regression-bounds/1",
        "margin": margin,
        "resolution": list(sizes[0]),
        "blender_samples": samples,
        "seed": SEED,
        "frames": {s: int(n) for s, n in frames.items()},
        "unit": "MAE in metres, mean over the scene's frames; bound = measured x (1 + margin)",
        "generated": datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds"),
        "bounds": bounds,
        "measured": rounded,
        "waivers": needed_waivers(table, waivers or {}),
    }


def load_bounds(path: Path | str) -> dict:
    """Read a bounds file (see :func:`make_bounds`)."""
    path = Path(path)
    data = read_json_file(path, "regression bounds file", "no regression bounds (generate them with `make "
                                                          "regress-update`)")
    if not isinstance(data.get("bounds"), dict):
        raise ValueError(f"{path}: not a regression bounds file (no \"bounds\" mapping)")
    return data


def check_bounds_target(path: Path) -> None:
    """Refuse ``path`` as the bounds file ``--update`` writes unless it is absent or a bounds file (this tool never
    replaces another file), in an existing folder; checked before any rendering.

    Raises:
        ValueError: one line naming ``path``.
    """
    if path.exists() or path.is_symlink():
        load_bounds(path)  # a bounds file, or one line saying what it is not
    elif not path.parent.is_dir():
        raise ValueError(f"{path}: its folder does not exist")


def write_bounds(data: dict, path: Path | str) -> None:
    """Write the bounds file atomically, keys sorted so that diffs read well."""

    atomic_write_text(Path(path), json.dumps(data, indent=2, sort_keys=True) + "\n")


def main(argv: list[str] | None = None) -> int:
    parser = ArgumentParser(prog=PROG, description=__doc__.split("\n\n")[0])
    parser.add_argument("--update", action="store_true", help="re-run and rewrite the bounds file")
    parser.add_argument("--margin", type=float, default=DEFAULT_MARGIN,
                        help="with --update: bound = measured x (1 + margin) (default %(default)s)")
    parser.add_argument("--bounds", type=Path, required=True, metavar="FILE",
                        help="bounds file to check against (with --update: to write); the repository's is "
                             "tests/regression_bounds.json")
    parser.add_argument("--data", type=Path, default=None,
                        help="render the data set into (or reuse it from) this directory instead of a temporary one")
    parser.add_argument("--threads", type=int, default=0, help="Cycles threads (0 = all cores)")
    parser.add_argument("--waive", action="append", default=[], metavar="SCENE/CONFIG=REASON",
                        help="with --update: record a known case where refinement does not beat average "
                             "(kept while still needed; existing waivers are carried over)")
    args = parser.parse_args(argv)
    waivers = {}
    for item in args.waive:
        key, sep, reason = item.partition("=")
        if not sep or key.count("/") != 1 or not reason.strip():
            parser.error(f"--waive expects SCENE/CONFIG=REASON, got {item!r}")
        waivers[key] = reason.strip()
    if args.waive and not args.update:
        parser.error("--waive needs --update")

    try:  # fail before rendering anything
        if not args.update:
            data = load_bounds(args.bounds)
            width, height = data.get("resolution", [REGRESSION_WIDTH, REGRESSION_WIDTH // 2])
            samples = int(data.get("blender_samples", BLENDER_SAMPLES))
        else:
            check_bounds_target(args.bounds)
            width, height, samples = REGRESSION_WIDTH, REGRESSION_WIDTH // 2, BLENDER_SAMPLES
    except (OSError, ValueError) as exc:
        return user_error(PROG, exc)
    start = time.perf_counter()
    with tempfile.TemporaryDirectory(prefix="tri360-regression-") as tmp:
        table = run_regression(tmp, data=args.data, width=width, samples=samples, threads=args.threads,
                               ctx=RunContext())
    seconds = time.perf_counter() - start
    print(f"\nMAE (m), mean over each scene's frames, {width}x{height}, {seconds:.0f} s")
    print(measured_text(table))
    if args.update:
        if args.bounds.exists():
            waivers = {**load_bounds(args.bounds).get("waivers", {}), **waivers}
        content = make_bounds(table, args.margin, samples, waivers)
        write_bounds(content, args.bounds)
        print(f"\nwrote {args.bounds} (margin {args.margin})")
        for key in sorted(waivers.keys() - content["waivers"].keys()):
            print(f"dropped waiver {key}: refinement beats average there now (or no such result)")
        problems = check(table, content["bounds"], (width, height), content["waivers"])
        if problems:  # only the refined-vs-average rule can fire here
            print("\nthe bounds are written, but the check will still fail:", file=sys.stderr)
            for p in problems:
                print(f"  {p}", file=sys.stderr)
            return 1
        return 0
    problems = check(table, data["bounds"], (width, height), data.get("waivers", {}))
    if problems:
        print(f"\nREGRESSION: {len(problems)} violation(s) of {args.bounds}:", file=sys.stderr)
        for p in problems:
            print(f"  {p}", file=sys.stderr)
        return 1
    print(f"\nno regression: every MAE within {args.bounds}")
    return 0


if __name__ == "__main__":
    sys.exit(startup.run_main(main, "regression"))

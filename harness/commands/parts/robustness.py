"""The robustness study: every default method's MAE against each perturbation's level, on chosen frames.

A robustness study is a TOML file that ``tri360 study`` recognises by ``kind = "robustness"``
(:func:`is_robustness_study`; ``harness.commands.study.run_study`` hands it to :func:`run_robustness`)::

    kind = "robustness"
    data = "data-dev"                          # a data root (relative to the current directory)
    frames = ["seminar-s1011/vp000", ...]      # optional: <scene>/<viewpoint> labels; default: every frame
    method = ["fused", "dis-rect:gradient"]    # optional: default ROBUSTNESS_METHODS
    seed = 1                                   # optional: the perturbations' seed (default 0)

    [levels]                                   # per perturbation kind, its levels (level 0 is always run)
    rotation = [0.1, 0.25, 0.5, 1.0]
    jpeg = [95, 80, 60, 40]

:func:`run_robustness` writes into ``out`` (a robustness study directory):

- ``data/unperturbed/``: the chosen frames as they are (a copy, so that the unperturbed frames are evaluated
  like every other point: one data root, one results set), ``data/<kind>-<level>/``: the frames perturbed with
  that one kind at that level (``tri360 perturb``, :func:`harness.commands.perturb.perturb_frames`, the file's seed);
- ``results/unperturbed/``, ``results/<kind>-<level>/``: their results sets (``tri360 evaluate`` without report);
- ``robustness.csv``: one row per (kind, level, method, frame) and the unperturbed rows (kind ``none``, level 0):
  ``kind, level, unit, method, frame, mae_m, median_m, valid_px`` and ``mae_sw_m, valid_sr`` when present;
- ``robustness.md``: per kind a table method x level of the pooled MAE and the level at which each method's MAE
  doubles (:func:`reports.robustness.doubling_level`), and its plot ``<kind>.png`` (:func:`reports.robustness.
  level_plot`); ``points.json``: which point uses which directories.

Everything is checked before any work (:func:`load_robustness`: keys, kinds, levels through
:func:`harness.commands.perturb.parse_applies`, methods; then the data root, the frames and ``out``).  Reuse: a
perturbed frame is kept when it is complete and its provenance names the same source (SHA-256 of the source
frame's files), seed and perturbation; a results set is kept when it is complete, ran the same methods and its
frames' provenance matches too; so a rerun perturbs and evaluates nothing, and a longer list of levels only the
new points.
"""

from __future__ import annotations

import json
import time
import tomllib
from dataclasses import dataclass
from pathlib import Path

import pandas as pd

from harness.commands.evaluate import evaluate, scorable_frame, select_frames
from harness.commands.parts import perturbations as P
from harness.commands.perturb import checked_perturbation, frame_hash, parse_applies, perturb_frames
from harness.data import jsonio
from harness.data.atomic import atomic_write_bytes, atomic_write_text
from harness.data.errors import UserError
from harness.data.frame import find_frames, frame_dir, is_complete, read_frame
from harness.data.outputs import check_output, ensure_output_dir, mark_output
from harness.data.results import CONFIG_JSON, RESULTS_CSV, read_frames, read_results
from harness.runtime.context import IN_PROCESS, RunContext
from harness.runtime.options import MethodSelection, typed_value
from reconstruction.params import type_hints
from reports.robustness import NONE_KIND, format_level, kind_table, level_plot, pooled_mae, robustness_markdown

__all__ = ["KIND", "KEYS", "ROBUSTNESS_METHODS", "ORIGINS", "RobustnessSpec", "Point", "is_robustness_study",
           "load_robustness", "plan_points", "run_robustness"]

KIND = "robustness"
"""The ``kind`` key's value that makes a study file a robustness study."""
KEYS = ("kind", "data", "frames", "method", "seed", "levels")
"""The keys of a robustness study file."""
ROBUSTNESS_METHODS = ("fused-mirror", "fused", "sweep", "dis-rect:gradient")
"""The methods when the file names none: the default method (``fused-mirror``), ``fused``, the sweep alone and
tri360's flow pipeline with the paper's optimised variant.  The paper's set-up (``deepflow-rect:gradient``) can be
named; it is not a default because DeepFlow as published takes about 50 s per 1000x500 frame."""
ORIGINS = {"jpeg": 100}
"""Per kind whose severity grows as its level falls, the level the unperturbed frames stand at in tables, plots and
the doubling level (JPEG quality 100: the closest to no compression); every other kind: 0."""
UNPERTURBED = "unperturbed"
"""The directory name of the unperturbed point under ``data/`` and ``results/``."""


@dataclass(frozen=True)
class RobustnessSpec:
    """A parsed, checked robustness study file.

    Attributes:
        path: the file; text: its text.  data: the data root (relative paths: to the current directory).
        frames: the chosen ``<scene>/<viewpoint>`` labels, or None for every frame.  methods: the method labels.
        seed: the perturbations' seed.  levels: kind -> its levels, in the file's order (kinds in ``P.ORDER``).
    """

    path: Path
    text: str
    data: Path
    frames: tuple[str, ...] | None
    methods: tuple[str, ...]
    seed: int
    levels: dict[str, tuple]


@dataclass(frozen=True)
class Point:
    """One point of the study: a kind and level (``NONE_KIND``, 0: the unperturbed frames) and its directory
    name under ``data/`` and ``results/``."""

    kind: str
    level: float | int
    name: str

    @property
    def applies(self) -> list[tuple[str, float | int]]:
        return [] if self.kind == NONE_KIND else [(self.kind, self.level)]


def _read_toml(path: Path) -> tuple[str, dict]:
    try:
        text = Path(path).read_text(encoding="utf-8")
    except FileNotFoundError:
        raise UserError(f"{path}: study file does not exist") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise UserError(f"{path}: study file cannot be read ({exc})") from None
    try:
        return text, tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise UserError(f"{path}: not valid TOML ({exc})") from None


def is_robustness_study(path: Path) -> bool:
    """True when ``path`` is a readable TOML file whose top-level ``kind`` is ``"robustness"`` (anything else,
    unreadable files included, is left to the grid study's checks)."""
    try:
        _, raw = _read_toml(path)
    except UserError:
        return False
    return raw.get("kind") == KIND


def _levels(path: Path, raw) -> dict[str, tuple]:
    if not isinstance(raw, dict) or not raw:
        raise UserError(f"{path}: [levels] must be a table of kind = [level, ...] (kinds: {', '.join(P.ORDER)})")
    out = {}
    for kind, values in raw.items():
        where = f"{path}: [levels] {kind}"
        if kind not in P.KINDS:
            raise UserError(f"{where}: unknown perturbation kind {kind!r} (choose from {', '.join(P.ORDER)})")
        if not isinstance(values, list) or not values:
            raise UserError(f"{where}: must be a non-empty list of levels ({P.KINDS[kind]})")
        levels = []
        for i, value in enumerate(values):
            if isinstance(value, bool) or not isinstance(value, int | float):
                raise UserError(f"{where}[{i}]: a level must be a number ({P.KINDS[kind]}), got {value!r}")
            if value == 0:
                raise UserError(f"{where}[{i}]: level 0 (the unperturbed frames) is always run; list only "
                                "perturbed levels")
            ((_, level),) = parse_applies([f"{kind}={value}"], option=f"{where}[{i}]")
            levels.append(level)
        if len(set(levels)) != len(levels):
            raise UserError(f"{where}: lists a level twice")
        out[kind] = tuple(levels)
    return {k: out[k] for k in P.ORDER if k in out}


def load_robustness(path: Path) -> RobustnessSpec:
    """Read and check a robustness study file: every key (:data:`KEYS`), kind and level, and the methods.

    Raises:
        UserError: one line naming the file and the key: unreadable or malformed TOML, an unknown key, a value
            of the wrong type, an unknown kind, a level out of its kind's range (:func:`parse_applies`), a level
            given twice or 0, an unknown method.
    """
    path = Path(path)
    text, raw = _read_toml(path)
    unknown = sorted(set(raw) - set(KEYS))
    if unknown:
        raise UserError(f"{path}: unknown key(s) {', '.join(unknown)}; a robustness study has {', '.join(KEYS)}")
    if raw.get("kind") != KIND:
        raise UserError(f"{path}: kind must be {KIND!r}, got {raw.get('kind')!r}")
    if "data" not in raw:
        raise UserError(f"{path}: data: missing (the data root of the frames to perturb, e.g. data = \"data-dev\")")
    data = typed_value(raw["data"], str, f"{path}: data")
    frames = None
    if "frames" in raw:
        frames = typed_value(raw["frames"], tuple[str, ...], f"{path}: frames")
        bad = [f for f in frames if f.count("/") != 1 or "" in f.split("/")]
        if bad:
            raise UserError(f"{path}: frames: {bad[0]!r} is not a <scene>/<viewpoint> label")
        if len(set(frames)) != len(frames):
            raise UserError(f"{path}: frames: lists a frame twice")
    hint = type_hints(MethodSelection)["method"]
    methods = typed_value(raw.get("method", list(ROBUSTNESS_METHODS)), hint, f"{path}: method")
    try:
        labels = tuple(m.label for m in MethodSelection(method=methods).methods())
    except UserError as exc:
        raise UserError(f"{path}: method: {exc}") from None
    seed = typed_value(raw.get("seed", 0), int, f"{path}: seed")
    if seed < 0:
        raise UserError(f"{path}: seed must be a non-negative integer, got {seed}")
    if "levels" not in raw:
        raise UserError(f"{path}: [levels]: missing (per kind a list of levels, e.g. rotation = [0.1, 0.5])")
    return RobustnessSpec(path, text, Path(data), frames, labels, seed, _levels(path, raw["levels"]))


def plan_points(spec: RobustnessSpec) -> list[Point]:
    """The unperturbed point, then every (kind, level) in ``P.ORDER`` and the file's order of levels."""
    points = [Point(NONE_KIND, 0, UNPERTURBED)]
    for kind, levels in spec.levels.items():
        points += [Point(kind, level, f"{kind}-{format_level(level)}") for level in levels]
    return points


def _matches(renderer, source_sha: str, seed: int, point: Point) -> bool:
    """Whether a frame's ``renderer`` record says it is ``point``'s perturbation of the source with that hash."""
    rec = renderer.get("perturbation") if isinstance(renderer, dict) else None
    if not isinstance(rec, dict) or not isinstance(rec.get("source"), dict):
        return False
    applied = [(a.get("kind"), a.get("level")) for a in rec.get("applied", []) if isinstance(a, dict)]
    return (rec["source"].get("sha256") == source_sha and applied == point.applies
            and (not point.applies or rec.get("seed") == seed))


def _frame_reusable(target: Path, source_sha: str, seed: int, point: Point) -> bool:
    """A complete frame at ``target`` that is ``point``'s perturbation of the source with that hash."""
    return is_complete(target) and _matches(read_frame(target, load_distance=False).renderer, source_sha, seed,
                                            point)


def _select(spec: RobustnessSpec):
    """The chosen frames of the data root (``FrameRef``s), each with usable ground truth."""
    refs = select_frames(spec.data)
    if spec.frames is not None:
        by_label = {f"{r.scene}/{r.viewpoint}": r for r in refs}
        missing = [f for f in spec.frames if f not in by_label]
        if missing:
            raise UserError(f"{spec.path}: frames: {missing[0]!r} is not a frame of {spec.data}"
                            + (f" (and {len(missing) - 1} more)" if len(missing) > 1 else ""))
        refs = [by_label[f] for f in spec.frames]
    for ref in refs:
        scorable_frame(ref.path)
    return refs


def _check_told_rigs(spec: RobustnessSpec, refs, points: list[Point], out: Path) -> None:
    """Every calibration-error point gives every frame a told rig the frame format accepts (a ``translation``
    too large for the baseline's tolerance would otherwise stop the study hours in): checked before any work."""
    pose = [p for p in points if p.kind in ("rotation", "translation")]
    for r in refs if pose else ():
        frame = read_frame(r.path)
        for p in pose:
            checked_perturbation(r.path, frame, p.applies, spec.seed, out / "data" / p.name,
                                 option=f"{spec.path}: [levels] {p.kind} = {format_level(p.level)} (seed {spec.seed}):")


def _results_reusable(results: Path, labels: tuple[str, ...], expected: dict[tuple[str, str], str], seed: int,
                      point: Point) -> bool:
    """A complete results set of exactly ``labels`` on exactly the expected frames, whose provenance matches."""
    if not ((results / RESULTS_CSV).is_file() and (results / CONFIG_JSON).is_file()):
        return False
    try:
        frames = read_frames(results) or []
        config = json.loads((results / CONFIG_JSON).read_text(encoding="utf-8"))
    except (UserError, OSError, ValueError):
        return False
    if not isinstance(config, dict) or not isinstance(config.get("methods"), dict) \
            or not isinstance(config.get("frames"), list):
        return False
    if set(config["methods"]) != set(labels) or {(f["scene"], f["viewpoint"]) for f in frames} != set(expected):
        return False
    seen = set()
    for info in config["frames"]:
        key = (info.get("scene"), info.get("viewpoint")) if isinstance(info, dict) else None
        if key not in expected or not _matches(info.get("renderer"), expected[key], seed, point):
            return False
        seen.add(key)
    return seen == set(expected)


def run_robustness(study_path: Path, out: Path, ctx: RunContext = IN_PROCESS) -> pd.DataFrame:
    """Run (or resume, or extend) a robustness study into robustness study directory ``out`` (see the module doc).

    Returns:
        The ``robustness.csv`` table.
    Raises:
        UserError: a malformed study file, a missing data root or frame, a frame without ground truth, a data
            directory of the study that holds frames the file no longer chooses, an unusable ``out``, or
            anything ``perturb``/``evaluate`` refuses -- all but the last before anything is written.
    """
    started = time.time()
    ctx.check()
    spec = load_robustness(study_path)
    refs = _select(spec)
    out = Path(out)
    check_output(out, "robustness", [study_path, spec.data, *(r.path for r in refs)])
    points = plan_points(spec)
    wanted = {(r.scene, r.viewpoint) for r in refs}
    for p in points:  # frames of another selection would be evaluated with these: refuse before any work
        extra = [d for d in find_frames(out / "data" / p.name) if (d.parent.name, d.name) not in wanted]
        if extra:
            raise UserError(f"{extra[0]}: a frame the study file no longer chooses is in the study's data root "
                            f"{out / 'data' / p.name}; remove that directory (tri360 wrote it) or choose another --out")
    _check_told_rigs(spec, refs, points, out)
    out = ensure_output_dir(out)
    atomic_write_text(out / "points.json", jsonio.dumps(
        [{"kind": p.kind, "level": p.level, "data": f"data/{p.name}", "results": f"results/{p.name}"}
         for p in points]))
    hashes = {(r.scene, r.viewpoint): frame_hash(r.path) for r in refs}
    if ctx.progress:
        print(f"robustness: {len(points)} point(s) x {len(refs)} frame(s) x {len(spec.methods)} method(s)",
              flush=True)
    methods = MethodSelection(method=spec.methods).methods()
    with ctx.executor() as ex:
        for p in points:
            data, results = out / "data" / p.name, out / "results" / p.name
            todo = [r for r in refs if not _frame_reusable(frame_dir(data, r.scene, r.viewpoint),
                                                           hashes[(r.scene, r.viewpoint)], spec.seed, p)]
            if todo and ctx.progress:
                what = "copy" if not p.applies else f"perturb {p.kind}={format_level(p.level)}"
                print(f"robustness: {what} {len(todo)} frame(s) -> {data}", flush=True)
            if todo:  # the point's data root is built whole: every chosen frame (the reusable ones are the same)
                check_output(data, "data", [r.path for r in refs])
                perturb_frames([r.path for r in refs], data, p.applies, spec.seed)
            if not todo and _results_reusable(results, spec.methods, hashes, spec.seed, p):
                if ctx.progress:
                    print(f"robustness: reuse {results}", flush=True)
                continue
            if ctx.progress:
                print(f"robustness: evaluate {p.name} -> {results}", flush=True)
            evaluate(data, results, methods, report=False, ctx=ctx.on(ex))
    table = _rows(out, points, spec)
    atomic_write_text(out / "robustness.csv", table.to_csv(index=False))
    pooled = pooled_mae(table)
    tables, units, origins, plots = {}, {}, {}, {}
    for kind, levels in spec.levels.items():
        origins[kind], units[kind] = ORIGINS.get(kind, 0), P.KINDS[kind]
        tables[kind] = kind_table(pooled, kind, levels, origins[kind], spec.methods)
        plots[kind] = f"{kind}.png"
        atomic_write_bytes(out / plots[kind], level_plot(tables[kind], kind, units[kind], levels, origins[kind]))
    origin_note = "".join(f"; for {k} at level {ORIGINS[k]}" for k in ORIGINS if k in spec.levels)
    intro = (f"{len(refs)} frame(s) of `{spec.data}` ({', '.join(f'`{r.scene}/{r.viewpoint}`' for r in refs)}), "
             f"perturbation seed {spec.seed}; one kind at a time. MAE of camera C's distance in metres, pooled over "
             f"the frames' scored pixels. `none`: the unperturbed frames (measured once; plotted at level 0"
             f"{origin_note}). \"MAE doubles at\": the level at which the MAE reaches twice the unperturbed MAE, "
             "linearly interpolated between measured levels; `-`: not within the measured levels. Per-frame rows: "
             f"`robustness.csv`. Written in {time.time() - started:.0f} s (reused frames and results included).\n\n"
             f"```toml\n{spec.text.strip()}\n```")
    atomic_write_text(out / "robustness.md", robustness_markdown(f"Robustness study `{spec.path.name}`", intro,
                                                                 tables, units, origins, plots))
    mark_output(out, "robustness")
    return table


CSV_COLUMNS = ("kind", "level", "unit", "method", "frame", "mae_m", "median_m", "valid_px")
OPTIONAL_COLUMNS = ("mae_sw_m", "valid_sr")


def _rows(out: Path, points: list[Point], spec: RobustnessSpec) -> pd.DataFrame:
    """``robustness.csv``'s table from every point's results set."""
    tables = []
    for p in points:
        res = read_results(out / "results" / p.name)
        res = res[res["method"].isin(spec.methods)]
        cols = {"kind": p.kind, "level": p.level, "unit": P.KINDS.get(p.kind, ""), "method": res["method"],
                "frame": res["scene"] + "/" + res["viewpoint"]}
        part = pd.DataFrame(cols, index=res.index)
        for c in (*CSV_COLUMNS[5:], *OPTIONAL_COLUMNS):
            if c in res.columns:
                part[c] = res[c]
        tables.append(part)
    table = pd.concat(tables, ignore_index=True)
    if any(c in table.columns and table[c].isna().all() for c in OPTIONAL_COLUMNS):
        table = table.drop(columns=[c for c in OPTIONAL_COLUMNS if c in table.columns])
    return table

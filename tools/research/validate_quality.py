"""Validate the ground-truth-free quality measures against true error on frames with ground truth (rerunnable).

Run as::

    python -m tools.research.validate_quality DATA_ROOT --method LABEL --out DIR
        [--results RESULTS_SET [--results-label LABEL2]] [--calibration-frames 10] [--rotation 0.5] [--seed 1]
        [--frames N] [--quiet]

on a data root of frames with ground truth (a suite's split: ``tri360 render --suite suites/tri360-v1.toml
--split dev --out data-dev``; frames without ground truth are skipped, ``--frames N`` keeps the first N in
(scene, viewpoint) order).  Two checks, issue 19's:

1. **Ranking.**  Per frame, C's distance of method LABEL (a registered label) -- run here, or, with ``--results``,
   the distance map that a ``tri360 evaluate`` results set holds for the frame under ``--results-label`` (default
   LABEL), accepted only when that set's ``config.json`` records for it the configuration of LABEL (method labels
   aside: a selection run's candidate may become the registered default under another name; and a fused method's
   ``quality_flow``) -- goes through :func:`reconstruction.quality.assess` with the method's confidence and, for a
   method with a reference distance (``fused``'s family: its ``reference_method``, read from the same results set
   under that method's label, or run with it, :func:`reconstruction.methods.base.reference_distance`), the
   reference.  Over the validly predicted pixels with ground truth, the Spearman rank
   correlation ``rho`` of each measure (:data:`MEASURES`; and the method's own confidence, negated, where it gives
   one) with the true absolute error, and the measure's AUSE (:func:`reports.metrics.sparsification_curves`, the
   measure negated as the confidence: pixels removed most uncertain first).  A pixel whose measure is not a
   number counts as the most uncertain (as in the sparsification).  Per family (the frame's provenance names it;
   else the scene name up to ``-s<seed>``) and over all frames: the mean, median and minimum of the frames' rho,
   the share of frames with rho >= :data:`RHO_BAR`, and the rho and AUSE of the family's pixels pooled.  Also
   the rho of every product of uncertainty factors (:func:`factor_subsets` of
   :data:`reconstruction.quality.FACTORS`) and the one with the highest mean rho: how
   :data:`reconstruction.quality.UNCERTAINTY_FACTORS` is chosen on the suite's dev split.
2. **Calibration check.**  ``--calibration-frames`` frames, chosen round-robin over the families in sorted order
   (each family's frames in order), are perturbed in memory with ``--rotation`` degrees of rotation error of U
   and R and ``--seed`` (:func:`harness.commands.perturb.checked_perturbation`, as ``tri360 perturb --apply
   rotation=...`` does), the method is run on the perturbed frame, and the :func:`reconstruction.quality.
   calibration_score` of the exact frame (from the distance of part 1) and of the perturbed one are compared with
   :data:`reconstruction.quality.CALIBRATION_THRESHOLD`.  A frame is *separated* when the exact frame is not
   flagged and the perturbed one is.  The summary also gives the threshold that separates most of the checked
   frames (:func:`choose_threshold`): how ``CALIBRATION_THRESHOLD`` is chosen on the dev split.

``DIR`` (a quality validation directory: absent, empty or one validate_quality wrote, never a study; built in a
staging directory and swapped in whole) gets

- ``validation.csv``: one row per frame: ``scene, viewpoint, family, width, height, scored_px`` (pixels with
  ground truth), ``valid_px`` (of those, validly predicted: the pixels ranked), ``mae_m`` (as ``evaluate`` scores
  it), ``mae_valid_m`` (over the ranked pixels), ``rho:<m>`` and ``ause_m:<m>`` for every measure of
  :data:`MEASURES` and ``confidence`` (empty for a method without one), ``rho:factors:<a*b...>`` for every
  factor subset, ``uncertainty_median``,
  ``calibration_score`` and ``calibration_flagged`` of the exact frame;
- ``calibration.csv``: one row per checked frame: ``scene, viewpoint, family, rotation_deg, seed, exact_score,
  exact_flagged, perturbed_score, perturbed_flagged, separated, perturbed_mae_m``;
- ``validation.json``: the summary (per measure the statistics of the frames' rho; per family and over all
  frames those of ``uncertainty`` and the pooled figures; the calibration counts), the method's configuration,
  where the distances came from, the data root, tri360's version and commit;
- ``validation.md``: the tables, ready to paste (also printed at the end).

The statistics and ``validation.md`` (``MEASURES``, ``RHO_BAR``, ``factor_subsets``, ``choose_threshold``...) are
:mod:`reports.quality_validation`'s, pure; this script checks the input, runs the method, reads and writes the
files.  Everything is checked before the first method runs; a bad option, method, data root, results set or ``--out`` is
one line and exit status 2, Ctrl-C one line and 130, and either way ``DIR`` is left as it was.
"""

from __future__ import annotations

from harness.runtime import startup

if __name__ == "__main__":  # run as a script: Ctrl-C during the imports below is one line and 130
    startup.guard("validate_quality")

import re
import sys
import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from harness.commands.evaluate import (
    FrameRef,
    checked_maps,
    frame_labels,
    scorable_frame,
    select_frames,
)
from harness.commands.parts import perturbations as P
from harness.commands.perturb import checked_perturbation
from harness.data import jsonio
from harness.data.atomic import atomic_write_text
from harness.data.errors import UserError
from harness.data.exr import CONFIDENCE_CHANNEL, DISTANCE_CHANNEL, read_float_map
from harness.data.outputs import check_output, mark_output, staged_directory
from harness.data.provenance import software
from harness.data.results import map_paths, read_config, read_results_set
from harness.runtime.blind import run_blind
from harness.runtime.context import IN_PROCESS, RunContext
from harness.runtime.progress import progress_bar
from reconstruction.camera.rig import CAMERA_NAMES
from reconstruction.flow.backends import get_flow
from reconstruction.methods.base import Method, MethodInput, ReferencingMethod, reference_distance, with_references
from reconstruction.methods.registry import get_methods
from reconstruction.photometry import NO_CALIBRATION
from reconstruction.quality import (
    CALIBRATION_THRESHOLD,
    calibration_score,
)
from reports.metrics import summary
from reports.quality_validation import (
    FrameValidation,
    calibration_summary,
    frame_validation,
    number_text,
    ranking_summary,
    validation_markdown,
)
from tools.common import ArgumentParser

__all__ = ["FORMAT", "frame_family", "calibration_choice", "config_difference", "resolve_method",
           "ground_truth_frames", "stored_maps", "validate_quality", "main"]

FORMAT = "tri360-quality-validation/1"
"""The ``format`` of ``validation.json``."""
PROG = "validate_quality"


# ------------------------------------------------------------------------------------------------ pure parts


def frame_family(scene: str, labelled: str) -> str:
    """The family of a frame: ``labelled`` (what its provenance names, :func:`harness.commands.evaluate.frame_labels`)
    when not empty, else the scene name up to ``-s<seed>`` (a suite's naming, ``<family>[-<preset>]-s<seed>``),
    else the scene name."""
    if labelled:
        return labelled
    m = re.match(r"^(.+?)-s\d+$", scene)
    return m.group(1) if m else scene


def calibration_choice(keys: Sequence[tuple[str, str]], families: dict[tuple[str, str], str],
                       count: int) -> list[tuple[str, str]]:
    """``count`` frames (``(scene, viewpoint)`` keys) spread over the families: round-robin over the families in
    sorted order, each family's frames in sorted order; fewer when there are fewer frames."""
    queues: dict[str, list] = {}
    for k in sorted(keys):
        queues.setdefault(families[k], []).append(k)
    order = [queues[f] for f in sorted(queues)]
    out: list[tuple[str, str]] = []
    while len(out) < count and any(order):
        for q in order:
            if q and len(out) < count:
                out.append(q.pop(0))
    return out


#: configuration keys that do not change a method's distance map: labels (names, not behaviour: ``fused``'s flow
#: and sweep carry their own) and a fused method's ``quality_flow`` (what its quality is compared with)
_IGNORED_KEYS = ("label", "quality_flow")


def _without_labels(config) -> object:
    """A method configuration as it reads back from JSON, without the keys of :data:`_IGNORED_KEYS` in the method
    and in the methods inside it."""
    if isinstance(config, dict):
        return {k: _without_labels(v) for k, v in config.items() if k not in _IGNORED_KEYS}
    if isinstance(config, list):
        return [_without_labels(v) for v in config]
    return config


#: parameters added after results sets were first written, with the value that reproduces what came before: a
#: stored configuration without the key ran that way (a sweep's ``planes.mirror_tolerance``: no mirror test; its
#: cost's ``intensity_weight``: 1 and ``feature``: the intensity; a method's ``photometric``: the images as they are;
#: the values that were module constants or fixed defaults before they became parameters: the pre-pass flow (DIS
#: with its built-in parameters), the fits' pixel and match limits, the evidence's blocks, the rig fit's iterations,
#: the noise blur's cap and scale, DeepFlow's and DeepMatching's; the rig fit's ``confirm_factor``: no confirming
#: pass; a sweep's ``post.fill_space``: the inverse distance; its ``planes.room_labels``: no floor or ceiling family;
#: its ``planes.bound_penalty``: labels beyond the room bound forbidden (``bound_penalty_min_az``: the penalty at
#: every bearing); its ``refine_planes.wall_margin``: walls left
#: alone).  A key ``parent.key`` applies only inside a mapping stored under ``parent``.
_ADDED_KEYS = {"mirror_tolerance": 0.0, "intensity_weight": 1.0, "feature": "intensity",
               "photometric": NO_CALIBRATION.config(),
               "photometric.prepass_flow": NO_CALIBRATION.prepass_flow.config(), "photometric.max_fit_pixels": 15000,
               "photometric.longitude_blocks": 16, "photometric.min_block_samples": 50,
               "rig.iterations": 6, "rig.tukey_c": 4.685, "rig.max_matches": 40000, "rig.longitude_blocks": 16,
               "rig.min_block_samples": 50, "rig.hemispheres": 0.0, "photometric.hemispheres": 0.0,
               "rig.confirm_factor": 0,
               "max_noise_blur_px": 1.5, "noise_scale": 1, "post.fill_space": "inverse",
               "planes.room_labels": 0, "planes.room_spread": 0.2, "planes.bound_penalty": 0.0,
               "planes.bound_penalty_min_az": 0.0, "planes.wall_yaw": "normals", "occlusion": 0.0,
               "occlusion_min_share": 0.25, "refine_planes.wall_margin": 0.0, "refine_planes.wall_max_share": 0.03,
               "refine_planes.ceiling_edge": 0.0, "refine_planes.closed_max_share": 0.0,
               "refine_planes.closed_ceiling_share": 0.0,
               "flat_contrast": 0.0, "flat_weight": 1.0, "flat_sigma_px": 2.0, "flat_min_noise": 0.5,
               "normalized_weight": 0.0, "normalized_contrast": 1.0,
               "post.edge_radius_px": 0, "post.edge_sigma_color": 10.0, "post.edge_sigma_px": 5.0,
               "post.edge_jump": 0.05, "post.edge_reach_px": 4, "prior.contrast_noise": 0.0,
               "prior.frame_agreement_contrast": 0.0, "prior.epipole_cone_deg": 0.0,
               "prior.epipole_cone_noise_low": 0.0, "prior.epipole_cone_noise_high": 0.0,
               "prior.contrast_blur": 0.0, "prior.contrast_blur_floor": 0.0, "prior.contrast_max_blur_px": 3.0,
               "prior.epipole_cone_fb_low": 0.0, "prior.epipole_cone_fb_high": 0.0,
               "prior.epipole_cone_room": 0.0,
               **{f"params.{k}": v for k, v in {
                   "presmooth_sigma": 1.0, "mid_smoothing": 1.0, "post_smoothing": 1.0, "hog_sigmoid": 0.2,
                   "ninth_dim": 0.3, "cell_px": 4, "nlpow": 1.4, "reciprocal_px": 4.0, "alpha": 6.0, "beta": 390.0,
                   "gamma": 5.0, "delta": 0.5, "sigma": 0.6, "bk": 1.0, "eta": 0.95, "min_size": 25, "n_inner": 5,
                   "n_solver": 25, "sor_omega": 1.6}.items()}}


def _stored_flow(value):
    """A stored pre-pass flow in today's form: a name (how it was stored before) as that backend's configuration with
    its built-in parameters, which is what ran; a name no longer known, and anything else, as it is."""
    if not isinstance(value, str):
        return value
    try:
        return get_flow(value).config()
    except ValueError:
        return value


#: values stored in an earlier form, read in today's: ``photometric.prepass_flow`` was the pre-pass flow's name
_EARLIER_FORMS = {"photometric.prepass_flow": _stored_flow}


def _with_added_keys(stored, wanted, parent: str = "") -> object:
    """``stored`` with every key of :data:`_ADDED_KEYS` that ``wanted`` has at the same place and ``stored`` lacks
    set to its earlier value, and every value of :data:`_EARLIER_FORMS` in today's form (``parent``: the key
    ``stored`` is under)."""
    if isinstance(stored, dict) and isinstance(wanted, dict):
        out = {k: _with_added_keys(v, wanted.get(k), k) for k, v in stored.items()}
        for name, convert in _EARLIER_FORMS.items():
            where, _, k = name.rpartition(".")
            if where in ("", parent) and k in out:
                out[k] = convert(out[k])
        for name, value in _ADDED_KEYS.items():
            where, _, k = name.rpartition(".")
            if where in ("", parent) and k in wanted and k not in out:
                out[k] = value
        return out
    if isinstance(stored, list) and isinstance(wanted, list) and len(stored) == len(wanted):
        return [_with_added_keys(a, b, parent) for a, b in zip(stored, wanted, strict=True)]
    return stored


def config_difference(stored, wanted) -> str | None:
    """The first place where two method configurations (as JSON, every method ``label`` and a fused method's
    ``quality_flow`` ignored: they do not change the distance; ``kind`` looked at first; a key of
    :data:`_ADDED_KEYS` missing from ``stored`` read as its earlier value) differ:
    ``"sweep.planes.wall_labels: 9 vs 0"`` (``stored`` first), or None when they are equal."""
    wanted = _without_labels(jsonio.to_jsonable(wanted))
    stored = _with_added_keys(_without_labels(jsonio.to_jsonable(stored)), wanted)
    return _difference(stored, wanted, "")


def _difference(a, b, where: str) -> str | None:
    if isinstance(a, dict) and isinstance(b, dict):
        for k in sorted(set(a) | set(b), key=lambda k: (k != "kind", k)):
            if k not in a or k not in b:
                return f"{where}{k}: {'absent' if k not in a else 'present'} vs {'absent' if k not in b else 'present'}"
            d = _difference(a[k], b[k], f"{where}{k}.")
            if d is not None:
                return d
        return None
    if a == b:
        return None

    def short(x) -> str:
        r = repr(x)
        return r if len(r) <= 40 else r[:37] + "..."

    return f"{where.rstrip('.') or 'configuration'}: {short(a)} vs {short(b)}"


# --------------------------------------------------------------------------------------------------- inputs


def resolve_method(label: str) -> Method:
    """The registered method ``label``.

    Raises:
        UserError: an unknown label (the registry's message).
    """
    try:
        return get_methods([label])[0]
    except ValueError as exc:
        raise UserError(f"--method {label}: {exc}") from None


def ground_truth_frames(data_root: Path, count: int | None = None) -> tuple[list[FrameRef], list[FrameRef]]:
    """The frames under ``data_root`` that have ground truth, in (scene, viewpoint) order, the first ``count``
    of them (None: all), and the frames without ground truth (skipped).

    Raises:
        UserError: a missing data root, no frames, a malformed frame.json, duplicate frames
            (:func:`harness.commands.evaluate.select_frames`), or no frame with ground truth.
    """
    refs = sorted(select_frames(data_root), key=lambda r: (r.scene, r.viewpoint))
    with_gt = [r for r in refs if any((r.path / f"{n}.distance.exr").exists() for n in CAMERA_NAMES)]
    without = [r for r in refs if r not in with_gt]
    if not with_gt:
        raise UserError(f"{data_root}: no frame has ground-truth distance ({len(refs)} frame(s), e.g. "
                        f"{refs[0].path}); the validation needs true error (render frames with tri360 render)")
    return (with_gt if count is None else with_gt[:count]), without


@dataclass(frozen=True)
class StoredMaps:
    """Where a results set holds one frame's maps of the reused method: distance map, confidence map or None."""

    distance: Path
    confidence: Path | None


def stored_maps(results: Path, label: str, method: Method, refs: Sequence[FrameRef],
                renderers: dict[tuple[str, str], dict]) -> dict[tuple[str, str], StoredMaps]:
    """The maps that results set ``results`` holds for method ``label`` on each of ``refs``, checked before any
    work: its ``config.json`` records for ``label`` the configuration of ``method`` (labels and ``quality_flow``
    aside), it has a row of ``label`` and a distance map for every frame, and each frame it evaluated has the
    provenance (``renderer``) of the frame under the data root.

    Raises:
        UserError: one line naming the results set (or file) and the label.
    """
    rs = read_results_set(results)
    config = read_config(results)
    if config is None:
        raise UserError(f"{results / 'config.json'}: file is missing, so the configuration of {label!r} cannot be "
                        f"checked against {method.label!r}'s (leave out --results to run the method)")
    methods = config.get("methods", {})
    if label not in methods:
        raise UserError(f"--results {results}: records no method {label!r} (it has: "
                        f"{', '.join(sorted(methods)) or 'none'}); give --results-label")
    diff = config_difference(methods[label], method.config())
    if diff is not None:
        raise UserError(f"--results {results}: method {label!r} there was run with another configuration than "
                        f"{method.label!r} (first difference, there vs {method.label!r}: {diff}); leave out "
                        f"--results to run {method.label!r}")
    frames = {(f.get("scene"), f.get("viewpoint")): f for f in config.get("frames", []) if isinstance(f, dict)}
    table = rs.results[rs.results["method"] == label]
    rows = {(r.scene, r.viewpoint): r for r in table.itertuples(index=False)}
    out = {}
    for ref in refs:
        key = (ref.scene, ref.viewpoint)
        if key not in rows:
            raise UserError(f"--results {results}: holds no row of {label!r} for frame {ref.scene}/{ref.viewpoint} "
                            f"({ref.path})")
        known = frames.get(key, {}).get("renderer")
        if known is not None and jsonio.to_jsonable(known) != jsonio.to_jsonable(renderers[key]):
            raise UserError(f"--results {results}: its frame {ref.scene}/{ref.viewpoint} is not the one at "
                            f"{ref.path} (other provenance in frame.json); evaluate that data root, or leave out "
                            "--results")
        r = rows[key]
        dist, conf = map_paths(ref.scene, ref.viewpoint, label, flow=r.flow, rectify=r.rectify, variant=r.variant,
                               source=str(results / "results.csv"))
        if not (results / dist).is_file():
            raise UserError(f"{results / dist}: file is missing (the distance map of {label!r} for "
                            f"{ref.scene}/{ref.viewpoint})")
        out[key] = StoredMaps(results / dist, results / conf if (results / conf).is_file() else None)
    return out


def _read_stored(maps: StoredMaps, frame) -> tuple[np.ndarray, np.ndarray | None]:
    """The stored distance (and confidence) of ``frame``, refused (named) when not of the frame's size."""
    d = read_float_map(maps.distance, DISTANCE_CHANNEL)
    c = None if maps.confidence is None else read_float_map(maps.confidence, CONFIDENCE_CHANNEL)
    for path, arr in ((maps.distance, d), (maps.confidence, c)):
        if arr is not None and arr.shape != (frame.height, frame.width):
            raise UserError(f"{path}: a {arr.shape[1]}x{arr.shape[0]} map for the {frame.width}x{frame.height} "
                            f"frame {frame.path}")
    return d, c


def _run(method: Method, frame, reference: bool = True) -> tuple[np.ndarray, np.ndarray | None, np.ndarray | None]:
    """The method's distance, confidence and reference distance (:func:`reference_distance`; None when not
    ``reference``) of ``frame``, float32 as ``evaluate`` stores them (shapes checked by
    :func:`harness.commands.evaluate.checked_maps`)."""
    try:
        outputs = run_blind(frame, with_references([method]) if reference else [method])
        output = outputs[method.label]
        ref = reference_distance(MethodInput.of(frame), method, outputs) if reference else None
    except ValueError as exc:
        raise UserError(f"{frame.path}: {exc}") from None
    d, conf = checked_maps(frame, method, output)
    return (np.asarray(d, np.float32), None if conf is None else np.asarray(conf, np.float32),
            None if ref is None else np.asarray(ref, np.float32))


# ------------------------------------------------------------------------------------------------------ job


def _check_count(value, option: str, minimum: int) -> int:
    if isinstance(value, bool) or not isinstance(value, int | np.integer) or value < minimum:
        raise UserError(f"{option} must be an integer >= {minimum}, got {value!r}")
    return int(value)


def validate_quality(data_root: Path, method_label: str, out: Path, results: Path | None = None,
                     results_label: str | None = None, calibration_frames: int = 10, rotation: float = 0.5,
                     seed: int = 1, frames: int | None = None, ctx: RunContext = IN_PROCESS) -> tuple[dict, str]:
    """Run both checks of the module doc on ``data_root`` and write ``out``.

    Everything is checked before the first method runs: the options, the method, the frames and their ground
    truth, the reused results set, and ``out`` (:func:`harness.data.outputs.check_output`: a validation directory
    that is not an input, inside one or around one).

    Args:
        method_label: a registered method label.
        results: a results set whose maps of ``results_label`` (default ``method_label``) are used instead of
            running the method for part 1 (the calibration check always runs the method on the perturbed frames).
        calibration_frames: frames of the calibration check (0 = none; fewer when the data root has fewer).
        rotation: degrees of rotation error of U and R; seed: the perturbation's seed.
        frames: only the first N frames with ground truth (None = all).
    Returns:
        ``(validation.json's contents, validation.md's text)``.
    Raises:
        UserError: bad input (one line naming it), before any work where it can be known then.
    """
    started = time.time()
    data_root, out = Path(data_root), Path(out)
    method = resolve_method(method_label)
    try:
        rotation = float(P.parse_level("rotation", str(rotation)))
    except ValueError as exc:
        raise UserError(f"--rotation: {exc}") from None
    seed = _check_count(seed, "--seed", 0)
    calibration_frames = _check_count(calibration_frames, "--calibration-frames", 0)
    if frames is not None:
        frames = _check_count(frames, "--frames", 1)
    if results_label is not None and results is None:
        raise UserError("--results-label needs --results (the results set whose maps it names)")
    refs, skipped = ground_truth_frames(data_root, frames)
    results = None if results is None else Path(results)
    check_output(out, "validation", [data_root, *(r.path for r in refs), *([results] if results else [])])
    renderers = {}
    for ref in refs:  # every frame and its ground truth, before any work
        renderers[(ref.scene, ref.viewpoint)] = scorable_frame(ref.path).renderer
    infos = [{"scene": r.scene, "viewpoint": r.viewpoint, "renderer": renderers[(r.scene, r.viewpoint)]}
             for r in refs]
    labelled = frame_labels(infos)
    families = {k: frame_family(k[0], v["family"]) for k, v in labelled.items()}
    stored = None if results is None else stored_maps(results, results_label or method_label, method, refs,
                                                      renderers)
    ref_method = method.reference_method if isinstance(method, ReferencingMethod) else None
    ref_stored = None
    if results is not None and ref_method is not None:
        held = (read_config(results) or {}).get("methods", {})
        if ref_method.label not in held:
            raise UserError(f"--results {results}: holds no maps of {ref_method.label!r}, the method whose distance "
                            f"{method.label!r} hands back as its reference (evaluate it beside {method.label!r}, or "
                            "leave out --results)")
        ref_stored = {k: StoredMaps(m.distance, None)  # only its distance is used
                      for k, m in stored_maps(results, ref_method.label, ref_method, refs, renderers).items()}
    chosen = set(calibration_choice(list(families), families, calibration_frames))
    items: list[FrameValidation] = []
    calib_rows: list[dict] = []
    with staged_directory(out) as stage, progress_bar(len(refs) + len(chosen), "validate", "step",
                                                      ctx.progress) as bar:
        for ref in refs:
            key = (ref.scene, ref.viewpoint)
            frame = scorable_frame(ref.path)
            if stored:
                distance, confidence = _read_stored(stored[key], frame)
                reference = _read_stored(ref_stored[key], frame)[0] if ref_stored else None
            else:
                distance, confidence, reference = _run(method, frame)
            item = frame_validation(frame, distance, confidence, reference)
            item.row = {"scene": ref.scene, "viewpoint": ref.viewpoint, "family": families[key],
                        **{k: v for k, v in item.row.items() if k not in ("scene", "viewpoint")}}
            items.append(item)
            bar.set_postfix_str(f"{ref.scene}/{ref.viewpoint} rho {number_text(item.row['rho:uncertainty'])}")
            bar.update(1)
            if key not in chosen:
                continue
            told = checked_perturbation(ref.path, frame, [("rotation", rotation)], seed, stage, "--rotation")
            d_off = _run(method, told, reference=False)[0]
            off = calibration_score(told, d_off)["score"]
            exact = item.row["calibration_score"]
            exact_flag, off_flag = bool(exact > CALIBRATION_THRESHOLD), bool(off > CALIBRATION_THRESHOLD)
            calib_rows.append({"scene": ref.scene, "viewpoint": ref.viewpoint, "family": families[key],
                               "rotation_deg": rotation, "seed": seed, "exact_score": exact,
                               "exact_flagged": exact_flag, "perturbed_score": off, "perturbed_flagged": off_flag,
                               "separated": (not exact_flag) and off_flag,
                               "perturbed_mae_m": summary(d_off, told.distance["C"])["mae_m"]})
            bar.set_postfix_str(f"{ref.scene}/{ref.viewpoint} calibration {number_text(exact)} -> {number_text(off)}")
            bar.update(1)
        calib_rows.sort(key=lambda r: (r["family"], r["scene"], r["viewpoint"]))
        rows = [i.row for i in items]
        result = {
            "format": FORMAT, "software": software(), "created_unix_s": round(started, 3),
            "data_root": str(data_root.resolve()), "frames": len(refs),
            "skipped_without_ground_truth": [str(r.path) for r in skipped],
            "method": {"label": method.label, "configuration": method.config()},
            "distances": ({"source": "run"} if results is None else
                          {"source": "results set", "path": str(results.resolve()),
                           "label": results_label or method_label}),
            "ranking": ranking_summary(items, [r["family"] for r in rows]),
            "calibration": calibration_summary(calib_rows, rotation, seed, calibration_frames),
        }
        text = validation_markdown(result, rows, calib_rows)
        calib_columns = ["scene", "viewpoint", "family", "rotation_deg", "seed", "exact_score", "exact_flagged",
                         "perturbed_score", "perturbed_flagged", "separated", "perturbed_mae_m"]
        atomic_write_text(stage / "validation.csv", pd.DataFrame(rows).to_csv(index=False))
        atomic_write_text(stage / "calibration.csv",
                          pd.DataFrame(calib_rows, columns=calib_columns).to_csv(index=False))
        atomic_write_text(stage / "validation.json", jsonio.dumps(result))
        atomic_write_text(stage / "validation.md", text)
        mark_output(stage, "validation")
    return result, text


def main(argv: Sequence[str] | None = None) -> int:
    parser = ArgumentParser(prog=f"python -m tools.research.{PROG}", description=__doc__.splitlines()[0])
    parser.add_argument("data_root", type=Path, metavar="DATA_ROOT", help="data root of frames with ground truth")
    parser.add_argument("--method", required=True, metavar="LABEL", help="registered method label (e.g. fused)")
    parser.add_argument("--out", type=Path, required=True, metavar="DIR",
                        help="output directory (absent, empty or one validate_quality wrote)")
    parser.add_argument("--results", type=Path, default=None, metavar="RESULTS_SET",
                        help="read C's distance maps from this tri360 evaluate results set instead of running the "
                             "method (for the ranking; its config.json must record LABEL's configuration)")
    parser.add_argument("--results-label", default=None, metavar="LABEL2",
                        help="the method's label in the results set (default: LABEL)")
    parser.add_argument("--calibration-frames", type=int, default=10, metavar="K",
                        help="frames of the calibration check, round-robin over families (0 = none; default 10)")
    parser.add_argument("--rotation", type=float, default=0.5, metavar="DEG",
                        help="rotation error of U and R, degrees (default 0.5)")
    parser.add_argument("--seed", type=int, default=1, help="seed of the rotation error (default 1)")
    parser.add_argument("--frames", type=int, default=None, metavar="N",
                        help="only the first N frames with ground truth, in (scene, viewpoint) order")
    parser.add_argument("--quiet", action="store_true", help="no progress bar")
    args = parser.parse_args(argv)
    try:
        _, text = validate_quality(args.data_root, args.method, args.out, results=args.results,
                                   results_label=args.results_label, calibration_frames=args.calibration_frames,
                                   rotation=args.rotation, seed=args.seed, frames=args.frames,
                                   ctx=RunContext(progress=not args.quiet))
    except UserError as exc:
        print(f"{PROG}: error: {exc}", file=sys.stderr)
        return 2
    except OSError as exc:
        where = f"{exc.filename}: " if exc.filename is not None else ""
        print(f"{PROG}: error: {where}{exc.strerror or exc}", file=sys.stderr)
        return 2
    print(text, end="")
    return 0


if __name__ == "__main__":
    sys.exit(startup.run_main(main, "validate_quality"))

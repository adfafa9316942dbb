"""Dense optical-flow backends behind one interface.

A backend maps two equal-size 8-bit RGB images to a flow field ``(H, W, 2)`` float32 (du, dv in pixels,
from image 0 to image 1).  Equirect images wrap around: :func:`equirect_flow` pads both images with
columns copied from the opposite edge before calling the backend, so correspondences that cross the
left/right seam are found, then crops the result back to ``W`` columns.

A backend that handles the wrap itself (``wraps=True``: its solver treats columns as periodic, e.g.
``deepflow``, DeepFlow as published) gets the images unpadded.

A backend's ``params`` are every parameter that changes its flow, and what ``config.json`` records of it: those of
``deepflow`` are every field of :class:`~reconstruction.flow.deepflow.DeepFlowParams` and of its
:class:`~reconstruction.flow.deepmatching.DeepMatchingParams`, those of ``epicflow`` DeepMatching's and its padding
(:func:`backend_params`); a backend with other values is the same ``compute`` with other ``params``.

``oracle`` is not an image backend: it is the exact correspondence from ground-truth distance and lives in
:mod:`reconstruction.flow.matching`.  Outside packages add backends through the entry-point group
``tri360.flows`` (an entry point loads to a :class:`FlowBackend` or a list of them); :func:`discover_flows`
finds them.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import threading
from collections.abc import Callable
from dataclasses import dataclass, field

import cv2
import numpy as np

from reconstruction.camera.image_ops import grey, periodic_pad
from reconstruction.flow.deepflow import DeepFlowParams, deep_flow_both
from reconstruction.flow.deepmatching import DeepMatchingParams, Matches, deep_matching_both
from reconstruction.params import from_mapping
from reconstruction.plugins import Registry, collect_registry, shadow_message, unknown_name_message

__all__ = ["flow_registry", "refuse_shadowed_flow",
           "FlowBackend", "ORACLE", "RENAMED_FLOWS", "renamed_flow_note", "builtin_flows", "builtin_flow",
           "discover_flows", "get_flow", "available_flows", "equirect_flow", "MATCHING_PARAMS", "DEEPFLOW_PARAMS",
           "matching_params", "deepflow_params", "backend_params", "interpolate_matches"]


ENTRY_POINT_GROUP = "tri360.flows"
ORACLE = "oracle"
#: flow names that tri360 no longer accepts -> the name of the same backend now (an unknown-name message names it)
RENAMED_FLOWS = {"deepflowdm": "deepflow"}


def renamed_flow_note(name: str) -> str:
    """``"flow deepflowdm is now called deepflow"`` for a name of :data:`RENAMED_FLOWS`, else ``""``."""
    return f"flow {name} is now called {RENAMED_FLOWS[name]}" if name in RENAMED_FLOWS else ""


@dataclass(frozen=True)
class FlowBackend:
    """A dense flow method.

    Attributes:
        name: the ``--flow`` name.
        compute: ``compute(img0, img1, **params) -> (H, W, 2) float32`` on (H, W, 3) uint8 RGB images.
        description: one line for ``--help`` and reports.
        params: keyword parameters passed to ``compute`` (recorded in ``config.json``).
        min_width: the smallest equirect width, pixels, the backend was measured to work at.
        wraps: the backend treats columns as periodic itself (:func:`equirect_flow` then does not pad).
        warm_up: called once per process before the backend's first timed call (:meth:`prepare`): compiles (or
            loads from numba's cache) the kernels, so that a frame's flow seconds are the flow's and not the
            compiler's; None = nothing to prepare.
    """

    name: str
    compute: Callable[..., np.ndarray]
    description: str = ""
    params: dict = field(default_factory=dict)
    min_width: int = 16
    wraps: bool = False
    warm_up: Callable[[], None] | None = field(default=None, compare=False)

    def __call__(self, img0: np.ndarray, img1: np.ndarray) -> np.ndarray:
        return self.compute(img0, img1, **self.params)

    def prepare(self) -> None:
        """Run :attr:`warm_up` if this process has not run it yet (thread-safe)."""
        if self.warm_up is None:
            return
        with _WARM_LOCK:
            if self.warm_up not in _WARMED:
                self.warm_up()
                _WARMED.add(self.warm_up)

    def config(self) -> dict:
        """JSON-able description: name, description and parameters."""
        return {"name": self.name, "description": self.description, "params": dict(self.params)}

    def __hash__(self) -> int:
        """By name and parameters (the parameters are a dict), so that a frozen configuration holding a backend
        (a method's ``group_key``, :class:`reconstruction.photometry.PhotometricParams`) hashes."""
        return hash((self.name, json.dumps(self.params, sort_keys=True, default=repr)))


_WARM_LOCK = threading.Lock()
_WARMED: set = set()
"""The warm-up functions this process has run."""


def _warm_pair() -> tuple[np.ndarray, np.ndarray]:
    """A small textured (64, 128, 3) uint8 pair, the second the first shifted by 3 columns."""
    rng = np.random.default_rng(0)
    img = cv2.GaussianBlur((rng.random((64, 128, 3)) * 255).astype(np.uint8), (0, 0), 1.5)
    return img, np.ascontiguousarray(np.roll(img, 3, axis=1))


def _warm_matching() -> None:
    """DeepMatching's kernels, on a small pair."""
    deep_matching_both(*_warm_pair(), DeepMatchingParams())


def _warm_deepflow() -> None:
    """DeepMatching's and DeepFlow's kernels, on a small pair."""
    deep_flow_both(*_warm_pair(), DeepFlowParams())


def _opencv_deepflow(img0, img1):
    """OpenCV's DeepFlow: only the variational part of Weinzaepfel et al. 2013 (no DeepMatching, no matching term)."""
    return cv2.optflow.createOptFlow_DeepFlow().calc(grey(img0), grey(img1), None)


_MATCH_CACHE = threading.local()
"""Per thread (Dask workers run tasks on several threads): ``.pending`` holds the one reverse matching kept."""

_FLOW_CACHE = threading.local()
"""Per thread: ``.pending`` holds the one reverse DeepFlow kept."""


def _one_way_of_both(cache: threading.local, img0: np.ndarray, img1: np.ndarray, key: str, both):
    """The img0 -> img1 half of ``both(img0, img1) -> (forward, reverse)``: the pipeline asks for a pair's forward
    then its backward result, so the reverse is kept in ``cache`` (one per thread) and is the answer of the next
    call whose images are these swapped (``key``: what else the result depends on)."""
    wanted = _digest(img0, img1, extra=key)
    pending = getattr(cache, "pending", None)
    cache.pending = None
    if pending is not None and pending[0] == wanted:
        return pending[1]
    fwd, bwd = both(img0, img1)
    cache.pending = (_digest(img1, img0, extra=key), bwd)
    return fwd


def _digest(*arrays, extra: str = "") -> bytes:
    h = hashlib.blake2b(extra.encode(), digest_size=16)
    for a in arrays:
        h.update(str(a.shape).encode())
        h.update(np.ascontiguousarray(a).tobytes())
    return h.digest()


def cached_matches(img0: np.ndarray, img1: np.ndarray, params: DeepMatchingParams) -> Matches:
    """DeepMatching from img0 to img1; the reverse direction, computed with it, is kept for the next call
    (the pipeline asks for the forward then the backward flow of each pair: one matching serves both)."""
    return _one_way_of_both(_MATCH_CACHE, img0, img1, repr(params), lambda a, b: deep_matching_both(a, b, params))


#: DeepMatching's parameters as a backend's parameters: every field of :class:`DeepMatchingParams` but ``wrap`` (the
#: backend's own, which its flow step shares)
MATCHING_PARAMS = tuple(f.name for f in dataclasses.fields(DeepMatchingParams) if f.name != "wrap")
#: DeepFlow's as the ``deepflow`` backend's parameters: every field of :class:`DeepFlowParams` but ``wrap`` (the
#: backend's own) and ``matching`` (:data:`MATCHING_PARAMS`, beside them)
DEEPFLOW_PARAMS = tuple(f.name for f in dataclasses.fields(DeepFlowParams) if f.name not in ("wrap", "matching"))


def matching_params(wrap: bool = True, **params) -> DeepMatchingParams:
    """The :class:`DeepMatchingParams` of a backend's parameters: ``wrap`` and those of :data:`MATCHING_PARAMS`
    (one not given keeps its default; an integer given for a float becomes a float).

    Raises:
        ParamError: an unknown parameter or a value of the wrong type (:func:`reconstruction.params.from_mapping`).
    """
    return from_mapping(DeepMatchingParams, {**params, "wrap": wrap}, where="DeepMatching parameters")


def deepflow_params(wrap: bool = True, **params) -> DeepFlowParams:
    """The :class:`DeepFlowParams` of the ``deepflow`` backend's parameters: ``wrap`` (DeepFlow's and DeepMatching's)
    and those of :data:`DEEPFLOW_PARAMS` and :data:`MATCHING_PARAMS` (one not given keeps its default; an integer
    given for a float becomes a float).

    Raises:
        ParamError: an unknown parameter or a value of the wrong type (:func:`reconstruction.params.from_mapping`).
    """
    own = {k: params.pop(k) for k in DEEPFLOW_PARAMS if k in params}
    return from_mapping(DeepFlowParams, {**own, "wrap": wrap, "matching": matching_params(wrap, **params)},
                        where="DeepFlow parameters")


def backend_params(params: DeepFlowParams | DeepMatchingParams, **extra) -> dict:
    """The flat parameters of a backend built on DeepFlow or DeepMatching: every field of ``params`` (and of its
    matching), ``wrap`` once, then ``extra``; :func:`deepflow_params` and :func:`matching_params` read them back."""
    matching = params.matching if isinstance(params, DeepFlowParams) else params
    out = {k: getattr(matching, k) for k in MATCHING_PARAMS}
    if isinstance(params, DeepFlowParams):
        out.update({k: getattr(params, k) for k in DEEPFLOW_PARAMS})
    return {**out, "wrap": params.wrap, **extra}


def _deepflow(img0, img1, **params):
    """DeepFlow as published (Weinzaepfel et al. 2013): DeepMatching + the variational energy with its matching
    term; ``params``: :func:`deepflow_params`'s.

    The pipeline asks for each pair's forward then backward flow: the first call matches both ways and solves
    both flows at once (:func:`~reconstruction.flow.deepflow.deep_flow_both`, one thread each) and keeps the
    reverse flow for the next call, which returns it if its images are the first call's, swapped."""
    p = deepflow_params(**params)
    return _one_way_of_both(_FLOW_CACHE, img0, img1, repr(p), lambda a, b: deep_flow_both(a, b, p))


def interpolate_matches(img0: np.ndarray, img1: np.ndarray, p0: np.ndarray, p1: np.ndarray) -> np.ndarray:
    """Dense flow from sparse matches by OpenCV's edge-aware interpolator (EpicFlow's step).

    Args:
        img0, img1: (H, W, 3) uint8 images.
        p0, p1: (N, 2) float32 pixel positions (x, y) of N >= 4 matches, ``p0`` in ``img0``, ``p1`` in ``img1``.
    Returns:
        (H, W, 2) float32 flow of ``img0`` towards ``img1``, pixels.

    The interpolator fits each pixel from its ``k`` nearest matches (OpenCV's default 128); with fewer matches than
    ``k``, OpenCV 4.11 reads past its table of neighbours (undefined results or a crash, opencv_contrib issue 4195),
    so ``k`` is cut to N.
    """
    interp = cv2.ximgproc.createEdgeAwareInterpolator()
    interp.setK(min(interp.getK(), len(p0)))
    return interp.interpolate(img0, p0.reshape(-1, 1, 2), img1, p1.reshape(-1, 1, 2))


def _epicflow(img0, img1, wrap=True, pad=32, **matching):
    """EpicFlow route: DeepMatching matches (``wrap`` and ``matching``: :func:`matching_params`'s), OpenCV's
    edge-aware interpolation, OpenCV variational refinement.

    OpenCV's interpolator and refinement know no periodic boundary, so the matched images are padded by ``pad``
    columns from the opposite edge for those two steps.
    """
    dm = matching_params(wrap, **matching)
    m = cached_matches(img0, img1, dm)
    h, w = img0.shape[:2]
    pad = int(min(pad, w)) if wrap else 0

    a, b = (periodic_pad(np.ascontiguousarray(img), pad) for img in (img0, img1))
    if m.x0.size < 4:
        return np.zeros((h, w, 2), np.float32)
    p0 = np.stack([m.x0 + pad, m.y0], axis=1).astype(np.float32)
    p1 = np.stack([m.x1 + pad, m.y1], axis=1).astype(np.float32)
    dense = interpolate_matches(a, b, p0, p1)
    ref = cv2.VariationalRefinement_create()
    dense = ref.calc(grey(a), grey(b), dense)
    return np.ascontiguousarray(dense[:, pad:pad + w], np.float32)


_DIS_PRESETS = {"ultrafast": cv2.DISOPTICAL_FLOW_PRESET_ULTRAFAST, "fast": cv2.DISOPTICAL_FLOW_PRESET_FAST,
                "medium": cv2.DISOPTICAL_FLOW_PRESET_MEDIUM}


def _dis(img0, img1, preset="medium", finest_scale=0, patch_size=8, patch_stride=3, gd_iterations=25,
         var_iterations=10, var_alpha=10.0, spatial_propagation=True):
    """DIS flow (Kroeger et al. 2016): an OpenCV preset with a finer patch stride and variational refinement."""
    dis = cv2.DISOpticalFlow_create(_DIS_PRESETS[preset])
    dis.setFinestScale(finest_scale)
    dis.setPatchSize(patch_size)
    dis.setPatchStride(patch_stride)
    dis.setGradientDescentIterations(gd_iterations)
    dis.setVariationalRefinementIterations(var_iterations)
    dis.setVariationalRefinementAlpha(var_alpha)
    dis.setUseSpatialPropagation(spatial_propagation)
    return dis.calc(grey(img0), grey(img1), None)


def _farneback(img0, img1, pyr_scale=0.5, levels=5, winsize=21, iterations=5, poly_n=7, poly_sigma=1.5):
    """Farneback polynomial-expansion flow."""
    return cv2.calcOpticalFlowFarneback(grey(img0), grey(img1), None, pyr_scale=pyr_scale, levels=levels,
                                        winsize=winsize, iterations=iterations, poly_n=poly_n,
                                        poly_sigma=poly_sigma, flags=0)


def _rlof(img0, img1, min_grid_step=6, max_matches=30000):
    """Dense RLOF (Senst et al.), robust local flow interpolated densely (needs 3-channel 8-bit).

    OpenCV's sparse-to-dense step takes at most 32767 matches (``match_num < SHRT_MAX``: measured to fail above
    1452 px wide rectified, 1092 plain), so the seed grid step, pixels, grows with the image to keep the number
    of seeds below ``max_matches``; up to about 1000 x 1000 padded pixels it is OpenCV's default 6.
    """
    h, w = img0.shape[:2]
    step = max(int(min_grid_step), int(np.ceil(np.sqrt(h * w / float(max_matches)))))
    return cv2.optflow.calcOpticalFlowDenseRLOF(np.ascontiguousarray(img0), np.ascontiguousarray(img1), None,
                                                gridStep=(step, step))


def builtin_flows() -> list[FlowBackend]:
    """The flow backends tri360 ships (``rlof`` only where this OpenCV build has it)."""
    # min_width: the smallest equirect width at which matching (both pairs, forward and backward, rectified and
    # plain) runs with finite output, measured on synthetic frames: DIS fails below 16 ("Incorrect size of input"),
    # RLOF below 60 (it tries to allocate gigabytes)
    out = [
        FlowBackend("deepflow", _deepflow, "DeepFlow as published (Weinzaepfel et al. 2013): DeepMatching + the "
                    "variational energy with its matching term; periodic in longitude",
                    params=backend_params(DeepFlowParams()), min_width=60,
                    wraps=True, warm_up=_warm_deepflow),
        FlowBackend("deepflow-opencv", _opencv_deepflow, "OpenCV's DeepFlow: the variational energy only (no "
                    "DeepMatching, no matching term), on images padded at the seam", min_width=8),
        FlowBackend("epicflow", _epicflow, "DeepMatching + OpenCV edge-aware interpolation + variational refinement",
                    params=backend_params(DeepMatchingParams(), pad=32),
                    min_width=60, wraps=True, warm_up=_warm_matching),
        FlowBackend("dis", _dis, "OpenCV DIS, medium preset, stride 3, variational refinement",
                    params={"preset": "medium", "finest_scale": 0, "patch_size": 8, "patch_stride": 3,
                            "gd_iterations": 25, "var_iterations": 10, "var_alpha": 10.0,
                            "spatial_propagation": True}, min_width=16),
        FlowBackend("farneback", _farneback, "OpenCV Farneback polynomial expansion",
                    params={"pyr_scale": 0.5, "levels": 5, "winsize": 21, "iterations": 5, "poly_n": 7,
                            "poly_sigma": 1.5}, min_width=8),
    ]
    if hasattr(cv2, "optflow") and hasattr(cv2.optflow, "calcOpticalFlowDenseRLOF"):
        out.append(FlowBackend("rlof", _rlof, "OpenCV dense RLOF",
                               params={"min_grid_step": 6, "max_matches": 30000}, min_width=60))
    return out


def builtin_flow(name: str, params: dict) -> FlowBackend:
    """The built-in backend ``name`` (:func:`builtin_flows`) with ``params`` as its parameters, which must name
    every parameter it has and no other (a preset writes its flow's parameters out in full,
    :mod:`reconstruction.methods.presets`).

    Raises:
        ValueError: ``name`` is no built-in backend, or ``params`` lacks one of its parameters or has another.
    """
    flows = {b.name: b for b in builtin_flows()}
    if name not in flows:
        raise ValueError(f"no built-in flow {name!r} (built in: {', '.join(sorted(flows))})")
    base = flows[name]
    missing, unknown = sorted(set(base.params) - set(params)), sorted(set(params) - set(base.params))
    if missing or unknown:
        raise ValueError(f"flow {name}: parameters missing: {', '.join(missing) or 'none'}; unknown: "
                         f"{', '.join(unknown) or 'none'}")
    return dataclasses.replace(base, params=dict(params))


def flow_registry() -> Registry:
    """The built-in flow backends plus entry points of group ``tri360.flows`` (an outside backend whose name is taken
    is refused: :attr:`reconstruction.plugins.Registry.refused`)."""
    return collect_registry(builtin_flows(), ENTRY_POINT_GROUP, lambda b: isinstance(b, FlowBackend), "FlowBackend",
                            key=lambda b: b.name)


def discover_flows() -> tuple[dict[str, FlowBackend], dict[str, str]]:
    """Every image flow backend: the built-ins plus entry points of group ``tri360.flows``.

    Returns:
        ``(backends by name, errors by plugin source)``.
    """
    reg = flow_registry()
    return reg.entries, reg.errors


def refuse_shadowed_flow(name: str, reg: Registry | None = None) -> None:
    """ValueError naming the plugin when a refused outside backend also has ``name`` (asking for it is ambiguous)."""
    reg = flow_registry() if reg is None else reg
    if name in reg.refused:
        raise ValueError(shadow_message("flow", name, reg))


def available_flows() -> list[str]:
    """Names accepted by ``--flow``: the image backends plus ``oracle``."""
    return sorted([*discover_flows()[0], ORACLE])


def get_flow(name: str) -> FlowBackend:
    """Look up an image flow backend; raises ValueError listing the known names."""
    reg = flow_registry()
    refuse_shadowed_flow(name, reg)
    flows, errors = reg.entries, reg.errors
    if name not in flows:
        if renamed_flow_note(name):
            raise ValueError(renamed_flow_note(name))
        raise ValueError(unknown_name_message("flow", name, sorted([*flows, ORACLE]), errors, "flow plugins"))
    return flows[name]


def equirect_flow(backend: FlowBackend, img0: np.ndarray, img1: np.ndarray, pad: int) -> np.ndarray:
    """Flow between two equirect images, with ``pad`` columns of wrap-around on each side.

    Args:
        backend: the flow method.
        img0, img1: (H, W, 3) uint8 RGB.
        pad: columns copied from the opposite edge on both sides (0 <= pad <= W); the flow of a pixel
            whose match lies up to ``pad`` columns past the seam is then found directly.  Ignored (no padding)
            for a backend with ``wraps=True``, which handles the seam itself.
    Returns:
        (H, W, 2) float32 flow of img0's pixels; targets may lie outside [0, W) (the caller wraps them).
    """
    w = img0.shape[1]
    pad = 0 if backend.wraps else int(min(max(pad, 0), w))

    flow = backend(periodic_pad(img0, pad), periodic_pad(img1, pad))
    flow = np.asarray(flow, dtype=np.float32)
    if not np.isfinite(flow).all():
        flow = np.nan_to_num(flow, nan=0.0, posinf=0.0, neginf=0.0)
    return np.ascontiguousarray(flow[:, pad:pad + w])

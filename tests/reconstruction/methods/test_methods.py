"""The Method interface and the registries (methods, flows, variants): discovery, labels, every entry smoke-tested."""

from __future__ import annotations

import ast
import dataclasses
import inspect
import json
import textwrap

import numpy as np
import pytest

from reconstruction.flow.backends import (
    FlowBackend,
    builtin_flow,
    builtin_flows,
    deepflow_params,
    discover_flows,
    get_flow,
)
from reconstruction.flow.deepflow import DeepFlowParams
from reconstruction.flow.deepmatching import DeepMatchingParams
from reconstruction.methods import presets
from reconstruction.methods.base import (
    GroupedMethod,
    Method,
    MethodOutput,
    ReferencingMethod,
    flow_fields,
    method_groups,
    reference_distance,
    run_methods,
    with_references,
)
from reconstruction.methods.flow_pipeline import BuiltOnFlow, FlowMethod
from reconstruction.methods.prior_sweep import PriorSweepMethod
from reconstruction.methods.registry import (
    ABLATIONS,
    DEFAULT_METHOD,
    PRESETS,
    builtin_methods,
    discover_methods,
    evaluate_default_methods,
    flow_methods,
    get_methods,
    uncalibrated,
)
from reconstruction.methods.sweep import SweepMethod
from reconstruction.params import ParamError
from reconstruction.refine.lm import RefineConfig, builtin_variants, discover_variants, get_variant
from reports.metrics import summary

GROUPS = sorted({m.group_key[1:3] for m in builtin_methods() if isinstance(m, FlowMethod)}, key=str)
OTHER_BUILTINS = [m.label for m in builtin_methods() if not isinstance(m, FlowMethod)]
#: the smoke runs kept in ``make test-fast`` (the others are marked ``slow``): the default flow on rectified pairs and
#: the default method
FAST_GROUP, FAST_BUILTIN = ("dis", True), DEFAULT_METHOD


def _group_name(flow) -> str:
    return flow[0] if isinstance(flow, tuple) else flow


def test_the_fast_smoke_runs_are_registered():
    assert FAST_GROUP in {(_group_name(f), r) for f, r in GROUPS} and FAST_BUILTIN in OTHER_BUILTINS


def test_builtin_labels_are_stable_and_unique():
    labels = [m.label for m in builtin_methods()]
    assert len(labels) == len(set(labels))
    for label in ("dis-rect:gradient", "deepflow-rect:average", "deepflow-plain:average", "deepflow-opencv-plain:color",
                  "oracle-rect:color", "farneback-plain:angle", "fused-mirror", "fused", "sweep"):
        assert label in labels
    # the default's ablations and the defaults it grew from are built in
    for label in ("fused-mirror-raw", "fused-mirror-told-rig", "fused-mirror-raw-images", "fused-mirror-shared-falloff",
                  "fused-gated", "fused-adaptive"):
        assert label in labels and get_methods([label])[0].label == label
    assert [p.label for p in ABLATIONS] == [m.label for m in builtin_methods()[len(PRESETS):len(PRESETS) + 6]]
    assert [m.label for m in evaluate_default_methods()] == [
        "fused-mirror", "sweep", "dis-rect:average", "dis-rect:angle", "dis-rect:gradient", "dis-rect:color",
        "deepflow-rect:average", "deepflow-rect:angle", "deepflow-rect:gradient", "deepflow-rect:color"]
    # the paper's set-up is DeepFlow as published (DeepMatching, periodic in longitude) on rectified pairs
    paper = get_methods(["deepflow-rect:gradient"])[0]
    assert paper.rectify and paper.flow.wraps and paper.flow.params["wrap"] is True
    assert not get_methods(["deepflow-opencv-rect:gradient"])[0].flow.wraps


def test_presets_are_the_named_builtins_each_described_in_one_line():
    labels = [p.label for p in (*PRESETS, *ABLATIONS)]
    assert DEFAULT_METHOD in labels and len(labels) == len(set(labels))
    assert [m.label for m in builtin_methods() if not isinstance(m, FlowMethod)] == labels
    for p in PRESETS:
        assert p.build().label == p.label
        assert p.description and "\n" not in p.description and "default" not in p.description, p.label
    for p in ABLATIONS:
        assert p.build().label == p.label and p.description and "\n" not in p.description


def test_flow_method_fields_and_config_are_json():
    m = get_methods(["dis-rect:gradient"])[0]
    assert isinstance(m, Method)
    assert flow_fields(m) == {"flow": "dis", "rectify": True, "variant": "gradient"}
    cfg = json.loads(json.dumps(m.config()))
    assert cfg["flow"] == json.loads(json.dumps(m.flow.config()))  # the backend's parameters (presets_snapshot.json)
    assert cfg["refine"]["gradient"] is True and cfg["triangulation"]["d_max_m"] > 0


def test_unknown_names_are_one_clear_message():
    with pytest.raises(ValueError, match="unknown method.*nope-rect:x.*named methods: fused-mirror, .*sweep.*"
                                         "dis-rect:gradient.*tri360 methods") as err:
        get_methods(["nope-rect:x"])
    assert "outside" not in str(err.value) and "\n" not in str(err.value)
    # a renamed flow: one line naming the label now
    with pytest.raises(ValueError, match=r"^deepflowdm-rect:gradient is now called deepflow-rect:gradient$"):
        get_methods(["deepflowdm-rect:gradient"])
    with pytest.raises(ValueError, match=r"^flow deepflowdm is now called deepflow$"):
        flow_methods(["deepflowdm"], [True])
    with pytest.raises(ValueError, match="unknown method.*nope.*deepflowdm-plain:average is now called "
                                         "deepflow-plain:average"):
        get_methods(["nope", "deepflowdm-plain:average"])
    with pytest.raises(ValueError, match="unknown flow 'nope'.*dis"):
        flow_methods(["nope"], [True])
    with pytest.raises(ValueError, match="unknown variant 'bogus'.*gradient"):
        flow_methods(["dis"], [True], ["bogus"])
    with pytest.raises(ValueError, match="unknown variant 'bogus'"):
        get_variant("bogus")


@pytest.mark.parametrize("flow, rectify", [
    pytest.param(f, r, marks=() if (_group_name(f), r) == FAST_GROUP else pytest.mark.slow) for f, r in GROUPS],
    ids=[f"{_group_name(f)}-{r}" for f, r in GROUPS])
def test_every_registered_method_runs(synthetic_frame, flow, rectify):
    """Registry smoke test: every built-in method gives a finite (H, W) float32 map of the scene's scale.

    On the 200 x 100 synthetic frame (mean distance 2.26 m) the oracle is exact; rectified image flows were
    measured at MAE 0.05-0.51 m (bound: 30 % of the mean distance); plain equirect flows, which fail near the
    poles at this size, at 0.53-2.94 m (bound: twice the mean distance, i.e. the right scale, not garbage)."""
    members = [m for m in builtin_methods() if isinstance(m, FlowMethod) and m.group_key[1:3] == (flow, rectify)]
    assert len(members) == 1 + len(builtin_variants())
    outs = run_methods(synthetic_frame, members)
    gt = synthetic_frame.distance["C"]
    for m in members:
        out = outs[m.label]
        assert isinstance(out, MethodOutput)
        assert out.distance.shape == gt.shape and out.distance.dtype == np.float32
        assert np.isfinite(out.distance).all() and out.total_seconds > 0
        mae = summary(out.distance, gt)["mae_m"]
        mean = float(np.mean(gt[np.isfinite(gt)]))
        if m.flow_name == "oracle":
            assert mae < (5e-3 if m.variant.startswith("color") else 1e-3), m.label
        else:
            assert mae < (0.3 if m.rectify else 2.0) * mean, (m.label, mae)


@pytest.mark.parametrize("label", [pytest.param(x, marks=() if x == FAST_BUILTIN else pytest.mark.slow)
                                   for x in OTHER_BUILTINS])
def test_every_other_builtin_method_runs(synthetic_frame, label):
    """Registry smoke test for the built-ins that are not the flow pipeline: a finite (H, W) float32 map within
    30 % of the mean distance in MAE, and a confidence in [0, 1] if one is given."""
    (m,) = get_methods([label])
    out = m.run(synthetic_frame)
    gt = synthetic_frame.distance["C"]
    assert out.distance.shape == gt.shape and out.distance.dtype == np.float32
    assert np.isfinite(out.distance).all()
    assert summary(out.distance, gt)["mae_m"] < 0.3 * float(np.mean(gt[np.isfinite(gt)]))
    if out.confidence is not None:
        assert out.confidence.shape == gt.shape and 0 <= out.confidence.min() and out.confidence.max() <= 1
    json.dumps(m.config())


@pytest.mark.slow
def test_grouped_run_equals_single_runs(synthetic_frame):
    """Sharing the flow stage across variants changes nothing: the grouped result equals each method alone
    (within 1 micrometre: OpenCV's multi-threaded filters can differ by one float32 ulp between runs)."""
    members = flow_methods(["dis"], [True], ["average", "angle"])
    grouped = run_methods(synthetic_frame, members)
    for m in members:
        np.testing.assert_allclose(grouped[m.label].distance, m.run(synthetic_frame).distance, rtol=0, atol=1e-6)


class ConstantMethod:
    """An outside method: predicts a constant distance (metres)."""

    def __init__(self, label: str, value: float):
        self.label, self.value = label, value

    def config(self) -> dict:
        return {"kind": "constant", "value": self.value}

    def run(self, frame) -> MethodOutput:
        return MethodOutput(np.full((frame.height, frame.width), self.value, np.float32), seconds={"total": 0.001})


def test_run_methods_keeps_order_and_runs_outside_methods(synthetic_frame):
    methods = [ConstantMethod("const-2", 2.0), *flow_methods(["oracle"], [True], ["average"])]
    outs = run_methods(synthetic_frame, methods)
    assert list(outs) == ["const-2", "oracle-rect:average"]
    assert float(outs["const-2"].distance.mean()) == 2.0
    assert flow_fields(methods[0]) == {"flow": "", "rectify": "", "variant": ""}


class SharedMethod(ConstantMethod):
    """An outside method that shares work with the others of its ``group_key`` (a :class:`GroupedMethod`)."""

    calls: list[list[str]] = []

    def __init__(self, label: str, value: float, key: str):
        super().__init__(label, value)
        self.group_key = key

    def run_group(self, frame, members, on_stage=None) -> dict[str, MethodOutput]:
        SharedMethod.calls.append([m.label for m in members])
        return {m.label: m.run(frame) for m in members}


class KeyOnly(ConstantMethod):
    """A ``group_key`` without ``run_group``: no :class:`GroupedMethod`, so a group of its own."""

    group_key = "flow-pipeline"


def test_the_builtin_grouped_and_referencing_methods_implement_their_protocols():
    methods = builtin_methods()
    flows = [m for m in methods if isinstance(m, FlowMethod)]
    fused = [m for m in methods if isinstance(m, PriorSweepMethod)]
    assert flows and fused
    for m in flows:
        assert isinstance(m, GroupedMethod) and not isinstance(m, BuiltOnFlow | ReferencingMethod), m.label
    for m in fused:
        assert isinstance(m, GroupedMethod) and isinstance(m, BuiltOnFlow) and isinstance(m, ReferencingMethod)
        assert m.group_key == m.flow.group_key and isinstance(m.reference_method, FlowMethod), m.label
    # every other built-in (the sweep) is a plain Method: a group of its own, without a reference
    others = [m for m in methods if not isinstance(m, FlowMethod | PriorSweepMethod)]
    assert others and all(isinstance(m, SweepMethod) for m in others)
    assert not any(isinstance(m, GroupedMethod | ReferencingMethod) for m in others)


def test_a_method_with_only_label_config_and_run_is_a_group_of_its_own(synthetic_frame):
    const, key_only = ConstantMethod("const-2", 2.0), KeyOnly("key-only", 3.0)
    a, b = flow_methods(["oracle"], [True], ["average", "angle"])
    assert isinstance(const, Method) and not isinstance(const, GroupedMethod | ReferencingMethod)
    assert isinstance(key_only, Method) and not isinstance(key_only, GroupedMethod)
    groups = method_groups([const, a, key_only, b, KeyOnly("key-only-2", 4.0), ConstantMethod("const-3", 3.0)])
    assert [[m.label for m in g] for g in groups] == [["const-2"], [a.label, b.label], ["key-only"], ["key-only-2"],
                                                      ["const-3"]]
    assert with_references([const]) == [const]
    outs = run_methods(synthetic_frame, [const, key_only])
    assert [float(o.distance.mean()) for o in outs.values()] == [2.0, 3.0]
    assert reference_distance(synthetic_frame, const, outs) is None
    with pytest.raises(TypeError, match="neither of the flow pipeline nor built on it.*const-2"):
        a.run_group(synthetic_frame, [a, const])


def test_an_outside_grouped_method_runs_its_group_once(synthetic_frame):
    SharedMethod.calls.clear()
    methods = [SharedMethod("s1", 1.0, "k"), ConstantMethod("c", 2.0), SharedMethod("s2", 3.0, "k"),
               SharedMethod("t", 4.0, "other")]
    assert all(isinstance(m, GroupedMethod) for m in methods if isinstance(m, SharedMethod))
    outs = run_methods(synthetic_frame, methods)
    assert SharedMethod.calls == [["s1", "s2"], ["t"]]
    assert {k: float(o.distance.mean()) for k, o in outs.items()} == {"s1": 1.0, "c": 2.0, "s2": 3.0, "t": 4.0}
    assert list(outs) == ["s1", "c", "s2", "t"]


@pytest.fixture
def plugin_dist(tmp_path, monkeypatch):
    """A real installed distribution (a .dist-info on sys.path) declaring tri360 entry points."""
    (tmp_path / "tri360_test_plugin.py").write_text(textwrap.dedent("""
        import numpy as np
        from reconstruction.flow.backends import FlowBackend
        from reconstruction.methods.base import MethodOutput
        from reconstruction.refine.lm import RefineConfig

        class Half:
            label = "half-gt"
            def config(self):
                return {"kind": "half"}
            def run(self, frame):
                return MethodOutput(frame.distance["C"] / 2, seconds={"total": 0.0})

        METHODS = [Half()]
        FLOW = FlowBackend("zero", lambda a, b: np.zeros(a.shape[:2] + (2,), np.float32), "no motion")
        VARIANT = RefineConfig("angle4", angle_power=4.0, description="steeper angle weights")
        BROKEN = 42
    """))
    info = tmp_path / "tri360_test_plugin-0.1.dist-info"
    info.mkdir()
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: tri360-test-plugin\nVersion: 0.1\n")
    (info / "entry_points.txt").write_text(textwrap.dedent("""
        [tri360.methods]
        half = tri360_test_plugin:METHODS
        [tri360.flows]
        zero = tri360_test_plugin:FLOW
        [tri360.variants]
        angle4 = tri360_test_plugin:VARIANT
        broken = tri360_test_plugin:BROKEN
    """))
    monkeypatch.syspath_prepend(str(tmp_path))
    return tmp_path


def test_entry_points_extend_every_registry(plugin_dist, synthetic_frame):
    flows, _ = discover_flows()
    assert "zero" in flows and {b.name for b in builtin_flows()} <= set(flows)
    variants, errors = discover_variants()
    assert isinstance(variants["angle4"], RefineConfig)
    assert any("broken" in k and "expected RefineConfig" in v for k, v in errors.items())
    methods, _ = discover_methods()
    assert "half-gt" in methods and "zero-rect:angle4" in methods
    half = get_methods(["half-gt"])[0]
    out = half.run(synthetic_frame)
    np.testing.assert_allclose(out.distance, synthetic_frame.distance["C"] / 2)
    # label, config() and run() only: a group of its own beside the built-ins, run unchanged
    assert not isinstance(half, GroupedMethod | ReferencingMethod)
    flows = flow_methods(["oracle"], [True], ["average"])
    outs = run_methods(synthetic_frame, [half, *flows])
    assert list(outs) == ["half-gt", "oracle-rect:average"] and len(method_groups([half, *flows])) == 2
    np.testing.assert_allclose(outs["half-gt"].distance, synthetic_frame.distance["C"] / 2)
    with pytest.raises(ValueError, match="variant plugins that failed to load.*broken"):
        get_variant("nope")


def test_flow_backend_parameters_reach_compute():
    seen = {}

    def compute(a, b, scale=1.0):
        seen["scale"] = scale
        return np.zeros(a.shape[:2] + (2,), np.float32)

    backend = FlowBackend("p", compute, params={"scale": 3.0})
    backend(np.zeros((4, 8, 3), np.uint8), np.zeros((4, 8, 3), np.uint8))
    assert seen == {"scale": 3.0} and backend.config()["params"] == {"scale": 3.0}
    assert FlowMethod(backend).label == "p-rect:average"


def test_deepflow_and_deepmatching_parameters_are_the_backends_and_reach_them():
    """Every field of DeepFlowParams and of its DeepMatchingParams is a parameter of the ``deepflow`` backend (so
    ``config.json`` records it) and a changed one reaches the solver's parameters."""
    params = get_flow("deepflow").params
    assert deepflow_params(**params) == DeepFlowParams()
    deepflow_fields = {f.name for f in dataclasses.fields(DeepFlowParams)} - {"matching"}
    matching_fields = {f.name for f in dataclasses.fields(DeepMatchingParams)}
    assert set(params) == deepflow_fields | matching_fields
    assert set(get_flow("epicflow").params) == matching_fields | {"pad"}
    config = get_methods(["deepflow-rect:gradient"])[0].config()["flow"]["params"]
    assert config["alpha"] == 6.0 and config["n_solver"] == 25 and config["hog_sigmoid"] == 0.2
    changed = deepflow_params(**{**params, "alpha": 3.0, "cell_px": 2, "wrap": False})
    assert (changed.alpha, changed.matching.cell_px, changed.wrap, changed.matching.wrap) == (3.0, 2, False, False)
    assert isinstance(deepflow_params(**{**params, "alpha": 3}).alpha, float)  # an integer for a float: a float
    with pytest.raises(ParamError, match=r"^DeepMatching parameters: cel_px: expected one of the keys .*, got an "):
        deepflow_params(**{**params, "cel_px": 2})
    with pytest.raises(ParamError, match=r"^DeepFlow parameters: n_solver: expected an integer, got 25\.0$"):
        deepflow_params(**{**params, "n_solver": 25.0})


def test_a_builtin_flow_takes_every_parameter_or_none():
    dis = get_flow("dis")
    assert builtin_flow("dis", dict(dis.params)) == dis
    with pytest.raises(ValueError, match="flow dis: parameters missing: preset; unknown: none"):
        builtin_flow("dis", {k: v for k, v in dis.params.items() if k != "preset"})
    with pytest.raises(ValueError, match="missing: none; unknown: bogus"):
        builtin_flow("dis", {**dis.params, "bogus": 1})
    with pytest.raises(ValueError, match="no built-in flow 'nope'"):
        builtin_flow("nope", {})


# ------------------------------------------------------------------------------------------ presets as data

#: the dataclasses of a method's configuration that a preset must write out in full
PARAMETER_CLASSES = {"PriorSweepMethod", "FlowMethod", "SweepMethod", "CostParams", "PlaneParams", "SgmParams",
                     "PostParams", "PriorParams", "PhotometricParams", "RigParams", "TriangulationLimits",
                     "RefineConfig", "PlaneRefineParams"}


def preset_problems(source: str, namespace: dict, preset_functions: set[str]) -> tuple[list[str], set[str]]:
    """What keeps ``source`` (a presets module) from writing its presets out in full: a call of a dataclass of
    ``namespace`` (but :class:`~reconstruction.methods.presets.Preset`, the table) that leaves a field to its default,
    passes one positionally or unpacks ``**``; a call of a preset function; any ``replace(...)``.

    Returns:
        ``(problems, the dataclasses called)``.
    """
    problems, called = [], set()
    for node in ast.walk(ast.parse(source)):
        if not isinstance(node, ast.Call):
            continue
        name = node.func.id if isinstance(node.func, ast.Name) else getattr(node.func, "attr", "")
        if name == "replace":
            problems.append(f"line {node.lineno}: replace(...) derives a value from another")
        if name in preset_functions:
            problems.append(f"line {node.lineno}: calls the preset {name}")
        target = namespace.get(name)
        if not (isinstance(target, type) and dataclasses.is_dataclass(target)) or target is presets.Preset:
            continue
        called.add(name)
        given = [k.arg for k in node.keywords]
        if node.args or None in given:
            problems.append(f"line {node.lineno}: {name} with positional or ** arguments")
        missing = sorted({f.name for f in dataclasses.fields(target) if f.init} - set(given))
        if missing:
            problems.append(f"line {node.lineno}: {name} leaves {', '.join(missing)} to the defaults")
    return problems, called


def test_every_preset_is_written_out_in_full():
    """presets.py gives every field of every parameter dataclass in every preset (no default enters a preset
    unseen), builds no preset from another, and derives nothing with ``replace``; each preset's flow gives every
    parameter of its backend (:func:`builtin_flow` refuses a missing one when the preset is built)."""
    functions = {p.build.__name__ for p in (*PRESETS, *ABLATIONS)}
    problems, called = preset_problems(inspect.getsource(presets), vars(presets), functions)
    assert problems == []
    assert called == PARAMETER_CLASSES
    assert [p.build().label for p in (*PRESETS, *ABLATIONS)] == [p.label for p in (*PRESETS, *ABLATIONS)]


def test_the_preset_check_catches_a_default_a_positional_argument_and_a_derived_preset():
    source = textwrap.dedent("""
        def a():
            return SgmParams(p1=1, p2=2, p3=3, edge=4.0)
        def b():
            return SgmParams(1, p2=2, p3=3, edge=4.0, paths=8)
        def c():
            return dataclasses.replace(a(), label="c")
    """)
    problems, _ = preset_problems(source, vars(presets), {"a", "b", "c"})
    assert problems == ["line 3: SgmParams leaves paths to the defaults",
                        "line 5: SgmParams with positional or ** arguments",
                        "line 5: SgmParams leaves p1 to the defaults",
                        "line 7: replace(...) derives a value from another", "line 7: calls the preset a"]


def test_the_raw_ablation_is_the_default_uncalibrated():
    """``uncalibrated`` (``tools.bench.sweep``'s ``<label>-raw``) of the default is the written-out
    ``fused-mirror-raw``."""
    assert uncalibrated(presets.fused_mirror()) == presets.fused_mirror_raw()

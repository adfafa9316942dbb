"""The selection of the default's floor and ceiling families and room bound: the candidates, and bad input."""

from __future__ import annotations

import pytest

from harness.data.errors import UserError
from reconstruction.methods.presets import fused_mirror
from tools.research.select_planes import CANDIDATES, REFERENCE, candidate_methods, main, planes_method


def test_candidates_the_reference_first_and_the_default_once():
    methods = candidate_methods()
    labels = [m.label for m in methods]
    assert labels[0] == "fused-mirror-planes-0-0.2-0.25" and labels[-1] == "fused-mirror"
    assert len(set(labels)) == len(labels) and len(methods) <= len(CANDIDATES) + 2
    ref = methods[0]
    p = ref.sweep.planes
    assert (p.room_labels, p.room_spread, p.bound_margin) == REFERENCE
    # everything but the three values is the default's
    default = fused_mirror()
    m = planes_method(9, 0.1, 0.15)
    p = m.sweep.planes
    assert (p.room_labels, p.room_spread, p.bound_margin) == (9, 0.1, 0.15)
    assert m.flow == default.flow and m.prior == default.prior and m.sweep.cost == default.sweep.cost
    assert m.sweep.sgm == default.sweep.sgm and m.sweep.post == default.sweep.post
    assert m.sweep.planes.wall_labels == default.sweep.planes.wall_labels
    assert [x.label for x in candidate_methods(["9-0.1-0.25"])][1:-1] in ([], ["fused-mirror-planes-9-0.1-0.25"])
    with pytest.raises(UserError, match="unknown candidate"):
        candidate_methods(["9-0.1-0.3"])


def test_a_missing_data_root_is_one_line_and_writes_nothing(tmp_path, capsys):
    out = tmp_path / "sel"
    assert main([str(tmp_path / "nope"), "--out", str(out), "--quiet", "--frames", "a/vp000"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "nope" in err[0]
    assert not out.exists()

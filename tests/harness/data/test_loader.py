"""FrameDataset: items of numpy arrays, batched by a DataLoader-style loop without torch."""

from __future__ import annotations

import numpy as np
import pytest

from harness.data.errors import UserError
from harness.data.frame import Frame, write_frame
from harness.data.loader import FrameDataset
from tests.helpers import make_synthetic_frame


def _collate(items):
    """What torch's default_collate does to a list of dicts of arrays and strings: stack arrays, list strings."""
    return {k: (np.stack([it[k] for it in items]) if isinstance(items[0][k], np.ndarray | np.generic)
                else [it[k] for it in items]) for k in items[0]}


def test_items_and_batches(tmp_path):
    frames = [make_synthetic_frame(32, viewpoint=v) for v in range(3)]
    for f in frames:
        write_frame(f, tmp_path)
    nogt = Frame(**{**frames[0].__dict__, "viewpoint": "vp009", "distance": {}})
    write_frame(nogt, tmp_path)
    ds = FrameDataset(tmp_path)
    assert len(ds) == 4
    it = ds[0]
    assert it["images"].shape == (3, 16, 32, 3) and it["images"].dtype == np.uint8
    np.testing.assert_array_equal(it["images"][1], frames[0].images["U"])  # order C, U, R
    assert it["distance"].dtype == np.float32 and it["valid"].all()
    np.testing.assert_array_equal(it["distance"], frames[0].distance["C"])
    assert it["positions"].shape == (3, 3) and it["rotations"].shape == (3, 3, 3)
    assert it["condition"] == "ideal" and it["scene"] == "synthetic_box"
    last = ds[3]  # no ground truth: NaN everywhere, nothing valid
    assert np.isnan(last["distance"]).all() and not last["valid"].any()
    seen, batch_size = [], 2
    for start in range(0, len(ds), batch_size):  # a DataLoader's loop, plain numpy
        batch = _collate([ds[i] for i in range(start, min(start + batch_size, len(ds)))])
        assert batch["images"].shape[1:] == (3, 16, 32, 3) and batch["distance"].shape[1:] == (16, 32)
        seen += batch["viewpoint"]
    assert seen == ["vp000", "vp001", "vp002", "vp009"]
    with pytest.raises(IndexError):
        ds[4]


def test_empty_root_is_refused(tmp_path):
    with pytest.raises(UserError, match="no tri360 frames"):
        FrameDataset(tmp_path)

"""Shared fixtures (helpers live in ``tests/helpers.py``)."""

from __future__ import annotations

import pytest

from harness.data.frame import write_frame
from tests.helpers import make_synthetic_frame


@pytest.fixture(scope="session")
def synthetic_frame():
    """A 200x100 synthetic_box frame (in memory)."""
    return make_synthetic_frame(200)


@pytest.fixture(scope="session")
def synthetic_root(tmp_path_factory, synthetic_frame):
    """A data root holding two synthetic_box frames on disk."""
    root = tmp_path_factory.mktemp("data")
    write_frame(synthetic_frame, root)
    write_frame(make_synthetic_frame(200, viewpoint=1), root)
    return root

"""The ``cluster`` marker is enforced: a test without it cannot start a Dask cluster in this process (so
``make test-fast``, ``-m "not ... and not cluster"``, starts none), and tests using a cluster fixture must carry it."""

from __future__ import annotations

import pytest
from distributed import LocalCluster

from tests.conftest import pytest_collection_modifyitems
from tests.helpers import external_cluster


def test_an_unmarked_test_cannot_start_a_local_cluster():
    with pytest.raises(RuntimeError, match="starts a Dask LocalCluster but is not marked @pytest.mark.cluster"):
        LocalCluster(n_workers=1, processes=False, dashboard_address=None)


def test_an_unmarked_test_cannot_start_scheduler_and_worker_processes(tmp_path):
    with pytest.raises(RuntimeError, match="not marked @pytest.mark.cluster"), external_cluster(tmp_path):
        pass
    assert not (tmp_path / "scheduler.json").exists()


class _Item:
    def __init__(self, nodeid: str, fixturenames: list[str], marked: bool):
        self.nodeid, self.fixturenames, self.marked = nodeid, fixturenames, marked

    def get_closest_marker(self, name: str):
        return object() if self.marked and name == "cluster" else None


def test_collection_refuses_an_unmarked_test_using_a_cluster_fixture():
    ok = [_Item("t::a", ["tmp_path", "dask_cluster"], marked=True), _Item("t::b", ["tmp_path"], marked=False)]
    pytest_collection_modifyitems(None, ok)
    with pytest.raises(pytest.UsageError, match="t::c"):
        pytest_collection_modifyitems(None, [*ok, _Item("t::c", ["scheduler"], marked=False)])

"""Shared fixtures (helpers live in ``tests/helpers.py``), the one shared Dask cluster, and the guard that a test
starting a Dask cluster is marked ``cluster`` (so ``make test-fast``, ``-m "not cluster"``, starts none)."""

from __future__ import annotations

from dataclasses import dataclass

import pytest
from distributed.deploy.spec import SpecCluster

from harness.data.frame import write_frame
from tests.helpers import CURRENT_TEST, external_cluster, make_synthetic_frame, require_cluster_marker, wait_for_workers

#: fixtures that are (or hold) a Dask cluster: a test using one must be marked ``cluster``
CLUSTER_FIXTURES = {"dask_cluster", "cluster", "scheduler"}


@pytest.hookimpl(tryfirst=True)
def pytest_runtest_setup(item):
    """Note the test about to run (before its fixtures, so a cluster fixture it starts is checked too)."""
    CURRENT_TEST.update(nodeid=item.nodeid, cluster=item.get_closest_marker("cluster") is not None)


def pytest_collection_modifyitems(config, items):
    unmarked = [i.nodeid for i in items if CLUSTER_FIXTURES & set(getattr(i, "fixturenames", ()))
                and i.get_closest_marker("cluster") is None]
    if unmarked:
        raise pytest.UsageError("tests using a Dask cluster fixture must be marked @pytest.mark.cluster: "
                                + ", ".join(unmarked))


_spec_cluster_init = SpecCluster.__init__


def _guarded_spec_cluster_init(self, *args, **kwargs):
    require_cluster_marker("a Dask LocalCluster")
    _spec_cluster_init(self, *args, **kwargs)


SpecCluster.__init__ = _guarded_spec_cluster_init  # LocalCluster is a SpecCluster: tri360's and any test's


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


@dataclass(frozen=True)
class DaskCluster:
    """The shared cluster: its scheduler's address and the ``dask`` processes (scheduler first)."""

    address: str
    processes: list


@pytest.fixture(scope="session")
def dask_cluster(tmp_path_factory):
    """ONE external cluster for the whole test run, shared by every test that can share one: ``dask scheduler``
    and two ``dask worker`` processes (1 thread each, with a nanny) on 127.0.0.1, started on first use.

    A test may kill a worker (its nanny starts another): a test that needs both workers asks for them through
    :func:`tests.helpers.wait_for_workers` when it starts, never relying on an earlier test having waited.
    """
    with external_cluster(tmp_path_factory.mktemp("dask")) as (address, procs):
        wait_for_workers(address, 2)
        yield DaskCluster(address, procs)

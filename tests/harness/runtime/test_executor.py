"""The Dask executor with real clusters on 127.0.0.1: a scheduler and two workers started outside tri360 (``dask
scheduler`` / ``dask worker`` subprocesses), a LocalCluster started by tri360, and a TLS cluster with self-made
certificates.  Frames must equal a sequential run's byte for byte, results its numbers up to another process's
rounding (tolerances below); a worker killed mid-run costs only a retry.
"""

from __future__ import annotations

import contextlib
import datetime
import ipaddress
import json
import os
import signal
import socket
import threading
from pathlib import Path

import numpy as np
import pandas as pd
import psutil
import pytest
from cryptography import x509
from cryptography.hazmat.primitives import hashes, serialization
from cryptography.hazmat.primitives.asymmetric import ec
from cryptography.x509.oid import NameOID
from distributed import Client
from distributed.diagnostics.plugin import WorkerPlugin

from harness.cli import main
from harness.commands.evaluate import evaluate
from harness.commands.render import RENDER_LOG
from harness.data.errors import UserError
from harness.data.exr import read_exr_channels
from harness.data.outputs import MARKER
from harness.runtime.cluster import ClusterOptions
from harness.runtime.context import QUIET, RunContext
from harness.runtime.executor import DaskExecutor, security_for
from reconstruction.methods.registry import get_methods
from tests.helpers import external_cluster, render_scene, wait_for_workers

#: the methods evaluated on the clusters and in this process: fused, the flow pipeline's average and the oracle
METHODS = ["fused", "dis-rect:average", "oracle-rect:gradient", "oracle-rect:average"]

#: A worker process may round floats otherwise than this one (the LM-refined variants on an image flow differ by up
#: to ~2e-8 m there): distributed's nanny starts it with OMP_NUM_THREADS, MKL_NUM_THREADS and OPENBLAS_NUM_THREADS 1
#: and it runs 1 task thread, and a sum that BLAS or a numba parallel loop splits over threads rounds by the split.
#: Results are therefore compared to tolerances that such rounding meets by orders of magnitude and a mix-up of
#: frames, methods or settings (>= 1e-3 m) does not.  Frames stay byte-identical: their floats are computed
#: element by element (no reduction across threads) and stored rounded (uint8 PNG, float32 EXR).
MAP_RTOL, MAP_ATOL = 1e-6, 1e-7  # float32 maps: ~8 float32 ulps relative; atol for confidences near 0 (unitless)
TABLE_RTOL, TABLE_ATOL = 1e-9, 1e-12  # float64 metrics of results.csv / regions.csv / breakdown.csv (metres, shares)


# ------------------------------------------------------------------------------------------------ helpers


def frame_files(root: Path) -> dict[str, bytes]:
    """Every file of the frames under a data root except the render logs (wall times), by relative path (the data
    root's own output marker is not a frame's)."""
    return {str(p.relative_to(root)): p.read_bytes() for p in sorted(root.rglob("*"))
            if p.is_file() and p.name != RENDER_LOG and p != root / MARKER}


def hidden_entries(root: Path) -> list[Path]:
    """Hidden leftovers under a data root (staging directories of killed writes); its output marker is not one."""
    return [p for p in root.rglob(".*") if p != root / MARKER]


def results_without_seconds(out: Path) -> pd.DataFrame:
    return pd.read_csv(out / "results.csv").drop(columns="seconds")


def assert_tables_match(got: pd.DataFrame, want: pd.DataFrame) -> None:
    """Same columns, rows and text; floats to :data:`TABLE_RTOL` / :data:`TABLE_ATOL`."""
    pd.testing.assert_frame_equal(got, want, rtol=TABLE_RTOL, atol=TABLE_ATOL)


def assert_results_match(got: Path, want: Path) -> None:
    """The results set ``got`` (evaluated on a cluster) holds ``want``'s (evaluated here): results.csv without its
    wall times, regions.csv and breakdown.csv to the table tolerances, and the same maps (channels, shapes, NaN and
    inf where ``want`` has them) to :data:`MAP_RTOL` / :data:`MAP_ATOL`."""
    assert_tables_match(results_without_seconds(got), results_without_seconds(want))
    for name in ("regions.csv", "breakdown.csv"):
        assert_tables_match(pd.read_csv(got / name), pd.read_csv(want / name))
    maps = sorted(p.relative_to(got) for p in (got / "maps").rglob("*.exr"))
    assert maps == sorted(p.relative_to(want) for p in (want / "maps").rglob("*.exr"))
    for rel in maps:
        a, b = read_exr_channels(got / rel), read_exr_channels(want / rel)
        assert list(a) == list(b), rel
        for channel, values in a.items():
            np.testing.assert_allclose(values, b[channel], rtol=MAP_RTOL, atol=MAP_ATOL, err_msg=f"{rel} {channel}")


SYNTH = {"viewpoints": 3, "width": 160}


def listening_ips(procs: list[psutil.Process]) -> set[tuple[str, int]]:
    """(ip, port) of every listening TCP socket of these processes and their descendants."""
    everyone = {p.pid: p for q in procs for p in [q, *q.children(recursive=True)]}
    return {(c.laddr.ip, c.laddr.port) for p in everyone.values() for c in p.net_connections(kind="inet")
            if c.status == psutil.CONN_LISTEN}


@pytest.fixture
def cluster(dask_cluster):
    """The shared cluster with both workers up now (an earlier test may have had one killed): (address, their
    process ids)."""
    return dask_cluster.address, wait_for_workers(dask_cluster.address, 2)


@pytest.fixture(scope="module")
def sequential(tmp_path_factory):
    """Frames and results made in this process, the reference for every cluster run."""
    root = tmp_path_factory.mktemp("seq")
    render_scene("synthetic_box", out_root=root / "data", ctx=QUIET, **{**SYNTH, "viewpoints": 4})
    evaluate(root / "data", root / "results", get_methods(METHODS), report=False, ctx=QUIET)
    return root


# ------------------------------------------------------------------------------------------------- tests


@pytest.mark.cluster
def test_the_documented_cluster_commands_listen_on_loopback_only(cluster, dask_cluster):
    listening = listening_ips([psutil.Process(p.pid) for p in dask_cluster.processes])
    assert listening and {ip for ip, _ in listening} == {"127.0.0.1"}, listening


@pytest.mark.cluster
def test_render_and_evaluate_on_an_external_scheduler_equal_a_sequential_run(cluster, sequential, tmp_path):
    address, worker_pids = cluster
    opts = ClusterOptions(scheduler=address)
    data = tmp_path / "data"
    dirs = render_scene("synthetic_box", out_root=data, ctx=RunContext(opts, progress=False),
                        **{**SYNTH, "viewpoints": 4})
    assert [d.name for d in dirs] == ["vp000", "vp001", "vp002", "vp003"]
    assert frame_files(data) == frame_files(sequential / "data")  # byte-identical, frame.json included
    # the frames were rendered by the two worker processes, not here
    ran = {json.loads((d / RENDER_LOG).read_text())["pid"] for d in dirs}
    assert ran <= set(worker_pids) and os.getpid() not in ran
    evaluate(data, tmp_path / "results", get_methods(METHODS), report=False,
             ctx=RunContext(opts, progress=False))
    assert_results_match(tmp_path / "results", sequential / "results")
    maps = list((tmp_path / "results" / "maps").rglob("*.exr"))
    assert len(maps) == 2 * 4 * len(METHODS)  # distance + confidence per frame and method
    # the scheduler saw tri360's tasks
    with Client(address, timeout=30) as c:
        prefixes = c.run_on_scheduler(lambda dask_scheduler: sorted(dask_scheduler.task_prefixes))
    assert "tri360_render" in prefixes and "tri360_evaluate" in prefixes
    # resumable: a rerun has nothing to do and changes nothing
    before = {p: p.stat().st_mtime_ns for p in data.rglob("frame.json")}
    render_scene("synthetic_box", out_root=data, ctx=RunContext(opts, progress=False),
                 **{**SYNTH, "viewpoints": 4})
    assert {p: p.stat().st_mtime_ns for p in data.rglob("frame.json")} == before


class KillOnce(WorkerPlugin):
    """Kills its own worker process (SIGKILL) shortly after a task of ``prefix`` starts executing, once per
    cluster (the marker file decides which worker)."""

    def __init__(self, marker: str, prefix: str, delay_s: float = 0.2):
        self.marker, self.prefix, self.delay_s = marker, prefix, delay_s

    def transition(self, key, start, finish, **kwargs):
        if finish != "executing" or not str(key).startswith(self.prefix):
            return
        try:
            fd = os.open(self.marker, os.O_CREAT | os.O_EXCL | os.O_WRONLY)
        except FileExistsError:
            return
        os.write(fd, f"{os.getpid()} {key}".encode())
        os.close(fd)
        threading.Timer(self.delay_s, os.kill, (os.getpid(), signal.SIGKILL)).start()


@pytest.mark.cluster
@pytest.mark.parametrize("job", ["render", "evaluate"])
def test_a_worker_killed_mid_run_costs_only_a_retry(cluster, sequential, tmp_path, job):
    address, _ = cluster
    marker = tmp_path / "killed"
    opts = ClusterOptions(scheduler=address)
    data = tmp_path / "data" if job == "render" else sequential / "data"
    # the plugin lives on the scheduler; this client is closed before the job's own client runs, so that two clients
    # never share this process (their event loops then clashed now and then: "bound to a different event loop")
    with Client(address, timeout=30) as c:
        c.register_plugin(KillOnce(str(marker), f"tri360_{job}-"), name="kill-once")
    try:
        if job == "render":
            dirs = render_scene("synthetic_box", out_root=data, ctx=RunContext(opts, progress=False),
                                **{**SYNTH, "viewpoints": 4})
            assert len(dirs) == 4 and len(set(dirs)) == 4
            assert frame_files(data) == frame_files(sequential / "data")  # all frames, each complete once
            assert hidden_entries(data) == []  # the killed worker's half-written frame was cleaned up
        else:
            evaluate(data, tmp_path / "results", get_methods(METHODS), report=False,
                     ctx=RunContext(opts, progress=False))
            got = results_without_seconds(tmp_path / "results")
            assert len(got) == 4 * len(METHODS)
            assert not got.duplicated(["scene", "viewpoint", "method"]).any()
            assert_tables_match(got, results_without_seconds(sequential / "results"))
    finally:
        with Client(address, timeout=30) as c:
            c.unregister_worker_plugin("kill-once")
    assert marker.is_file(), "no worker was killed: the test proved nothing"
    killed_pid = int(marker.read_text().split()[0])
    assert not psutil.pid_exists(killed_pid) or psutil.Process(killed_pid).status() == psutil.STATUS_ZOMBIE


@pytest.mark.cluster
def test_local_cluster_listens_on_loopback_only_and_renders_the_same_frames(sequential, tmp_path):
    data = tmp_path / "data"
    me = psutil.Process()
    before = {p.pid for p in me.children(recursive=True)}  # e.g. the external cluster of other tests
    mine_before = {(c.laddr.ip, c.laddr.port) for c in me.net_connections(kind="inet")
                   if c.status == psutil.CONN_LISTEN}
    with DaskExecutor(ClusterOptions(workers=2)) as ex:
        # Python's resource tracker and fork server (whose children the workers are) live as long as we do.  They
        # are told apart by the code they run: every process multiprocessing starts also carries this process's
        # -W options in its command line, and once a CLI test ran guard() in-process, those name the tracker.
        procs = [p for p in me.children(recursive=True) if p.pid not in before
                 and "multiprocessing.resource_tracker import main" not in " ".join(p.cmdline())
                 and not (p.ppid() == me.pid and "multiprocessing.forkserver import main" in " ".join(p.cmdline()))]
        assert len(procs) >= 2  # the worker processes (and their nannies' children)
        listening = {(c.laddr.ip, c.laddr.port) for p in [me, *procs] for c in p.net_connections(kind="inet")
                     if c.status == psutil.CONN_LISTEN} - mine_before
        assert listening, "the LocalCluster listens nowhere?"
        assert {ip for ip, _ in listening} == {"127.0.0.1"}, listening
        assert ex.client.scheduler.address.startswith("tcp://127.0.0.1:")
        render_scene("synthetic_box", out_root=data, ctx=RunContext(ex, progress=False), **{**SYNTH, "viewpoints": 2})
        worker_pids = set(ex.client.run(os.getpid).values())
    assert {json.loads((d / RENDER_LOG).read_text())["pid"] for d in data.glob("*/*")} <= worker_pids
    seq = {k: v for k, v in frame_files(sequential / "data").items() if k.split("/")[1] in ("vp000", "vp001")}
    assert frame_files(data) == seq
    _, left = psutil.wait_procs(procs, timeout=15)  # the cluster is stopped: its processes exit
    left = [p for p in left if p.is_running() and p.status() != psutil.STATUS_ZOMBIE]
    assert not left, f"LocalCluster processes still running: {left}"


def make_certificates(d: Path, name: str) -> dict:
    """A self-made CA and a certificate for 127.0.0.1 signed by it: ``{ca, cert, key}`` PEM paths in ``d``.

    Made with ``cryptography`` (a dev dependency), so the TLS test needs no ``openssl`` command and never skips.
    """
    d.mkdir(parents=True, exist_ok=True)
    now = datetime.datetime.now(datetime.UTC)

    def certificate(subject: str, key, issuer: str, issuer_key, ca: bool):
        b = (x509.CertificateBuilder()
             .subject_name(x509.Name([x509.NameAttribute(NameOID.COMMON_NAME, subject)]))
             .issuer_name(x509.Name([x509.NameAttribute(NameOID.COMMON_NAME, issuer)]))
             .public_key(key.public_key()).serial_number(x509.random_serial_number())
             .not_valid_before(now - datetime.timedelta(minutes=5)).not_valid_after(now + datetime.timedelta(days=2))
             .add_extension(x509.BasicConstraints(ca=ca, path_length=None), critical=True))
        if not ca:
            b = b.add_extension(x509.SubjectAlternativeName([x509.IPAddress(ipaddress.ip_address("127.0.0.1"))]),
                                critical=False)
        return b.sign(issuer_key, hashes.SHA256())

    ca_key = ec.generate_private_key(ec.SECP256R1())
    node_key = ec.generate_private_key(ec.SECP256R1())
    ca_cert = certificate(f"{name}-ca", ca_key, f"{name}-ca", ca_key, ca=True)
    node_cert = certificate("127.0.0.1", node_key, f"{name}-ca", ca_key, ca=False)
    (d / "ca.pem").write_bytes(ca_cert.public_bytes(serialization.Encoding.PEM))
    (d / "node.pem").write_bytes(node_cert.public_bytes(serialization.Encoding.PEM))
    (d / "node.key").write_bytes(node_key.private_bytes(serialization.Encoding.PEM,
                                                        serialization.PrivateFormat.PKCS8,
                                                        serialization.NoEncryption()))
    return {"ca": str(d / "ca.pem"), "cert": str(d / "node.pem"), "key": str(d / "node.key")}


@pytest.mark.cluster
def test_tls_cluster_accepts_certified_clients_and_refuses_others(sequential, tmp_path):
    certs = make_certificates(tmp_path / "pki", "tri360")
    other = make_certificates(tmp_path / "other-pki", "intruder")
    opts = ClusterOptions(scheduler="", tls_ca=Path(certs["ca"]), tls_cert=Path(certs["cert"]),
                          tls_key=Path(certs["key"]), connect_timeout_s=20)
    with external_cluster(tmp_path / "cluster", n_workers=1, tls=certs) as (address, _):
        assert address.startswith("tls://127.0.0.1:")
        opts = ClusterOptions(**{**opts.__dict__, "scheduler": address})
        wait_for_workers(address, 1, security=security_for(opts))
        data = tmp_path / "data"
        render_scene("synthetic_box", out_root=data, ctx=RunContext(opts, progress=False),
                     **{**SYNTH, "viewpoints": 1})
        seq = {k: v for k, v in frame_files(sequential / "data").items() if k.split("/")[1] == "vp000"}
        assert frame_files(data) == seq
        # no certificate at all: refused by tri360 before connecting, and by the scheduler when forced
        with pytest.raises(UserError, match="TLS address"):
            ClusterOptions(scheduler=address).check()
        with pytest.raises((OSError, TimeoutError, TypeError)):  # TypeError: Dask's client needs an SSL context
            Client(address, timeout=5)
        with pytest.raises((OSError, TimeoutError)):
            Client(address.replace("tls://", "tcp://"), timeout=5)
        # a certificate from another CA: the scheduler refuses the handshake
        intruder = ClusterOptions(scheduler=address, tls_ca=Path(other["ca"]), tls_cert=Path(other["cert"]),
                                  tls_key=Path(other["key"]), connect_timeout_s=5)
        with pytest.raises(UserError, match="cannot connect to the Dask scheduler"):
            render_scene("synthetic_box", out_root=tmp_path / "intruder", ctx=RunContext(intruder, progress=False),
                         **{**SYNTH, "viewpoints": 1})
        assert not (tmp_path / "intruder" / "synthetic_box" / "vp000").exists()


def test_cluster_options_are_checked_before_any_work(tmp_path, capsys):
    for argv, message in [
        (["--workers", "0"], "--workers must be >= 1"),
        (["--scheduler", "tls://127.0.0.1:1"], "TLS address"),
        (["--tls-ca", str(tmp_path / "nope.pem")], "--tls-cert"),
        (["--scheduler", "no-such-file"], "neither an address"),
    ]:
        assert main(["render", "--scene", "synthetic_box", "--out", str(tmp_path / "d"), "--quiet", *argv]) == 2
        err = capsys.readouterr().err.strip()
        assert len(err.splitlines()) == 1 and message in err, err
        assert not (tmp_path / "d").exists()
    with pytest.raises(SystemExit):  # argparse: --scheduler and --workers are exclusive
        main(["render", "--scheduler", "tcp://127.0.0.1:1", "--workers", "2"])


@pytest.mark.slow
def test_unreachable_scheduler_is_one_clear_error(tmp_path):
    with socket.socket() as s:  # a port nobody listens on
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    opts = ClusterOptions(scheduler=f"tcp://127.0.0.1:{port}", connect_timeout_s=3)
    with pytest.raises(UserError, match="cannot connect to the Dask scheduler"):
        render_scene("synthetic_box", out_root=tmp_path / "d", ctx=RunContext(opts, progress=False),
                     **{**SYNTH, "viewpoints": 1})
    assert not (tmp_path / "d" / "synthetic_box").exists()


@pytest.mark.blender
@pytest.mark.cluster
def test_cycles_renders_on_a_dask_worker_identically(cluster, tmp_path):
    address, worker_pids = cluster
    kw = {"viewpoints": 1, "width": 64, "samples": 2, "threads": 1}
    render_scene("box_room", out_root=tmp_path / "seq", ctx=QUIET, **kw)
    (d,) = render_scene("box_room", out_root=tmp_path / "dask", **kw,
                        ctx=RunContext(ClusterOptions(scheduler=address), progress=False))
    assert json.loads((d / RENDER_LOG).read_text())["pid"] in worker_pids
    assert frame_files(tmp_path / "dask") == frame_files(tmp_path / "seq")


@pytest.mark.cluster
def test_local_cluster_starts_quietly_when_dasks_default_port_is_taken(capfd, recwarn):
    """A second job's cluster (or anything else) on 127.0.0.1:8787: our LocalCluster's scheduler serves its HTTP
    on another free loopback port and says nothing (Dask would warn "Port 8787 is already in use", which the
    command line shows on stderr)."""
    with contextlib.ExitStack() as stack:
        holder = stack.enter_context(socket.socket())
        with contextlib.suppress(OSError):  # already taken by another process: the same situation
            holder.bind(("127.0.0.1", 8787))
            holder.listen()
        capfd.readouterr()
        with DaskExecutor(ClusterOptions(workers=1)) as ex:
            assert list(ex.run(pow, {"a": (2, 5)}, progress=False)) == [("a", 32)]
        _, err = capfd.readouterr()
    said = [str(w.message) for w in recwarn] + [err]
    assert not any("8787" in x or "already in use" in x for x in said), said

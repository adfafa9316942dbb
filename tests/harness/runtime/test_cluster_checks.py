"""Cluster options that cannot work are one line, before any work and within a bounded time: --workers past what
the machine runs, --scheduler at a TCP service that is not Dask (a silent listener, an HTTP server; 127.0.0.1
only), TLS files that are not PEM (naming which option); Ctrl-C with --workers prints one line."""

from __future__ import annotations

import contextlib
import dataclasses
import http.server
import os
import signal
import socket
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

from harness.cli import main
from harness.data.errors import UserError
from harness.data.frame import find_frames, read_frame, write_frame
from harness.runtime.cluster import (
    BASE_BYTES,
    ClusterOptions,
    Executor,
    SequentialExecutor,
    machine_cores,
    max_workers,
    physical_memory_bytes,
)
from harness.runtime.context import QUIET, RunContext
from tests.harness.render.test_render_interrupt import _cmdline, _descendants
from tests.harness.runtime.test_executor import make_certificates
from tests.helpers import render_scene

ROOT = Path(__file__).resolve().parents[3]
RENDER = ["render", "--scene", "synthetic_box", "--width", "64", "--quiet"]


def one_line_error(capsys) -> str:
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "Traceback" not in err, err
    return err


# ------------------------------------------------------------------------------------------------- --workers


def test_max_workers_is_bounded_by_cores_and_memory():
    gib = 1 << 30
    assert max_workers(1, cores=2, memory_bytes=23 * gib) == 4  # 2 tasks per core
    assert max_workers(2, cores=2, memory_bytes=23 * gib) == 2  # tasks at once = workers x threads
    assert max_workers(1, cores=64, memory_bytes=4 * gib) == 3  # 80 % of 4 GiB at 1 GiB a task
    assert max_workers(1, cores=1, memory_bytes=gib) == 0
    assert max_workers() >= 2, "the tests' 2-worker clusters fit on any machine with a core and 3 GiB"
    assert BASE_BYTES == gib


def test_too_many_workers_is_one_line_with_the_reason(tmp_path, capsys):
    top = max_workers()
    assert main([*RENDER, "--out", str(tmp_path / "d"), "--workers", str(top + 1)]) == 2
    err = one_line_error(capsys)
    cores, gib = machine_cores(), physical_memory_bytes() / 2**30
    assert f"--workers {top + 1}: this machine has {cores} core" in err and f"{gib:.0f} GiB" in err, err
    assert f"at most {top} workers" in err
    assert main([*RENDER, "--out", str(tmp_path / "d"), "--workers", "1000"]) == 2
    assert "--workers 1000: this machine has" in one_line_error(capsys)
    assert not (tmp_path / "d").exists()


# ----------------------------------------------------------------------------------- --scheduler not Dask


@contextlib.contextmanager
def silent_listener():
    """A TCP port on 127.0.0.1 that accepts connections and never says a word."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        s.listen(8)
        yield f"tcp://127.0.0.1:{s.getsockname()[1]}"


class _Quiet(http.server.BaseHTTPRequestHandler):
    def log_message(self, *args):  # no request lines on stderr
        pass


@contextlib.contextmanager
def http_server():
    """An HTTP server on 127.0.0.1 (it answers Dask's bytes with 400 Bad Request)."""
    srv = http.server.ThreadingHTTPServer(("127.0.0.1", 0), _Quiet)
    t = threading.Thread(target=srv.serve_forever, daemon=True)
    t.start()
    try:
        yield f"tcp://127.0.0.1:{srv.server_address[1]}"
    finally:
        srv.shutdown()
        srv.server_close()


@pytest.mark.slow
@pytest.mark.parametrize("service", [silent_listener, http_server])
def test_a_scheduler_address_that_is_not_dask_is_one_line_in_bounded_time(service, tmp_path):
    with service() as address:
        t0 = time.monotonic()
        with pytest.raises(UserError) as info:
            render_scene("synthetic_box", out_root=tmp_path / "d", width=64,
                         ctx=RunContext(ClusterOptions(scheduler=address, connect_timeout_s=3), progress=False))
        elapsed = time.monotonic() - t0
    message = str(info.value)
    assert elapsed < 20, f"took {elapsed:.1f} s with a 3 s connect timeout (6 s in all for an answer)"
    assert len(message.splitlines()) == 1 and address in message, message
    assert "Dask" in message
    assert not (tmp_path / "d" / "synthetic_box").exists()


@pytest.mark.slow
def test_the_cli_gives_up_on_a_silent_scheduler_within_its_connect_timeout(tmp_path, capsys):
    """The command line's own connect timeout (30 s, and 5 s for the answer) bounds the wait too."""
    with silent_listener() as address:
        t0 = time.monotonic()
        assert main([*RENDER, "--out", str(tmp_path / "d"), "--scheduler", address]) == 2
        elapsed = time.monotonic() - t0
    err = one_line_error(capsys)
    assert "no Dask answer within 35 s" in err and address in err
    assert elapsed < 50


# ---------------------------------------------------------------------------------------------- TLS files


@pytest.fixture(scope="module")
def pki(tmp_path_factory):
    d = tmp_path_factory.mktemp("pki")
    certs = {k: Path(v) for k, v in make_certificates(d / "good", "tri360").items()}
    other = {k: Path(v) for k, v in make_certificates(d / "other", "other").items()}
    (d / "junk.pem").write_text("not a certificate\n")
    (d / "broken.pem").write_text("-----BEGIN CERTIFICATE-----\n@@@@ not base64 @@@@\n-----END CERTIFICATE-----\n")
    (d / "binary.der").write_bytes(b"\x30\x82\x01\x0a" + bytes(range(256)))
    return d, certs, other


@pytest.mark.parametrize(("bad", "which", "message"), [
    ("ca", "junk.pem", "--tls-ca is not a PEM certificate"),
    ("ca", "broken.pem", "--tls-ca is not a valid PEM certificate"),
    ("ca", "binary.der", "--tls-ca is not a PEM certificate"),
    ("ca", "key", "--tls-ca is not a PEM certificate"),
    ("cert", "junk.pem", "--tls-cert is not a PEM certificate"),
    ("cert", "key", "--tls-cert is not a PEM certificate"),
    ("cert", "broken.pem", "--tls-cert is not a valid PEM certificate"),
    ("key", "junk.pem", "--tls-key is not a PEM private key"),
    ("key", "cert", "--tls-key is not a PEM private key"),
    ("key", "other-key", "--tls-key is not the private key of --tls-cert"),
])
def test_tls_files_that_are_not_pem_name_the_option(pki, tmp_path, capsys, bad, which, message):
    d, certs, other = pki
    files = dict(certs)
    files[bad] = {"key": certs["key"], "cert": certs["cert"], "other-key": other["key"]}.get(which, d / which)
    argv = [*RENDER, "--out", str(tmp_path / "d"), "--scheduler", "tls://127.0.0.1:1",
            "--tls-ca", str(files["ca"]), "--tls-cert", str(files["cert"]), "--tls-key", str(files["key"])]
    assert main(argv) == 2
    err = one_line_error(capsys)
    assert message in err and str(files[bad]) in err, err
    assert not (tmp_path / "d").exists()


def test_good_tls_files_pass_the_checks(pki):
    _, certs, _ = pki
    ClusterOptions(scheduler="tls://127.0.0.1:1", tls_ca=certs["ca"], tls_cert=certs["cert"],
                   tls_key=certs["key"]).check()


# ----------------------------------------------------------------------------------- Ctrl-C with --workers


@pytest.fixture(scope="module")
def frames(tmp_path_factory):
    root = tmp_path_factory.mktemp("frames")
    render_scene("synthetic_box", out_root=root, viewpoints=2, width=200, ctx=QUIET)
    return root


@pytest.fixture(scope="module")
def many_frames(frames, tmp_path_factory):
    """48 frames, copies of the two rendered ones under other viewpoint names: work that lasts well past the
    moment the Ctrl-C test interrupts it on any machine (the two frames alone are evaluated in about 2 s)."""
    root = tmp_path_factory.mktemp("many-frames")
    originals = [read_frame(d) for d in find_frames(frames)]
    for i in range(48):
        write_frame(dataclasses.replace(originals[i % len(originals)], viewpoint=f"vp{i:03d}", path=None), root)
    return root


@contextlib.contextmanager
def _cli(args: list[str]) -> Iterator[subprocess.Popen]:
    """``python -m harness.cli ARGS`` in a session of its own with Ctrl-C's default action (as from a terminal,
    even when this test runs from a background job, which inherits SIGINT ignored); killed on the way out."""
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(ROOT), *filter(None, [os.environ.get("PYTHONPATH")])])}
    proc = subprocess.Popen([sys.executable, "-m", "harness.cli", *args], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, env=env, start_new_session=True,
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    try:
        yield proc
    finally:
        with contextlib.suppress(ProcessLookupError):
            os.killpg(proc.pid, signal.SIGKILL)
        proc.wait(timeout=30)


def _ctrl_c(proc: subprocess.Popen) -> str:
    """Ctrl-C to the whole process group, as a terminal sends it; the command's stderr once it has exited."""
    os.killpg(proc.pid, signal.SIGINT)
    return proc.communicate(timeout=90)[1].decode()


@pytest.mark.cluster
@pytest.mark.parametrize("command", ["evaluate", "study"])
def test_ctrl_c_with_workers_prints_one_line(many_frames, tmp_path, command):
    """Ctrl-C to the whole process group, as a terminal sends it, once the LocalCluster's workers run: exit 130
    and exactly one line on stderr (the workers ignore SIGINT and are stopped by the command)."""
    if command == "evaluate":
        args = ["evaluate", str(many_frames), "--out", str(tmp_path / "out"), "--no-report"]
    else:
        study = tmp_path / "s.toml"  # 8 grid points: 4 took 23 s (2 cores, loaded)
        study.write_text('[render]\nscene = "synthetic_box"\nwidth = 400\n[evaluate]\nmethod = ["fused"]\n'
                         "[grid]\nbaseline = [0.15, 0.2, 0.25, 0.3, 0.35, 0.4, 0.45, 0.5]\n")
        args = ["study", str(study), "--out", str(tmp_path / "out")]
    with _cli([*args, "--workers", "2", "--quiet"]) as proc:
        deadline = time.monotonic() + 120
        while proc.poll() is None and time.monotonic() < deadline and len(
                [p for p in _descendants(proc.pid) if "forkserver" in _cmdline(p)]) < 3:  # the server + 2 workers
            time.sleep(0.2)
        time.sleep(3.0)  # the workers import and take their first tasks
        assert proc.poll() is None, proc.communicate()
        err = _ctrl_c(proc)
    assert proc.returncode == 130, err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"tri360 {command}: interrupted"), err



def test_a_run_context_runs_on_options_or_an_open_executor():
    seq = SequentialExecutor()
    assert isinstance(seq, Executor) and not seq.distributed
    ctx = RunContext(seq)
    with ctx.executor() as ex:
        assert ex is seq and list(ex.run(pow, {"a": (2, 3)}, progress=False)) == [("a", 8)]
    assert not ctx.distributed and not RunContext().distributed and not RunContext(ClusterOptions()).distributed
    assert RunContext(ClusterOptions(workers=1)).distributed
    with RunContext().executor() as ex:
        assert isinstance(ex, SequentialExecutor)
    assert RunContext().on(seq).where is seq and not RunContext().quiet().progress


@pytest.mark.cluster
def test_ctrl_c_after_the_command_finished_leaves_its_exit_status(frames, tmp_path):
    """Ctrl-C once the results are written, while the process shuts down (Dask loaded: about half a second, in
    which Python puts SIGINT back to its default action): exit status 0 and nothing on stderr -- not a silent death
    by SIGINT.  On a machine slow enough that the command had not returned yet: 130 and one line."""
    with _cli(["evaluate", str(frames), "--out", str(tmp_path / "out"), "--no-report", "--workers", "2", "--quiet",
               "--method", "fused"]) as proc:
        for line in proc.stdout:
            if b"results in" in line:
                break
        time.sleep(0.3)
        err = _ctrl_c(proc)
    assert proc.returncode in (0, 130), (proc.returncode, err)
    assert len(err.strip().splitlines()) == (proc.returncode == 130), err
    assert (tmp_path / "out" / "results.csv").is_file()

"""harness.data.native: the capture of C libraries' output is process-wide, so it happens on the main thread only;
other threads decode unserialised and their library output is never swallowed."""

from __future__ import annotations

import os
import threading

from harness.data.native import native_output_captured


def _in_thread(fn):
    result = {}
    t = threading.Thread(target=lambda: result.setdefault("value", fn()))
    t.start()
    t.join(timeout=30)
    assert not t.is_alive(), "the worker thread is stuck"
    return result["value"]


def test_worker_threads_do_not_capture(capfd):
    capfd.readouterr()

    def decode():
        with native_output_captured() as captured:
            os.write(2, b"worker: library message\n")
        return captured

    captured = _in_thread(decode)
    assert not captured.active and captured.text == ""
    assert capfd.readouterr().err == "worker: library message\n"  # reached the real descriptor


def _worker_capture_active() -> bool:
    with native_output_captured() as captured:
        return captured.active


def test_a_worker_decodes_while_the_main_thread_captures(capfd):
    """No lock between captures: a worker's (inactive) capture completes while the main thread holds one."""
    capfd.readouterr()
    with native_output_captured() as main:
        worker = _in_thread(_worker_capture_active)
        os.write(2, b"main: damaged file\n")
    assert main.active and worker is False
    assert main.text == "main: damaged file\n"
    assert capfd.readouterr() == ("", "")  # the main thread's capture was not released


def test_nested_capture_is_a_no_op():
    with native_output_captured() as outer, native_output_captured() as inner:
        os.write(1, b"x\n")
    assert outer.active and not inner.active and outer.text == "x\n"

"""The virtual devices stop on SIGTERM whichever of their threads the kernel hands it to.

A process-directed signal goes to any thread that does not block it, and the threads BLAS
starts when numpy is imported (and a server's own) block none; Python runs the handler in the
main thread only, when that thread next runs Python. A server whose main thread slept in a wait
only its own signal ends never ran it (the likely cause of a CI failure: `tests/test_capture.py`'s
teardown waited 10 s for a virtual encoder to stop; rare, as the kernel mostly picks the main
thread). Here the signal is sent to another thread of the server on purpose.
"""

from __future__ import annotations

import signal
import subprocess
import sys
from pathlib import Path

import pytest

SCENARIO = Path(__file__).resolve().parents[1] / "scenarios" / "geometric_irb120.toml"
THREAD_STOPS = """
import signal, sys, threading, time
from twin.cli import main

def stop_from_this_thread() -> None:
    sys.stdin.readline()
    time.sleep(0.5)  # the main thread asleep in its wait by then
    signal.pthread_kill(threading.get_ident(), signal.SIGTERM)

threading.Thread(target=stop_from_this_thread, daemon=True).start()
sys.exit(main(sys.argv[1:]))
"""
"""`twin` with a thread that sends SIGTERM to itself, not to the main thread, at a line on
stdin."""
STOP_S = 10.0


@pytest.mark.skipif(not hasattr(signal, "pthread_kill"), reason="POSIX threads' signals")
@pytest.mark.parametrize("command", [["virtual-encoder"],
                                     ["virtual-encoder", "--protocol", "modbus"],
                                     ["virtual-controller"]])
def test_a_virtual_device_stops_on_sigterm_taken_by_another_thread(command: list[str],
                                                                   tmp_path: Path) -> None:
    """The device serves (its first line printed), a thread other than the main one takes
    SIGTERM, and the command ends as SIGTERM ends it: exit 143, one line."""
    process = subprocess.Popen(
        [sys.executable, "-c", THREAD_STOPS, *command, str(SCENARIO), "--pose-file",
         str(tmp_path / "pose.json")],
        stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        assert process.stdout is not None and process.stdin is not None
        assert process.stdout.readline(), "the device printed nothing"
        process.stdin.write("\n")
        process.stdin.flush()
        _, error = process.communicate(timeout=STOP_S)
    finally:
        if process.poll() is None:
            process.kill()
            process.wait()
    assert process.returncode == 143, error
    assert error == "twin: terminated\n", error

"""What serves until it is stopped — the virtual devices, `--rerun-serve`'s web viewer — stops
on SIGTERM whichever of its threads the kernel hands it to.

A process-directed signal goes to any thread that does not block it, and the threads BLAS
starts when numpy is imported (and a server's own) block none; Python runs the handler in the
main thread only, when that thread next runs Python. A server whose main thread slept in a wait
only its own signal ends never ran it (the likely cause of a CI failure: `tests/test_capture.py`'s
teardown waited 10 s for a virtual encoder to stop; rare, as the kernel mostly picks the main
thread; `twin calibrate --rerun-serve` slept an hour at a time and went on serving that long).
Here the signal is sent to another thread of the server on purpose.
"""

from __future__ import annotations

import signal
import socket
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path

import pytest
from conftest import free_port

from twin.cli import main
from twin.viz.sinks import rerun_executable

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


def _stopped_by_another_thread(arguments: list[str],
                               serving: Callable[[subprocess.Popen[str]], None]
                               ) -> tuple[int, str]:
    """Run ``twin ARGUMENTS`` with :data:`THREAD_STOPS`, wait until ``serving`` has seen it
    serve, have a thread other than its main one take SIGTERM; its exit code and what it wrote
    on stderr after what ``serving`` read."""
    process = subprocess.Popen([sys.executable, "-c", THREAD_STOPS, *arguments],
                               stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                               stderr=subprocess.PIPE, text=True)
    try:
        serving(process)
        assert process.stdin is not None
        process.stdin.write("\n")
        process.stdin.flush()
        _, error = process.communicate(timeout=STOP_S)
    finally:
        if process.poll() is None:
            process.kill()
            process.wait()
    return process.returncode, error


@pytest.mark.skipif(not hasattr(signal, "pthread_kill"), reason="POSIX threads' signals")
@pytest.mark.parametrize("command", [["virtual-encoder"],
                                     ["virtual-encoder", "--protocol", "modbus"],
                                     ["virtual-controller"]])
def test_a_virtual_device_stops_on_sigterm_taken_by_another_thread(command: list[str],
                                                                   tmp_path: Path) -> None:
    """The device serves (its first line printed), a thread other than the main one takes
    SIGTERM, and the command ends as SIGTERM ends it: exit 143, one line."""
    def serving(process: subprocess.Popen[str]) -> None:
        assert process.stdout is not None
        assert process.stdout.readline(), "the device printed nothing"

    code, error = _stopped_by_another_thread(
        [*command, str(SCENARIO), "--pose-file", str(tmp_path / "pose.json")], serving)
    assert code == 143, error
    assert error == "twin: terminated\n", error


@pytest.mark.slow
@pytest.mark.skipif(not hasattr(signal, "pthread_kill"), reason="POSIX threads' signals")
@pytest.mark.skipif(rerun_executable() is None, reason="needs the rerun executable")
def test_the_web_viewer_stops_serving_on_sigterm_taken_by_another_thread(tmp_path: Path
                                                                         ) -> None:
    """`twin calibrate --rerun-serve` serves its web viewer (the line asking for Ctrl-C
    printed), a thread other than the main one takes SIGTERM, and the command stops serving as
    SIGTERM stops it: exit 0, "stopped serving", the viewer's ports closed."""
    assert main(["simulate", str(SCENARIO), "--out", str(tmp_path)]) == 0
    ports = free_port(), free_port()

    def serving(process: subprocess.Popen[str]) -> None:
        assert process.stderr is not None
        lines: list[str] = []
        while not any("press Ctrl-C" in line for line in lines):
            line = process.stderr.readline()
            assert line, "".join(lines)
            lines.append(line)

    code, error = _stopped_by_another_thread(
        ["calibrate", str(tmp_path / "capture.toml"), "--rerun-serve", "--rerun-web-port",
         str(ports[0]), "--rerun-grpc-port", str(ports[1])], serving)
    assert code == 0, error
    assert "stopped serving" in error
    for port in ports:
        with socket.socket() as probe:
            assert probe.connect_ex(("127.0.0.1", port)) != 0

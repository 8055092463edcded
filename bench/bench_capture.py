"""Capture throughput: readings/s over a real pty (ASCII vs Modbus RTU), and the cost of
making each pose durable (append + fsync vs a plain append).

Run by hand: ``python bench/bench_capture.py`` (``--tiny``: a few readings and rows). The
devices are :mod:`twin.hardware.virtual_encoder`
served in threads of this process on pseudo-terminals, with the core's closed-form lengths and
exact readings, so the figures are the drivers' and the line's, not MuJoCo's. A pty ignores the
baud rate, but minimalmodbus waits the Modbus 3.5-character silence of the configured rate.
Prints the measured rates and their ratios, all from this one run.
"""

from __future__ import annotations

import os
import queue
import tempfile
import threading
import time
from pathlib import Path

import numpy as np
from _timing import tiny_run

from twin.hardware.capture_session import HEADER, format_row, journal
from twin.hardware.encoders import open_encoder, parse_url
from twin.hardware.encoders.settle import SettleRule, settle
from twin.hardware.robot_sources.sim import publish_pose
from twin.hardware.virtual_encoder import MeasuringHead, serve
from twin.io.robot_file import default_robot
from twin.kinds.length import cable_length
from twin.units import deg_to_rad, mm_to_m

READINGS = 400
ROWS = 200
POSES = 60
PORT_M = mm_to_m([600.0, -400.0, 100.0])


def start_device(protocol: str, pose_file: Path) -> str:
    robot = default_robot()
    instrument = MeasuringHead(lambda q, _from: cable_length(robot.structure, robot.dh, q, PORT_M),
                            lambda length_m, _rng: length_m, 6, pose_file, seed=0)
    paths: queue.Queue[str] = queue.Queue()
    threading.Thread(target=serve, args=(instrument, protocol), daemon=True,
                     kwargs={"announce": paths.put}).start()
    return paths.get(timeout=30)


def readings_per_s(url: str) -> float:
    with open_encoder(parse_url(url)) as encoder:
        encoder.read_m()
        started = time.perf_counter()
        for _ in range(READINGS):
            encoder.read_m()
        return READINGS / (time.perf_counter() - started)


def poses_per_s(url: str, pose_file: Path) -> tuple[float, float]:
    """Settled poses per second (k = 5 within 0.01 mm), and mean readings per pose."""
    q_rad = deg_to_rad(np.random.default_rng(0).uniform(-60, 60, size=(POSES, 6)))
    readings = 0
    with open_encoder(parse_url(url)) as encoder:
        started = time.perf_counter()
        for pose, q in enumerate(q_rad, start=1):
            publish_pose(pose_file, pose, q, np.zeros(6))
            readings += settle(encoder.read_m, SettleRule(k=5)).readings
        return POSES / (time.perf_counter() - started), readings / POSES


def append_s(folder: Path, durable: bool) -> float:
    """Seconds per row appended."""
    path = folder / f"rows_{durable}.csv"
    path.write_text(HEADER)
    record = journal(path, 6)
    q = np.zeros(6)
    started = time.perf_counter()
    for pose in range(1, ROWS + 1):
        line = format_row(pose, q, 0.5, np.ones(6, dtype=np.int8))
        if durable:
            record.append(line)
        else:
            with open(path, "a", encoding="utf-8") as handle:
                handle.write(line)
    return (time.perf_counter() - started) / ROWS


def main() -> None:
    global READINGS, ROWS, POSES
    if tiny_run(__doc__):
        READINGS, ROWS, POSES = 5, 5, 2
    with tempfile.TemporaryDirectory(dir=Path.cwd()) as name:
        folder = Path(name)
        pose_file = folder / "pose.json"
        publish_pose(pose_file, 1, np.zeros(6), np.zeros(6))
        ascii_path, modbus_path = (start_device(p, pose_file) for p in ("ascii", "modbus"))
        rates = {
            "ascii": readings_per_s(f"serial://{ascii_path}"),
            "modbus 9600": readings_per_s(f"serial://{modbus_path}?protocol=modbus&scale=0.001"),
            "modbus 115200": readings_per_s(
                f"serial://{modbus_path}?protocol=modbus&scale=0.001&baud=115200"),
        }
        print(f"readings/s over a pty ({READINGS} readings each):")
        for name_, rate in rates.items():
            print(f"  {name_:14s} {rate:8.0f}/s   ascii / this = {rates['ascii'] / rate:5.2f}")
        pose_rate, per_pose = poses_per_s(f"serial://{ascii_path}", pose_file)
        print(f"settled poses/s over ASCII (k = 5, 0.01 mm): {pose_rate:.0f}/s, "
              f"{per_pose:.1f} readings per pose")
        plain, durable = append_s(folder, False), append_s(folder, True)
        print(f"append per row ({ROWS} rows, {os.statvfs(folder).f_bsize} B blocks, beside "
              f"the repository): plain {plain * 1e6:.1f} µs, O_APPEND + fsync "
              f"{durable * 1e6:.1f} µs, ratio {durable / plain:.1f}")
        print(f"fsync share of one settled ASCII pose: "
              f"{durable / (durable + 1 / pose_rate) * 100:.1f} %")


if __name__ == "__main__":
    main()

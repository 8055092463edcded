"""A virtual drawstring encoder on a pseudo-terminal, answering as the real instrument would.

The host side is the slave of a pseudo-terminal (``/dev/pts/N``); drivers open it with pyserial
exactly as they would open ``/dev/ttyUSB0``. Protocols:

- ``ascii``: a line ``MEAS?`` (CR LF) gets one signed decimal in mm with 3 decimals and CR LF,
  e.g. ``+0123.456``; any other line gets ``ERR``. The device answers on the pty master.
- ``modbus``: a Modbus RTU slave served by pymodbus (``ModbusSerialServer``, a ``SimDevice``
  whose action fills the registers at each request). pymodbus opens a port by path, so it opens
  the slave of a second pty and the two masters are joined like a null-modem cable. Holding and
  input registers (functions 3 and 4) hold the same values:

  ====== ======= ====================================
  regs   type    value
  ====== ======= ====================================
  0–1    int32   length in µm, high word first (ABCD)
  2–3    int32   length in µm, low word first (CDAB)
  4–5    float32 length in mm, high word first
  ====== ======= ====================================

The length is the twin's (:class:`twin.sim.Twin`: true robot, joint errors with the backlash side
of the approach, static equilibrium) at the pose the simulated robot was last sent to, read from
the pose file (:mod:`twin.hardware.robot_sources.sim`) at every query. Reading ``j`` = 1, 2, …
after a move is the scenario's encoder model (:class:`twin.sim.NoiseModel`: offset, Gaussian
noise, outliers, resolution) applied to ``L + A·(−½)^(j−1)``, a decaying swing of the cable
(A = :data:`TRANSIENT_M`). Its random draws come from a generator seeded with (seed, pose) that
restarts at each move, so an interrupted capture reads the same numbers again. The arm's
repeatability jitter of the scenario is not applied here (the joints land on the command).

``garbage_every=N`` corrupts every N-th answer (test of the drivers' fault handling): ASCII
answers become, in turn, non-ASCII bytes, a line that is not a number, and a partial line
without end; Modbus answers get a wrong CRC.
"""

from __future__ import annotations

import asyncio
import os
import tty
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from twin.errors import InputError, UnknownChoiceError
from twin.hardware.encoders import ENCODERS
from twin.hardware.robot_sources.sim import read_pose
from twin.units import m_to_mm, mm_to_m
from twin.waiting import serve_until_stopped_async

LengthSource = Callable[[NDArray[np.float64], NDArray[np.float64]], NDArray[np.float64]]
"""Noise-free cable lengths (m,) in m at joint angles (m, n) in rad approached from (n,) rad."""
Reading = Callable[[float, np.random.Generator], float]
"""What the encoder reads, m, for a true length in m, drawing its noise from the generator."""

TRANSIENT_M = float(mm_to_m(0.05))
"""First swing of the cable after a move, m; it halves and changes sign at each reading."""
QUERY = b"MEAS?"
GARBAGE = (b"\xff\xfe+01\x0023.4\r\n", b"#?E+1!2\r\n", b"+0123.")
"""Corrupt ASCII answers, in turn: non-ASCII bytes, not a number, a partial line."""
MICROMETRE_M = float(mm_to_m(1e-3))
"""One count of the Modbus integer registers, m."""


class MeasuringHead:
    """The encoder's measuring head: the reading at the robot's current commanded pose.

    Args:
        lengths_m: The twin's noise-free cable lengths.
        read: The encoder's reading of a true length.
        n_joints: Joints of the robot (the pose before any move is all zeros).
        pose_file: Where the simulated robot publishes its pose.
        seed: Seed of the noise; the generator of pose K is seeded with (seed, K).
        prismatic: Which joints slide (their values in the pose file in mm); none if empty.
    """

    def __init__(self, lengths_m: LengthSource, read: Reading, n_joints: int,
                 pose_file: str | Path, seed: int, prismatic: tuple[bool, ...] = ()) -> None:
        self.lengths_m = lengths_m
        self.read = read
        self.n_joints = n_joints
        self.prismatic = prismatic
        self.pose_file = Path(pose_file)
        self.seed = seed
        self._command: str | None = None
        self._length_m = 0.0
        self._count = 0
        self._rng = np.random.default_rng(seed)

    def reading_m(self) -> float:
        """The next reading, m."""
        commanded = read_pose(self.pose_file, self.prismatic)
        command = "" if commanded is None else commanded.command
        if command != self._command:
            home = np.zeros(self.n_joints)
            pose, q_rad, from_q_rad = (0, home, home) if commanded is None else commanded[:3]
            self._length_m = float(self.lengths_m(q_rad[None, :], from_q_rad)[0])
            self._rng = np.random.default_rng([self.seed, pose])
            self._count = 0
            self._command = command
        self._count += 1
        swing = TRANSIENT_M * (-0.5) ** (self._count - 1)
        return self.read(self._length_m + swing, self._rng)


def scenario_instrument(scenario_path: str | Path, pose_file: str | Path,
                        seed: int | None = None) -> MeasuringHead:
    """The encoder of a scenario: the twin of its true robot, its encoder noise and seed.

    The truth (D-H errors, port, joint-error phases) is :func:`twin.sim.simulate`'s for the same
    scenario and seed, so ``twin capture --robot-source sim`` writes the matching nominal robot,
    told port and truth.
    """
    from twin.dataset import approach_directions
    from twin.scenario import load_scenario
    from twin.sim import Twin, simulate

    scenario = load_scenario(scenario_path)
    sim = simulate(scenario, seed)
    if sim.port_m is None or len(sim.rig.ports_m) > 1:
        raise InputError(f"a {sim.measurements.kind} scenario with {len(sim.rig.ports_m)} ports",
                         "a scenario of one cable port (the virtual encoder serves one cable)",
                         source=scenario_path)
    twin = Twin.build(sim.true_robot, sim.port_m, scenario.physics, sim.joint_errors,
                      sim.rig.attachment_m)

    def lengths_m(q_rad: NDArray[np.float64], from_q_rad: NDArray[np.float64]
                  ) -> NDArray[np.float64]:
        return twin.lengths(q_rad, approach_directions(q_rad, from_q_rad))

    def read(length_m: float, rng: np.random.Generator) -> float:
        return float(scenario.noise.read(np.array([length_m]), rng).length_m[0])

    return MeasuringHead(lengths_m, read, sim.robot.n_joints, pose_file, sim.seed,
                         tuple(bool(v) for v in sim.robot.prismatic))


def _open_pty() -> tuple[int, int, str]:
    """A raw pseudo-terminal: (master fd, slave fd, slave path)."""
    master, slave = os.openpty()
    tty.setraw(slave)
    os.set_blocking(master, False)
    return master, slave, os.ttyname(slave)


class _Every:
    """True on every N-th call (never if N is 0)."""

    def __init__(self, every: int) -> None:
        self.every, self.count = every, 0

    def __call__(self) -> bool:
        self.count += 1
        return self.every > 0 and self.count % self.every == 0


class _AsciiDevice:
    """Answers ASCII queries arriving on a pty master."""

    def __init__(self, instrument: MeasuringHead, master: int, garbage_every: int) -> None:
        self.instrument, self.master = instrument, master
        self.corrupt = _Every(garbage_every)
        self.buffer = b""

    def on_readable(self) -> None:
        try:
            self.buffer += os.read(self.master, 4096)
        except OSError:
            return  # EIO: no host has the port open
        while b"\n" in self.buffer:
            line, self.buffer = self.buffer.split(b"\n", 1)
            os.write(self.master, self.answer(line.strip()))

    def answer(self, line: bytes) -> bytes:
        if line != QUERY:
            return b"ERR\r\n"
        length_mm = float(m_to_mm(self.instrument.reading_m()))
        if self.corrupt():
            return GARBAGE[(self.corrupt.count // self.corrupt.every - 1) % len(GARBAGE)]
        return f"{length_mm:+09.3f}\r\n".encode("ascii")


def _join(loop: asyncio.AbstractEventLoop, a: int, b: int) -> None:
    """Copy bytes both ways between two pty masters: a null-modem cable."""

    def copy(source: int, target: int) -> None:
        try:
            data = os.read(source, 4096)
        except OSError:
            return
        os.write(target, data)

    loop.add_reader(a, copy, a, b)
    loop.add_reader(b, copy, b, a)


def _registers(length_m: float) -> list[int]:
    """The six registers of the table in the module docstring."""
    counts = round(length_m / MICROMETRE_M) & 0xFFFFFFFF
    high, low = counts >> 16, counts & 0xFFFF
    bits = int(np.array(m_to_mm(length_m), dtype=">f4").view(">u4"))
    return [high, low, low, high, bits >> 16, bits & 0xFFFF]


async def _serve_modbus(instrument: MeasuringHead, host_master: int, slave_id: int,
                        garbage_every: int) -> Any:
    from pymodbus import FramerType
    from pymodbus.server import ModbusSerialServer
    from pymodbus.simulator import DataType, SimData, SimDevice

    async def action(function_code: int, start_address: int, address: int, count: int,
                     registers: list[int], set_values: list[int] | list[bool] | None) -> None:
        if set_values is None:
            registers[:6] = _registers(instrument.reading_m())

    corrupt = _Every(garbage_every)

    def trace_packet(sending: bool, data: bytes) -> bytes:
        if not sending or not data:
            return data
        if data[0] != slave_id:
            # Silence, as on an RS-485 bus, for requests to other slaves: pymodbus 3.16 answers
            # them with "device failure" (its SimCore raises KeyError, not NoSuchIdException,
            # so ignore_missing_devices has no effect).
            return b""
        if corrupt():
            return data[:-1] + bytes([data[-1] ^ 0xFF])
        return data

    device_master, _device_slave, device_path = _open_pty()
    _join(asyncio.get_running_loop(), host_master, device_master)
    server = ModbusSerialServer(
        SimDevice(id=slave_id, simdata=[SimData(0, count=6, values=0,
                                                datatype=DataType.REGISTERS)], action=action),
        framer=FramerType.RTU, port=device_path, trace_packet=trace_packet,
    )
    await server.serve_forever(background=True)
    return server


async def _serve(instrument: MeasuringHead, protocol: str, slave_id: int, garbage_every: int,
                 announce: Callable[[str], None]) -> None:
    master, _slave, path = _open_pty()
    # Keeping our own slave fd open means the master never reads EIO between two captures.
    loop = asyncio.get_running_loop()
    if protocol == "modbus":
        server = await _serve_modbus(instrument, master, slave_id, garbage_every)
    else:
        server = None
        loop.add_reader(master, _AsciiDevice(instrument, master, garbage_every).on_readable)
    announce(path)
    try:
        await serve_until_stopped_async()
    finally:
        if server is not None:
            await server.shutdown()


def serve(instrument: MeasuringHead, protocol: str, *, slave_id: int = 1, garbage_every: int = 0,
          announce: Callable[[str], None] | None = None) -> None:
    """Serve the instrument on a new pseudo-terminal until the process is stopped.

    Args:
        instrument: The measuring head.
        protocol: ``ascii`` or ``modbus``.
        slave_id: Modbus slave id.
        garbage_every: Corrupt every N-th answer (0: never).
        announce: Called with the host-side device path once the device answers.
    """
    if protocol not in ENCODERS:
        raise UnknownChoiceError("protocol", protocol, ENCODERS)
    # One length before the device answers: the first loads the kinematics kernel (the
    # compiled one's cached code takes up to a second), which a driver's first read must not
    # wait for.
    home = np.zeros(instrument.n_joints)
    instrument.lengths_m(home[None, :], home)

    def default_announce(path: str) -> None:
        print(path, flush=True)

    asyncio.run(_serve(instrument, protocol, slave_id, garbage_every,
                       announce or default_announce))

"""Encoder drivers over a real pseudo-terminal, their settings, and the settling rule.

The device is :mod:`twin.hardware.virtual_encoder` served in a thread of the test process on a
real pty: the drivers open ``/dev/pts/N`` with pyserial (and minimalmodbus) as they would a USB
adapter.
Its length source here is the core's closed form and its reading is exact, so every value a
driver returns can be checked to the device's resolution.
"""

from __future__ import annotations

import math
import os
import queue
import threading
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest

from twin.errors import InputError
from twin.hardware.capture_session import measure
from twin.hardware.encoders import (
    EncoderConfig,
    EncoderDisconnectedError,
    EncoderReadError,
    load_device,
    open_encoder,
    parse_url,
)
from twin.hardware.encoders.settle import SettleRule, SettleTimeoutError, settle
from twin.hardware.robot_sources.sim import publish_pose
from twin.hardware.virtual_encoder import TRANSIENT_M, MeasuringHead, serve
from twin.io.robot_file import default_robot
from twin.kinds.length import cable_length
from twin.units import deg_to_rad, m_to_mm, mm_to_m

PORT_M = mm_to_m([600.0, -400.0, 100.0])
Q_RAD = deg_to_rad([20.0, 30.0, -40.0, 10.0, 50.0, 0.0])
ROBOT = default_robot()
TRUE_M = float(cable_length(ROBOT.structure, ROBOT.dh, Q_RAD[None, :], PORT_M)[0])


def expected_m(j: int) -> float:
    """The exact j-th reading after a move (the device's settling swing, no noise), m."""
    return TRUE_M + TRANSIENT_M * (-0.5) ** (j - 1)


def start_device(protocol: str, pose_file: Path, garbage_every: int = 0) -> str:
    """Serve an exact virtual encoder on a new pty in a daemon thread; its host path."""
    instrument = MeasuringHead(lambda q, _from: cable_length(ROBOT.structure, ROBOT.dh, q, PORT_M),
                            lambda length_m, _rng: length_m, 6, pose_file, seed=0)
    paths: queue.Queue[str] = queue.Queue()
    threading.Thread(target=serve, args=(instrument, protocol), daemon=True,
                     kwargs={"garbage_every": garbage_every, "announce": paths.put}).start()
    return paths.get(timeout=30)


@pytest.fixture(scope="module")
def pose_file(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return tmp_path_factory.mktemp("encoders") / "pose.json"


@pytest.fixture(scope="module")
def ascii_path(pose_file: Path) -> str:
    return start_device("ascii", pose_file)


@pytest.fixture(scope="module")
def modbus_path(pose_file: Path) -> str:
    return start_device("modbus", pose_file)


@pytest.fixture()
def moved(pose_file: Path) -> Iterator[None]:
    """Send the simulated robot to Q_RAD: the device restarts its reading sequence."""
    publish_pose(pose_file, 1, Q_RAD, np.zeros(6))
    yield


def test_url_defaults_are_9600_8n1_ascii_with_meas_query() -> None:
    """A bare URL gives the documented defaults; the query keys override them."""
    config = parse_url("serial:///dev/ttyUSB0")
    assert (config.port, config.protocol, config.baud, config.bytesize, config.parity,
            config.stopbits) == ("/dev/ttyUSB0", "ascii", 9600, 8, "N", 1)
    assert config.query == "MEAS?\r\n" and config.unit == "mm" and config.m_per_count == 1e-3
    config = parse_url("serial:///dev/ttyUSB0?baud=115200&protocol=modbus&slave=3&register=0x10"
                       "&word_order=little&scale=0.001&parity=e")
    assert (config.baud, config.protocol, config.slave, config.register, config.word_order,
            config.parity) == (115200, "modbus", 3, 16, "little", "E")
    assert math.isclose(config.m_per_count, 1e-6)


def test_url_round_trips_and_device_toml_gives_the_same_config(tmp_path: Path) -> None:
    """to_url() parses back to the same config; a device TOML with the same keys is equal."""
    config = parse_url("serial:///dev/ttyS1?baud=19200&query=RD%0D%0A&pattern=L%3D(%5Cd%2B)"
                       "&unit=m&timeout=0.5")
    assert config.query == "RD\r\n" and config.pattern == r"L=(\d+)"
    assert parse_url(config.to_url()) == config
    device = tmp_path / "encoder.toml"
    device.write_text('port = "/dev/ttyS1"\nbaud = 19200\nquery = "RD\\r\\n"\n'
                      'pattern = \'L=(\\d+)\'\nunit = "m"\ntimeout = 0.5\n')
    assert load_device(device) == config


@pytest.mark.parametrize(("url", "where"), [
    ("serial:///dev/ttyUSB0?baud=fast", "baud"),
    ("serial:///dev/ttyUSB0?protocol=canbus", "protocol"),
    ("serial:///dev/ttyUSB0?speed=9600", "speed"),
    ("serial:///dev/ttyUSB0?function=6&protocol=modbus", "function"),
    ("serial:///dev/ttyUSB0?min=5&max=1", "max"),
    ("tcp://10.0.0.1:502", "serial:///"),
])
def test_bad_settings_name_the_key(url: str, where: str) -> None:
    """Each bad URL is one InputError whose message names the offending key."""
    with pytest.raises(InputError, match=where):
        parse_url(url)


def test_settle_averages_the_first_k_readings_that_agree() -> None:
    """A decaying swing settles once k readings lie within the tolerance; their mean is used."""
    readings = iter([1.0, 0.5, 0.25, 0.125, 0.0625, 0.062, 0.0621, 0.0622, 9.0])
    settled = settle(lambda: next(readings), SettleRule(k=4, tolerance_m=0.001))
    assert settled.readings == 8 and settled.failures == 0
    assert settled.length_m == pytest.approx((0.0625 + 0.062 + 0.0621 + 0.0622) / 4)
    assert settled.spread_m == pytest.approx(0.0005)


def test_settle_retries_failed_readings_then_gives_up() -> None:
    """Isolated failures are retried (and reported); max_failures in a row stop the wait."""
    seen: list[str] = []
    sequence: list[float | None] = [1.0, None, 1.0, None, 1.0]

    def read() -> float:
        value = sequence.pop(0)
        if value is None:
            raise EncoderReadError("garbled")
        return value

    settled = settle(read, SettleRule(k=3, tolerance_m=0.0, max_failures=2),
                     on_failure=lambda exc: seen.append(str(exc)))
    assert (settled.length_m, settled.readings, settled.failures) == (1.0, 5, 2)
    assert seen == ["garbled", "garbled"]

    def broken() -> float:
        raise EncoderReadError("garbled")

    with pytest.raises(EncoderReadError, match="3 failed readings in a row"):
        settle(broken, SettleRule(max_failures=3))


def test_settle_times_out_on_a_value_that_keeps_moving() -> None:
    """A drifting value raises SettleTimeoutError once the (simulated) clock passes timeout."""
    ticks = iter(range(1000))
    drift = iter(np.arange(1000) * 1e-3)
    with pytest.raises(SettleTimeoutError, match="did not settle within 5 s"):
        settle(lambda: float(next(drift)), SettleRule(k=3, tolerance_m=1e-4, timeout_s=5),
               clock=lambda: float(next(ticks)))


@pytest.mark.usefixtures("moved")
def test_ascii_driver_reads_the_devices_sequence(ascii_path: str) -> None:
    """MEAS? over the pty: each answer is the device's reading to its 0.001 mm resolution."""
    with open_encoder(parse_url(f"serial://{ascii_path}")) as encoder:
        values = [encoder.read_m() for _ in range(6)]
    expected = [expected_m(j) for j in range(1, 7)]
    assert np.allclose(m_to_mm(values), m_to_mm(expected), atol=0.0005 + 1e-9)


@pytest.mark.usefixtures("moved")
def test_modbus_driver_reads_every_register_layout(modbus_path: str) -> None:
    """minimalmodbus over the pty reads int32 µm in both word orders and float32 mm alike."""
    base = f"serial://{modbus_path}?protocol=modbus&timeout=0.5"
    # int32 counts µm (half a count of rounding); float32 keeps ~7 digits of ~1000 mm.
    layouts = [("&scale=0.001", 5e-4), ("&scale=0.001&register=2&word_order=little", 5e-4),
               ("&register=4&type=float32", 1e-4)]
    for j, (extra, atol_mm) in enumerate(layouts, start=1):
        with open_encoder(parse_url(base + extra)) as encoder:
            value = encoder.read_m()
        assert float(m_to_mm(value)) == pytest.approx(float(m_to_mm(expected_m(j))),
                                                      abs=atol_mm + 1e-9)


def test_ascii_garbage_and_partial_lines_fail_one_reading_each(pose_file: Path) -> None:
    """Non-ASCII bytes, a non-number and a partial line are read errors; the line recovers."""
    path = start_device("ascii", pose_file, garbage_every=3)
    publish_pose(pose_file, 1, Q_RAD, np.zeros(6))
    outcomes: list[str | float] = []
    with open_encoder(parse_url(f"serial://{path}?timeout=0.3")) as encoder:
        for _ in range(10):
            try:
                outcomes.append(encoder.read_m())
            except EncoderReadError as exc:
                outcomes.append(str(exc))
    assert "not ASCII" in str(outcomes[2])
    assert "does not match the pattern" in str(outcomes[5])
    assert "partial answer b'+0123.'" in str(outcomes[8]) and "timeout" in str(outcomes[8])
    good = [j for j in range(10) if j not in (2, 5, 8)]
    assert np.allclose(m_to_mm([outcomes[j] for j in good]),
                       m_to_mm([expected_m(j + 1) for j in good]), atol=0.0005 + 1e-9)


def test_modbus_crc_errors_and_a_silent_slave_are_read_errors(pose_file: Path,
                                                              modbus_path: str) -> None:
    """A corrupted CRC fails one reading; a wrong slave id gets no answer (timeout)."""
    path = start_device("modbus", pose_file, garbage_every=2)
    publish_pose(pose_file, 1, Q_RAD, np.zeros(6))
    with open_encoder(parse_url(f"serial://{path}?protocol=modbus&scale=0.001&timeout=0.3")
                      ) as encoder:
        first = encoder.read_m()
        with pytest.raises(EncoderReadError, match="CRC"):
            encoder.read_m()
        third = encoder.read_m()
    assert m_to_mm([first, third]) == pytest.approx(m_to_mm([expected_m(1), expected_m(3)]),
                                                    abs=5e-4 + 1e-9)
    with open_encoder(parse_url(f"serial://{modbus_path}?protocol=modbus&slave=9&timeout=0.2")
                      ) as encoder, pytest.raises(EncoderReadError, match="no answer"):
        encoder.read_m()


@pytest.mark.usefixtures("moved")
def test_out_of_range_reading_is_a_read_error(ascii_path: str) -> None:
    """A reading outside the configured [min, max] is refused, naming the keys to check."""
    with open_encoder(parse_url(f"serial://{ascii_path}?max=100")) as encoder, \
            pytest.raises(EncoderReadError, match="outside the plausible range"):
        encoder.read_m()


def test_absent_device_is_reported_as_disconnected(tmp_path: Path) -> None:
    """Opening a path with no device raises EncoderDisconnectedError naming the port."""
    missing = tmp_path / "ttyUSB9"
    for protocol in ("ascii", "modbus"):
        with pytest.raises(EncoderDisconnectedError, match="ttyUSB9"):
            open_encoder(EncoderConfig(port=str(missing), protocol=protocol))


def test_unplugged_device_is_reported_as_disconnected() -> None:
    """When the device side of the line closes, the next reading fails as disconnected."""
    master, slave = os.openpty()
    path = os.ttyname(slave)
    os.close(slave)
    encoder = open_encoder(parse_url(f"serial://{path}?timeout=0.3"))
    os.close(master)
    with pytest.raises(EncoderDisconnectedError, match=path):
        encoder.read_m()
    encoder.close()


@pytest.mark.usefixtures("moved")
def test_lost_port_is_reopened_on_the_same_path(ascii_path: str, tmp_path: Path) -> None:
    """A USB adapter unplugged and plugged back reappears behind the same by-id link: the
    reading that failed is retried on the reopened port and settles on the device's value."""
    master, slave = os.openpty()
    link = tmp_path / "usb-encoder-port0"
    link.symlink_to(os.ttyname(slave))
    encoder = open_encoder(parse_url(f"serial://{link}?timeout=0.3"))
    os.close(slave)
    link.unlink()
    link.symlink_to(ascii_path)  # what udev does when the device comes back
    os.close(master)  # unplugged: the open port fails
    lines: list[str] = []
    # The swing halves per reading: readings 4–6 are the first three within 0.012 mm.
    rule = SettleRule(k=3, tolerance_m=float(mm_to_m(0.012)))
    settled = measure(encoder, rule, 5.0, lines.append)
    encoder.close()
    assert any("trying to reopen" in line for line in lines)
    assert settled.length_m == pytest.approx(np.mean([expected_m(j) for j in (4, 5, 6)]),
                                             abs=mm_to_m(5e-4))

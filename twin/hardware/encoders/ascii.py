"""ASCII line protocol: send a query, read one line holding one number.

Default: the host sends ``MEAS?`` CR LF; the device answers a signed decimal in mm and CR LF,
e.g. ``+0123.456``. Query, answer pattern, scale and unit are configurable
(:class:`~twin.hardware.encoders.url.EncoderConfig`).
"""

from __future__ import annotations

import re
import termios

import serial

from twin.hardware.encoders.base import Encoder, EncoderDisconnectedError, EncoderReadError
from twin.hardware.encoders.url import EncoderConfig

LINE_ERRORS = (serial.SerialException, OSError, termios.error)
"""What pyserial raises when the port fails (termios.error: flushing a hung-up tty)."""


def open_serial(config: EncoderConfig) -> serial.Serial:
    """Open the configured port exclusively, with its line settings and read timeout.

    Raises:
        EncoderDisconnectedError: if the device is absent or busy.
    """
    try:
        return serial.Serial(
            config.port, baudrate=config.baud, bytesize=config.bytesize, parity=config.parity,
            stopbits=config.stopbits, timeout=config.timeout, write_timeout=config.timeout,
            exclusive=True,
        )
    except (serial.SerialException, OSError, ValueError) as exc:
        raise EncoderDisconnectedError(
            f"cannot open encoder port {config.port} (is the device plugged in, the path right "
            f"and the port free?): {exc}") from None


class AsciiEncoder(Encoder):
    """An encoder answering ASCII queries."""

    _port: serial.Serial | None = None

    def open(self) -> None:
        """(Re)open the port."""
        self.close()
        self._pattern = re.compile(self.config.pattern)
        self._query = self.config.query.encode("latin-1")
        self._port = open_serial(self.config)

    def close(self) -> None:
        """Close the port."""
        if self._port is not None:
            self._port.close()
            self._port = None

    def read_raw(self) -> float:
        """Send the query and parse the answer line."""
        port = self.config.port
        if self._port is None:
            raise EncoderDisconnectedError(f"encoder port {port} is closed")
        try:
            # A late answer to an earlier, timed-out query must not be taken for this one.
            self._port.reset_input_buffer()
            self._port.write(self._query)
            answer = self._port.read_until(b"\n")
        except serial.SerialTimeoutException:
            raise EncoderReadError(f"{port}: could not send the query within "
                                   f"{self.config.timeout:g} s") from None
        except LINE_ERRORS as exc:
            raise EncoderDisconnectedError(f"encoder port {port} failed: {exc}") from None
        if not answer.endswith(b"\n"):
            what = f"a partial answer {answer!r}" if answer else "no answer"
            raise EncoderReadError(f"{port}: {what} within {self.config.timeout:g} s "
                                   "(timeout; expected a line ending in LF)")
        try:
            text = answer.decode("ascii").strip()
        except UnicodeDecodeError:
            raise EncoderReadError(f"{port}: garbage answer {answer!r} (not ASCII)") from None
        match = self._pattern.fullmatch(text)
        if match is None:
            raise EncoderReadError(f"{port}: answer {text!r} does not match the pattern "
                                   f"{self.config.pattern!r}")
        number = match.group(1) if self._pattern.groups else match.group(0)
        try:
            return float(number)
        except ValueError:
            raise EncoderReadError(f"{port}: {number!r} in answer {text!r} is not a number") \
                from None

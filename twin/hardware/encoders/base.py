"""The encoder interface: one reading of the cable length at a time, and its faults.

Drivers talk to the device through pyserial exactly as to ``/dev/ttyUSB0``; the virtual encoder
(:mod:`twin.hardware.virtual_encoder`) serves a pseudo-terminal, so tests run this same code.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from types import TracebackType

from twin.errors import TwinError
from twin.hardware.encoders.url import EncoderConfig


class EncoderError(TwinError):
    """A fault of the encoder or of its line."""


class EncoderDisconnectedError(EncoderError):
    """The device is absent, was unplugged, or its port failed: reading again will not help."""


class EncoderReadError(EncoderError):
    """One reading failed (timeout, garbage or partial answer, CRC error, out-of-range value).

    The next reading may succeed: callers retry a few times.
    """


class Encoder(ABC):
    """A drawstring encoder on a serial line.

    Attributes:
        config: The settings the driver was opened with.
    """

    def __init__(self, config: EncoderConfig) -> None:
        self.config = config
        self.open()

    @abstractmethod
    def open(self) -> None:
        """(Re)open the serial port.

        Raises:
            EncoderDisconnectedError: if the device is absent or cannot be opened.
        """

    @abstractmethod
    def read_raw(self) -> float:
        """One value as the device reports it, before ``scale``.

        Raises:
            EncoderReadError: if this reading failed but the line is alive.
            EncoderDisconnectedError: if the port failed.
        """

    @abstractmethod
    def close(self) -> None:
        """Close the port; closing twice is harmless."""

    def read_m(self) -> float:
        """One reading of the cable length, m, checked against the configured range.

        Raises:
            EncoderReadError: if the reading failed or is outside ``[min, max]``.
            EncoderDisconnectedError: if the port failed.
        """
        length_m = self.read_raw() * self.config.m_per_count
        low_m, high_m = self.config.range_m
        if not low_m <= length_m <= high_m:
            raise EncoderReadError(
                f"{self.config.port}: reading {length_m:.6g} m is outside the plausible range "
                f"[{low_m:g}, {high_m:g}] m (keys min, max, scale, unit)"
            )
        return length_m

    def __enter__(self) -> Encoder:
        return self

    def __exit__(
        self, kind: type[BaseException] | None, value: BaseException | None,
        traceback: TracebackType | None,
    ) -> None:
        self.close()

"""Drawstring-encoder drivers behind one interface (:class:`~twin.hardware.encoders.base.Encoder`).

An adapter: pyserial and minimalmodbus are imported by the drivers, when :func:`open_encoder`
opens one.
"""

from __future__ import annotations

from twin.hardware.encoders.base import (
    Encoder,
    EncoderDisconnectedError,
    EncoderError,
    EncoderReadError,
)
from twin.hardware.encoders.url import EncoderConfig, load_device, parse_url, resolve

__all__ = [
    "Encoder",
    "EncoderConfig",
    "EncoderDisconnectedError",
    "EncoderError",
    "EncoderReadError",
    "load_device",
    "open_encoder",
    "parse_url",
    "resolve",
]


def open_encoder(config: EncoderConfig) -> Encoder:
    """Open the driver of ``config.protocol`` on ``config.port``.

    Raises:
        EncoderDisconnectedError: if the device is absent.
    """
    if config.protocol == "modbus":
        from twin.hardware.encoders.modbus import ModbusEncoder

        return ModbusEncoder(config)
    from twin.hardware.encoders.ascii import AsciiEncoder

    return AsciiEncoder(config)

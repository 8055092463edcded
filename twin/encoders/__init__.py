"""Drawstring-encoder drivers behind one interface (:class:`~twin.encoders.base.Encoder`).

An adapter: it imports pyserial and minimalmodbus. The CLI imports it inside ``run()`` only.
"""

from __future__ import annotations

from twin.encoders.base import Encoder, EncoderDisconnectedError, EncoderError, EncoderReadError
from twin.encoders.url import EncoderConfig, load_device, parse_url, resolve

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
        from twin.encoders.modbus import ModbusEncoder

        return ModbusEncoder(config)
    from twin.encoders.ascii import AsciiEncoder

    return AsciiEncoder(config)

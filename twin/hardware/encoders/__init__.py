"""Drawstring-encoder drivers behind one interface (:class:`~twin.hardware.encoders.base.Encoder`),
registered by protocol in :data:`ENCODERS`.

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
from twin.hardware.encoders.url import ENCODERS, EncoderConfig, load_device, parse_url, resolve

__all__ = [
    "ENCODERS",
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
    return ENCODERS.lookup(config.protocol)(config)

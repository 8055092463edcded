"""Drawstring-encoder drivers behind one interface (:class:`~twin.hardware.encoders.base.Encoder`),
registered by protocol in :data:`ENCODERS`.

An adapter: pyserial and minimalmodbus are imported by the drivers, when :func:`open_encoder`
opens one.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from twin.distribution import Lazy, Registry, lazy_exports

if TYPE_CHECKING:
    from twin.hardware.encoders.base import (
        Encoder,
        EncoderDisconnectedError,
        EncoderError,
        EncoderReadError,
    )
    from twin.hardware.encoders.url import EncoderConfig, load_device, parse_url, resolve

ENCODERS: Registry[type[Encoder]] = Registry("protocol", {
    "ascii": Lazy("twin.hardware.encoders.ascii:AsciiEncoder"),
    "modbus": Lazy("twin.hardware.encoders.modbus:ModbusEncoder"),
})
"""Every driver, by the ``protocol`` key of a device's configuration
(:class:`~twin.hardware.encoders.url.EncoderConfig`) that selects it; a driver's module (and
pyserial, minimalmodbus) is imported when it is opened."""

__getattr__ = lazy_exports(__name__, {
    "twin.hardware.encoders.base": ("Encoder", "EncoderDisconnectedError", "EncoderError",
                                    "EncoderReadError"),
    "twin.hardware.encoders.url": ("EncoderConfig", "load_device", "parse_url", "resolve")})

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

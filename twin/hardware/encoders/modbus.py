"""Modbus RTU: read the length from one or two registers with minimalmodbus.

Configurable (:class:`~twin.hardware.encoders.url.EncoderConfig`): slave id, register address,
function 3 (holding) or 4 (input registers), value type (int32, int16, float32), 32-bit word
order and scale (device counts to ``unit``): a signed 32-bit count of µm, high word first, is
``protocol=modbus&type=int32&scale=0.001``.
"""

from __future__ import annotations

import minimalmodbus

from twin.hardware.encoders.ascii import LINE_ERRORS, open_serial
from twin.hardware.encoders.base import (
    Encoder,
    EncoderDisconnectedError,
    EncoderError,
    EncoderReadError,
)

_BYTE_ORDERS = {"big": minimalmodbus.BYTEORDER_BIG, "little": minimalmodbus.BYTEORDER_LITTLE_SWAP}
"""Word order to minimalmodbus byte order: ABCD (high word first) or CDAB (low word first)."""


class ModbusEncoder(Encoder):
    """An encoder read over Modbus RTU (minimalmodbus as the client)."""

    _instrument: minimalmodbus.Instrument | None = None

    def open(self) -> None:
        """(Re)open the port; the instrument gets our own serial object, not a shared one."""
        self.close()
        # A port object of our own: minimalmodbus would otherwise cache one per path, which
        # stays broken after the device is unplugged and plugged back.
        instrument = minimalmodbus.Instrument(open_serial(self.config), self.config.slave,
                                              mode=minimalmodbus.MODE_RTU)
        instrument.clear_buffers_before_each_transaction = True
        self._instrument = instrument

    def close(self) -> None:
        """Close the port."""
        if self._instrument is not None:
            self._instrument.serial.close()
            self._instrument = None

    def read_raw(self) -> float:
        """Read the value registers."""
        config, instrument = self.config, self._instrument
        if instrument is None:
            raise EncoderDisconnectedError(f"encoder port {config.port} is closed")
        order = _BYTE_ORDERS[config.word_order]
        try:
            if config.type == "int32":
                return float(instrument.read_long(config.register, config.function, signed=True,
                                                  byteorder=order))
            if config.type == "float32":
                return float(instrument.read_float(config.register, config.function,
                                                   byteorder=order))
            return float(instrument.read_register(config.register, 0, config.function,
                                                  signed=True))
        except minimalmodbus.NoResponseError:
            raise EncoderReadError(f"{config.port}: no answer from Modbus slave {config.slave} "
                                   f"within {config.timeout:g} s (timeout)") from None
        except minimalmodbus.InvalidResponseError as exc:
            raise EncoderReadError(f"{config.port}: invalid Modbus answer (CRC or framing "
                                   f"error): {exc}") from None
        except minimalmodbus.SlaveDeviceBusyError:
            raise EncoderReadError(f"{config.port}: Modbus slave {config.slave} is busy") \
                from None
        except minimalmodbus.SlaveReportedException as exc:
            raise EncoderError(
                f"{config.port}: Modbus slave {config.slave} refused to read register "
                f"{config.register} with function {config.function}: {exc}") from None
        except minimalmodbus.ModbusException as exc:
            raise EncoderReadError(f"{config.port}: Modbus transaction failed: {exc}") from None
        except LINE_ERRORS as exc:
            raise EncoderDisconnectedError(f"encoder port {config.port} failed: {exc}") from None

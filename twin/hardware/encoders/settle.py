"""Read until the cable length settles, then average.

After the robot stops, the cable and the arm still move a little. A reading is accepted when
``k`` consecutive readings lie within ``tolerance`` of each other (max − min); their mean is the
measurement. Failed readings (timeouts, garbage, CRC errors) are retried up to
``max_failures`` in a row; the whole wait is bounded by ``timeout`` (unless the user turned the
limit off explicitly).
"""

from __future__ import annotations

import math
import time
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass
from typing import NamedTuple

from twin.hardware.encoders.base import EncoderError, EncoderReadError
from twin.report.display import AS_GIVEN, mm, mm_values
from twin.units import mm_to_m


@dataclass(frozen=True)
class SettleRule:
    """When a series of readings counts as settled.

    Attributes:
        k: Consecutive readings that must agree.
        tolerance_m: Largest spread (max − min) of those readings, m.
        timeout_s: Longest wait for the value to settle, s; None waits until it settles.
        max_failures: Failed readings in a row before giving up.
        interval_s: Pause between readings, s.
    """

    k: int = 5
    tolerance_m: float = float(mm_to_m(0.01))
    timeout_s: float | None = 10.0
    max_failures: int = 5
    interval_s: float = 0.0

    def __post_init__(self) -> None:
        if self.k < 1 or self.max_failures < 1:
            raise ValueError("k and max_failures must be >= 1")
        timeout_ok = self.timeout_s is None or 0 < self.timeout_s < math.inf
        if not (0 <= self.tolerance_m < math.inf and timeout_ok
                and 0 <= self.interval_s < math.inf):
            raise ValueError("finite tolerance_m >= 0, timeout_s > 0 (or None) and "
                             "interval_s >= 0 expected")


class Settled(NamedTuple):
    """A settled measurement."""

    length_m: float
    """Mean of the last k readings, m."""
    spread_m: float
    """max − min of those readings, m."""
    readings: int
    """Readings taken, including failed ones."""
    failures: int
    """Failed readings that were retried."""


class SettleTimeoutError(EncoderError):
    """The value did not settle in time."""


def settle(
    read_m: Callable[[], float],
    rule: SettleRule,
    *,
    on_failure: Callable[[EncoderReadError], None] | None = None,
    clock: Callable[[], float] = time.monotonic,
) -> Settled:
    """Read until ``rule.k`` consecutive readings agree within ``rule.tolerance_m``.

    Args:
        read_m: One reading, m; raises EncoderReadError on a failed reading.
        rule: Settling rule.
        on_failure: Called with each retried failure (to report it).
        clock: Monotonic time source, s.

    Raises:
        SettleTimeoutError: if the readings do not settle within ``rule.timeout_s``.
        EncoderReadError: after ``rule.max_failures`` failed readings in a row.
        EncoderDisconnectedError: as soon as the port fails.
    """
    window: deque[float] = deque(maxlen=rule.k)
    deadline = math.inf if rule.timeout_s is None else clock() + rule.timeout_s
    readings = failures = in_a_row = 0
    while True:
        readings += 1
        try:
            window.append(read_m())
            in_a_row = 0
        except EncoderReadError as exc:
            failures += 1
            in_a_row += 1
            if in_a_row >= rule.max_failures:
                raise EncoderReadError(f"{exc} ({in_a_row} failed readings in a row)") from None
            if on_failure is not None:
                on_failure(exc)
        if len(window) == rule.k:
            spread = max(window) - min(window)
            if spread <= rule.tolerance_m:
                return Settled(sum(window) / rule.k, spread, readings, failures)
        if clock() > deadline:
            last = mm_values(list(window))
            raise SettleTimeoutError(
                f"the length did not settle within {rule.timeout_s:g} s: the last readings "
                f"[{last}] mm are not {rule.k} within {mm(rule.tolerance_m, significant=AS_GIVEN)}"
            )
        if rule.interval_s:
            time.sleep(rule.interval_s)

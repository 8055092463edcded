"""Measurement kinds behind one interface (:class:`~twin.kinds.base.Kind`), one module each,
in one registry (:data:`KINDS`)."""

from __future__ import annotations

from twin.distribution import Registry
from twin.kinds.base import Kind, KindJacobian
from twin.kinds.length import Length
from twin.kinds.point import Point
from twin.kinds.position import Position

KINDS: Registry[Kind] = Registry("measurement kind",
                                 {kind.name: kind for kind in (Length(), Position(), Point())})
"""Every measurement kind, by the name :attr:`twin.dataset.Measurements.kind` gives
(``KINDS.lookup(name)``)."""

__all__ = ["KINDS", "Kind", "KindJacobian"]

"""Measurement kinds behind one interface (:class:`~twin.kinds.base.Kind`), one module each,
in one registry (:data:`KINDS`).

A kind owns everything about its readings (:mod:`twin.kinds.base`): nothing outside this package
asks which kind a measurement is. A new kind is one module and its line here.
"""

from __future__ import annotations

from twin.distribution import Registry
from twin.kinds.base import Canvas, Kind, KindJacobian, Measured
from twin.kinds.length import Length
from twin.kinds.plane import Plane
from twin.kinds.point import Point
from twin.kinds.pose import Pose
from twin.kinds.position import Position

KINDS: Registry[Kind] = Registry("measurement kind", {
    kind.name: kind for kind in (Length(), Position(), Point(), Pose(), Plane())})
"""Every measurement kind, by the name :attr:`twin.dataset.Measurements.kind` gives
(``KINDS.lookup(name)``)."""

DEFAULT_KIND = Length.name
"""The kind a calibration assumes when none is named: the paper's, cable lengths."""

__all__ = ["DEFAULT_KIND", "KINDS", "Canvas", "Kind", "KindJacobian", "Measured"]

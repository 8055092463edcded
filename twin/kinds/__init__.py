"""Measurement kinds behind one interface (:class:`~twin.kinds.base.Kind`), one module each."""

from __future__ import annotations

from twin.errors import UnknownChoiceError
from twin.kinds.base import Kind, KindJacobian
from twin.kinds.length import Length
from twin.kinds.point import Point
from twin.kinds.position import Position

KINDS: dict[str, Kind] = {kind.name: kind for kind in (Length(), Position(), Point())}
"""Every measurement kind, by the name :attr:`twin.dataset.Measurements.kind` gives."""


def get_kind(name: str) -> Kind:
    """The measurement kind called ``name``.

    Raises:
        UnknownChoiceError: listing the kinds.
    """
    if name not in KINDS:
        raise UnknownChoiceError("measurement kind", name, KINDS)
    return KINDS[name]


__all__ = ["KINDS", "Kind", "KindJacobian", "get_kind"]

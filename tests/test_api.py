"""The package's public names: everything `__all__` lists is importable from `twin`."""

from __future__ import annotations

import twin


def test_every_public_name_is_there() -> None:
    """`from twin import *` gives every name `__all__` lists, and the quick start's settings
    value is among them."""
    namespace: dict[str, object] = {}
    exec("from twin import *", namespace)
    assert set(twin.__all__) <= set(namespace)
    assert {"CalibrationSettings", "load_result", "calibrate"} <= set(twin.__all__)

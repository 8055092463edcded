"""The display module: every number a user reads, in the unit and form it is read in."""

from __future__ import annotations

import pytest

from twin.report.display import deg, mm, plain


@pytest.mark.parametrize(("value", "decimals", "sign", "shown"), [
    (-1e-14, 4, False, "0.0000"),      # a held unknown's round-off
    (-1e-14, 4, True, "+0.0000"),
    (-4e-5, 4, False, "0.0000"),
    (-1e-4, 4, False, "-0.0001"),      # a value that rounds to something keeps its sign
    (-0.4, 0, False, "0"),
    (2.5e-5, 4, True, "+0.0000"),
])
def test_a_value_rounded_to_zero_has_no_sign(value: float, decimals: int, sign: bool,
                                             shown: str) -> None:
    """Rounded to zero, a negative value reads "0.0000", not "-0.0000" (an error with a
    direction); anything the rounding keeps keeps its sign."""
    assert plain(value, decimals, sign=sign) == shown


def test_rounded_zero_in_the_units_and_in_a_table_column() -> None:
    """mm and degrees go through the same rule, aligned in their column; numbers in
    exponent form keep their sign."""
    assert mm(-1e-12) == "0.0000 mm"
    assert deg(-1e-12, unit=False) == "0.0000"
    assert plain(-1e-14, 4, width=10) == "    0.0000"
    assert plain(-1e-20, significant=3) == "-1e-20"

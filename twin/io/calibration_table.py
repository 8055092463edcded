"""The ``[calibration]`` table of capture files and scenarios: the one reader and writer of
:class:`~twin.calibration.settings.CalibrationSettings` in TOML::

    [calibration]                     # every key optional
    errors = ["dh"]                   # the robot's error groups (twin.unknowns.ERRORS)
    estimate_port = false             # the rig's unknowns to identify too
    estimate_offset = false
    estimate_attachment = false
    estimate_base = false             # tracker frame
    loss = "linear"                   # or huber, soft_l1, cauchy (twin.loss)
    loss_scale_mm = 0.03              # the loss's scale (default 3 σ)
    train_fraction = 0.8
    stop = "converge"                 # or "paper" (twin.stopping)
    max_iterations = 200              # another iteration limit
    bounds = ["dh=20mm", "a2=50mm"]   # the search box (twin.unknowns.limits), in order
    priors = ["dh=1mm", "dh=0.5deg"]  # Gaussian priors around the nominal
    fix = ["theta6"]                  # held at the nominal, left out
    joint_resolution_deg = 0.1        # the joints' recording resolution (or one per joint)
    joint_sigma_deg = 0.0             # and their noise 1σ: errors in variables
    sigma = "auto"                    # estimate σ from the data (the only value)

The noise σ is not a key here: the file's instrument (a capture's ``[encoder]``, a scenario's
noise) states it, and the reader is given it — unless ``sigma = "auto"`` asks the data. The
joints' noise defaults to the one the file's robot states (a scenario's ``[joints]
resolution_deg``); written back folded into ``joint_sigma_deg``.
"""

from __future__ import annotations

import json
from typing import Any

from twin.calibration.settings import (
    MAX_JOINT_SIGMA_RAD,
    RIG_UNKNOWNS,
    CalibrationSettings,
    joint_noise,
)
from twin.errors import InputError
from twin.io.table import Table
from twin.units import deg_to_rad, m_to_mm, mm_to_m, rad_to_deg, significant
from twin.unknowns import ERRORS

KEYS = ("errors", *(f"estimate_{name}" for name in RIG_UNKNOWNS), "loss", "loss_scale_mm",
        "train_fraction", "stop", "max_iterations", "bounds", "priors", "fix",
        "joint_resolution_deg", "joint_sigma_deg", "sigma")
"""The keys of a ``[calibration]`` table."""
LIMITS = {"bounds": "a list of bounds such as \"dh=20mm\" or \"a2=-5:20mm\"",
          "priors": "a list of priors such as \"dh=1mm\"",
          "fix": "a list of unknowns, families or groups such as \"theta6\""}
"""The keys of what may move and how far, and what each holds."""
MAX_JOINT_DEG = float(rad_to_deg(MAX_JOINT_SIGMA_RAD))
"""The largest joint noise or resolution a table may state, degrees."""
AUTO = "auto"
"""The one value of ``sigma``: estimate σ from the data."""


def _angles_rad(table: Table, key: str) -> list[float]:
    """A number of degrees or a list of them (one per joint), each in [0, 10], in rad."""
    value: Any = table.values.get(key)
    values: list[Any] = value if isinstance(value, list) else [value]
    numbers = [float(v) for v in values if isinstance(v, int | float) and not isinstance(v, bool)]
    if not values or len(numbers) != len(values) or not all(0 <= v <= MAX_JOINT_DEG
                                                            for v in numbers):
        raise table.error(key, repr(value), f"degrees from 0 to {MAX_JOINT_DEG:g}, one for all "
                          "joints or a list of one per joint")
    return deg_to_rad(numbers).tolist()


def parse_calibration(table: Table, sigma_m: float, joint_sigma_rad: tuple[float, ...] = (),
                      sigma_rad: float | None = None) -> CalibrationSettings:
    """The settings of a ``[calibration]`` table (every key optional) and the file's noise.

    Args:
        table: The table (its allowed keys are the caller's: :data:`KEYS` and any of its own).
        sigma_m: The noise 1σ of one reading the file states, m.
        joint_sigma_rad: The noise 1σ of the recorded joint angles the file states, rad (one
            or one per joint); the table's ``joint_*`` keys replace it.
        sigma_rad: The noise 1σ of an angle it states, rad (6-D poses), or None.

    Raises:
        InputError: naming the file and key of the first wrong value.
    """
    values: dict[str, Any] = {"sigma_m": sigma_m, "joint_sigma_rad": joint_sigma_rad,
                              "sigma_rad": sigma_rad}
    if table.has("sigma"):
        if table.values["sigma"] != AUTO:
            raise table.error("sigma", repr(table.values["sigma"]), f'"{AUTO}" (σ itself is the '
                              "instrument's: a capture's [encoder] sigma_mm)")
        values["sigma_auto"] = True
    if table.has("joint_resolution_deg") or table.has("joint_sigma_deg"):
        values["joint_sigma_rad"] = joint_noise(
            *(_angles_rad(table, key) if table.has(key) else []
              for key in ("joint_sigma_deg", "joint_resolution_deg")))
    if table.has("errors"):
        values["errors"] = tuple(table.strings("errors", expected="a non-empty list of error "
                                               "groups among " + ", ".join(ERRORS)))
    values["estimate"] = tuple(name for name in RIG_UNKNOWNS
                               if table.boolean(f"estimate_{name}", False))
    for key in ("loss", "stop"):
        if table.has(key):
            values[key] = table.text(key)
    if table.has("loss_scale_mm"):
        values["loss_scale_m"] = float(mm_to_m(table.number(
            "loss_scale_mm", minimum=0.0, strict_minimum=True, expected="a scale in mm > 0")))
    if table.has("train_fraction"):
        values["train_fraction"] = table.number("train_fraction")
    if table.has("max_iterations"):
        values["max_iterations"] = table.integer("max_iterations")
    for key, expected in LIMITS.items():
        if table.has(key):
            values[key] = tuple(table.strings(key, expected=expected))
    try:
        return CalibrationSettings(**values)
    except InputError as exc:
        key = {"loss_scale_m": "loss_scale_mm", "estimate": "estimate_port",
               "joint_sigma_rad": "joint_sigma_deg"}.get(str(exc.where), str(exc.where))
        raise table.error(key, exc.found, exc.expected) from None


def calibration_lines(settings: CalibrationSettings) -> list[str]:
    """The ``[calibration]`` table of ``settings``, as TOML lines (the noise is the
    instrument's, written with it)."""
    lines = ["[calibration]", f"errors = {json.dumps(list(settings.errors))}"]
    lines += [f"estimate_{name} = {json.dumps(settings.estimates(name))}"
              for name in RIG_UNKNOWNS]
    lines += [f"loss = {json.dumps(settings.loss)}",
              f"train_fraction = {settings.train_fraction!r}",
              f"stop = {json.dumps(settings.stop)}"]
    if settings.loss_scale_m is not None:
        lines.append(f"loss_scale_mm = {float(m_to_mm(settings.loss_scale_m))!r}")
    if settings.max_iterations is not None:
        lines.append(f"max_iterations = {settings.max_iterations}")
    if settings.joint_sigma_rad:
        shown = [significant(value) for value in rad_to_deg(settings.joint_sigma_rad)]
        lines.append(f"joint_sigma_deg = {json.dumps(shown)}")
    if settings.sigma_auto:
        lines.append(f'sigma = "{AUTO}"')
    for key, rules in (("bounds", [rule.text for rule in settings.bounds]),
                       ("priors", [rule.text for rule in settings.priors]),
                       ("fix", list(settings.fix))):
        if rules:
            lines.append(f"{key} = {json.dumps(rules, ensure_ascii=False)}")
    return lines


__all__ = ["KEYS", "calibration_lines", "parse_calibration"]

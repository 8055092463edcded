"""twin — a digital-twin testbench for the kinematic calibration of serial robots.

A drawstring encoder measures the distance from a fixed port to the robot's flange; `twin`
identifies the robot's kinematic errors (and the rig's unknowns) from such lengths. All values
are SI (m, rad) inside; files and the command line use mm and degrees.

The public names below are imported when first used (module ``__getattr__``, PEP 562): ``import
twin.cli`` — what ``twin --version`` and ``twin CMD --help`` run — loads no numpy or scipy, and
``twin.calibrate`` loads what a calibration needs the first time it is read.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from twin.distribution import lazy_exports

if TYPE_CHECKING:
    from twin.analysis.metrics import Metrics
    from twin.calibration.crossval import CrossValidation, cross_validate
    from twin.calibration.pipeline import calibrate, calibrate_many
    from twin.calibration.predict import Prediction, predict
    from twin.calibration.result import CalibrationResult
    from twin.calibration.settings import CalibrationSettings
    from twin.dataset import Measurements
    from twin.errors import InputError, TwinError, UnknownChoiceError
    from twin.geometry.kinematics import (
        Structure,
        flange_transform,
        point_jacobian,
        point_position,
    )
    from twin.io.identified import IdentifiedModel, load_result
    from twin.io.measurements import load_measurements, write_measurements
    from twin.io.robot_file import default_robot, load_robot
    from twin.kinds.length import cable_length
    from twin.loss import Loss
    from twin.model import Model
    from twin.rig import Distance, Rig
    from twin.robot import RobotModel
    from twin.stopping import Budget, StopReason

__getattr__ = lazy_exports(__name__, {
    "twin.analysis.metrics": ("Metrics",),
    "twin.calibration.crossval": ("CrossValidation", "cross_validate"),
    "twin.calibration.pipeline": ("calibrate", "calibrate_many"),
    "twin.calibration.predict": ("Prediction", "predict"),
    "twin.calibration.result": ("CalibrationResult",),
    "twin.calibration.settings": ("CalibrationSettings",),
    "twin.dataset": ("Measurements",),
    "twin.errors": ("InputError", "TwinError", "UnknownChoiceError"),
    "twin.geometry.kinematics": ("Structure", "flange_transform", "point_jacobian",
                                 "point_position"),
    "twin.io.identified": ("IdentifiedModel", "load_result"),
    "twin.io.measurements": ("load_measurements", "write_measurements"),
    "twin.io.robot_file": ("default_robot", "load_robot"),
    "twin.kinds.length": ("cable_length",),
    "twin.loss": ("Loss",),
    "twin.model": ("Model",),
    "twin.rig": ("Distance", "Rig"),
    "twin.robot": ("RobotModel",),
    "twin.stopping": ("Budget", "StopReason"),
})

__all__ = [
    "Budget",
    "CalibrationResult",
    "CalibrationSettings",
    "CrossValidation",
    "Distance",
    "IdentifiedModel",
    "InputError",
    "Loss",
    "Measurements",
    "Metrics",
    "Model",
    "Prediction",
    "Rig",
    "RobotModel",
    "StopReason",
    "Structure",
    "TwinError",
    "UnknownChoiceError",
    "cable_length",
    "calibrate",
    "calibrate_many",
    "cross_validate",
    "default_robot",
    "flange_transform",
    "load_measurements",
    "load_result",
    "load_robot",
    "point_jacobian",
    "point_position",
    "predict",
    "write_measurements",
]

"""twin — a digital-twin testbench for the kinematic calibration of serial robots.

A drawstring encoder measures the distance from a fixed port to the robot's flange; `twin`
identifies the robot's Denavit–Hartenberg errors from such lengths. All values are SI (m, rad)
inside; files and the command line use mm and degrees.
"""

from twin.cable import CableModel, Measurements, cable_length
from twin.calibration import CalibrationResult, calibrate, calibrate_many
from twin.errors import InputError, TwinError, UnknownChoiceError
from twin.io.measurements import load_measurements, write_measurements
from twin.kinematics import flange_position, flange_position_jacobian, flange_transform
from twin.metrics import Metrics
from twin.robot import RobotModel, default_robot, load_robot
from twin.stopping import Budget, StopReason

__all__ = [
    "Budget",
    "CableModel",
    "CalibrationResult",
    "InputError",
    "Measurements",
    "Metrics",
    "RobotModel",
    "StopReason",
    "TwinError",
    "UnknownChoiceError",
    "cable_length",
    "calibrate",
    "calibrate_many",
    "default_robot",
    "flange_position",
    "flange_position_jacobian",
    "flange_transform",
    "load_measurements",
    "load_robot",
    "write_measurements",
]

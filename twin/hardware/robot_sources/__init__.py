"""Robot sources behind one interface
(:class:`~twin.hardware.robot_sources.base.RobotSource`): where the joint angles of each
captured pose come from.

- ``sim`` (:mod:`twin.hardware.robot_sources.sim`): the twin's robot, publishing its pose to
  the virtual encoder;
- ``manual`` (:mod:`twin.hardware.robot_sources.manual`): the operator jogs the robot and
  confirms;
- ``file`` (:mod:`twin.hardware.robot_sources.file`): joint angles logged by the robot
  controller.
"""

from twin.hardware.robot_sources.base import RobotSource

__all__ = ["RobotSource"]

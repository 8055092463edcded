"""Robot sources behind one interface (:class:`~twin.robots.base.RobotSource`): where the joint
angles of each captured pose come from.

- ``sim`` (:mod:`twin.robots.sim`): the twin's robot, publishing its pose to the virtual encoder;
- ``manual`` (:mod:`twin.robots.manual`): the operator jogs the robot and confirms;
- ``file`` (:mod:`twin.robots.file`): joint angles logged by the robot controller.
"""

from twin.robots.base import RobotSource

__all__ = ["RobotSource"]

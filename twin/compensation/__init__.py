"""Compensation: batched inverse kinematics (:mod:`.ik`), the joints that make the identified
robot go where the nominal one would (:mod:`.joints`), reachable Cartesian targets
(:mod:`.targets`) and how well a compensation does against a truth (:mod:`.check`).
"""

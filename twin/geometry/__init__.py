"""Geometry: forward kinematics and their Jacobians, the one rigid transform, the kinematic
parametrisations (D-H, MDH, Hayati, free origins) and joint torques under static load.

Pure numpy; every function is vectorised over poses and parameter sets.
"""

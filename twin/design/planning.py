"""Planning a cable capture: D-optimal poses among candidates the rig can measure, the port (or
the stations) they are measured from, and how the plan compares with as many random poses.

Candidates come from a sampler the caller passes in: the MuJoCo twin's feasibility sampler
(:func:`twin.sim.poses.feasible_sampler`: flange above the floor, no collision, cable in range
and clear of the links, per port), or the joint limits alone (the default); the design itself
(:mod:`twin.design.optimal`) is pure numpy. Every random draw (candidates, workspace poses, the
random plan) comes from one generator seeded by ``seed``.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray

from twin.analysis.workspace import WORKSPACE_POSES
from twin.arrays import Array
from twin.design.optimal import DesignScore, PortChoice, choose_port, plan_stations, score_poses
from twin.model import Model
from twin.rig import Rig
from twin.robot import RobotModel, random_poses

Sampler = Callable[[Array, int], Array]
"""``draw(port_m, count)``: ``count`` candidate poses for the port (3,) m, shape (count, n),
rad."""
SamplerFactory = Callable[[RobotModel, np.random.Generator], Sampler]
"""Makes a :data:`Sampler` for a robot, drawing from the plan's generator."""


class Draws(NamedTuple):
    """The random part of a plan, drawn in this order from one generator."""

    draw: Sampler
    """Draws candidate (and random) poses for a port."""
    q_workspace_rad: Array
    """Poses the flange error is predicted over, shape (WORKSPACE_POSES, n), rad."""
    candidates_rad: Array
    """Candidates per port, shape (K, M, n), rad."""


class PortPlan(NamedTuple):
    """A plan for the best of candidate ports (:func:`plan_for_ports`)."""

    choice: PortChoice
    """Every port's plan and predicted flange error; the chosen one."""
    port_m: Array
    """The chosen port, shape (3,), m."""
    planned: DesignScore
    """The plan's score."""
    random: DesignScore
    """The score of as many random poses, drawn with the same constraints."""

    @property
    def q_rad(self) -> Array:
        """The planned poses, shape (N, n), rad."""
        return self.choice.plans[self.choice.best].q_rad


class StationsPlan(NamedTuple):
    """A plan of poses and stations together (:func:`plan_for_stations`)."""

    q_rad: Array
    """The planned poses, shape (N, n), rad."""
    port: NDArray[np.intp]
    """The station of each pose, shape (N,), an index into the rig's ports."""
    base_parameters: int
    """Base parameters the plan was optimised for."""
    exchanges: int
    """Exchange steps the design took."""
    planned: DesignScore
    """The plan's score."""
    random: DesignScore
    """The score of as many random poses shared evenly between the stations."""


def joint_limit_sampler(robot: RobotModel, rng: np.random.Generator) -> Sampler:
    """Candidate poses anywhere within the joint limits, whatever the port."""
    return lambda port_m, count: random_poses(robot, count, rng)


def _draws(robot: RobotModel, ports_m: Array, n_candidates: int, seed: int,
           sampler: SamplerFactory) -> Draws:
    rng = np.random.default_rng(seed)
    draw = sampler(robot, rng)
    q_workspace = random_poses(robot, WORKSPACE_POSES, rng)
    return Draws(draw, q_workspace, np.stack([draw(port, n_candidates) for port in ports_m]))


def plan_for_ports(model_at: Callable[[Array], Model], ports_m: Array, n_poses: int,
                   n_candidates: int, sigma_m: float, *, seed: int,
                   sampler: SamplerFactory = joint_limit_sampler) -> PortPlan:
    """The D-optimal plan for each candidate port; the port whose plan predicts the smallest
    flange error over the workspace, and its plan scored against random poses.

    Args:
        model_at: The model the calibration will fit, with the encoder at a port (3,) m.
        ports_m: Candidate ports, base frame, shape (K, 3), m.
        n_poses: Poses to plan.
        n_candidates: Candidate poses drawn per port.
        sigma_m: Length noise 1σ of the predicted accuracy, m.
        seed: Seed of every draw.
        sampler: Makes the candidate sampler from the robot and the plan's generator: within
            the joint limits by default; :func:`twin.sim.poses.feasible_sampler` draws those
            the rig can measure (the twin's constraints).
    """
    robot = model_at(ports_m[0]).robot
    draws = _draws(robot, ports_m, n_candidates, seed, sampler)
    choice = choose_port(model_at(ports_m[0]), ports_m, draws.candidates_rad, n_poses, sigma_m,
                         draws.q_workspace_rad)
    port_m = ports_m[choice.best]
    plan = choice.plans[choice.best]
    q_random = draws.draw(port_m, n_poses)
    at_port = model_at(port_m)
    x0 = np.zeros(at_port.n_params)
    return PortPlan(
        choice, port_m,
        score_poses(at_port, x0, plan.q_rad, plan.base_mask, sigma_m, draws.q_workspace_rad),
        score_poses(at_port, x0, q_random, plan.base_mask, sigma_m, draws.q_workspace_rad))


def plan_for_stations(model: Model, rig: Rig, n_poses: int, n_candidates: int,
                      sigma_m: float, *, seed: int,
                      sampler: SamplerFactory = joint_limit_sampler) -> StationsPlan:
    """Poses and stations planned together for an encoder moved between named ports, scored
    against random poses shared evenly between the stations.

    Args:
        model: The model the calibration will fit, its rig holding every station.
        rig: That rig.
        n_poses: Poses to plan.
        n_candidates: Candidate poses drawn per station.
        sigma_m: Length noise 1σ of the predicted accuracy, m.
        seed: Seed of every draw.
        sampler: As in :func:`plan_for_ports`.
    """
    draws = _draws(model.robot, rig.ports_m, n_candidates, seed, sampler)
    x0 = np.zeros(model.n_params)
    plan = plan_stations(model, x0, draws.candidates_rad, n_poses)
    share, extra = divmod(n_poses, len(rig.ports_m))
    counts = [share + (k < extra) for k in range(len(rig.ports_m))]
    q_random = np.concatenate([draws.draw(port, count) for port, count
                               in zip(rig.ports_m, counts, strict=True)])
    port_random = np.repeat(np.arange(len(rig.ports_m)), counts)
    return StationsPlan(
        plan.q_rad, plan.port, int(plan.base_mask.sum()), plan.selection.exchanges,
        score_poses(model, x0, plan.q_rad, plan.base_mask, sigma_m, draws.q_workspace_rad,
                    plan.port),
        score_poses(model, x0, q_random, plan.base_mask, sigma_m, draws.q_workspace_rad,
                    port_random))

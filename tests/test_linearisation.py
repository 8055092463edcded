"""The linearisation the checks after a fit share: one Jacobian and its R factor per point,
recognised by the poses' content, and checks that read R agree with the same checks on J."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from twin.analysis.identifiability import identifiability
from twin.analysis.linearisation import chain_jacobian, fingerprint, linearise, model_jacobian
from twin.analysis.uncertainty import parameter_covariance, seen_covariance
from twin.calibration.setup import make_model
from twin.kinds.length import length_measurements
from twin.rig import Rig
from twin.robot import RobotModel, random_poses


@pytest.fixture(scope="module")
def setup(irb120: RobotModel, port_m: np.ndarray):
    """A cable model, unknowns off the nominal and 40 measured poses."""
    rng = np.random.default_rng(3)
    model = make_model(irb120, Rig.cable(port_m))
    x = rng.uniform(-1, 1, model.n_params) * model.radius
    data = model.measure(x, random_poses(irb120, 40, rng))
    return model, x, data


def test_linearisation_is_the_models_jacobian_and_its_r_factor(setup) -> None:
    """The residuals and Jacobian are the model's; RᵀR = JᵀJ to round-off."""
    model, x, data = setup
    kept = linearise(model, x, data)
    r, jacobian = model.identifiable_jacobian(x, data)
    np.testing.assert_array_equal(kept.residuals, r)
    np.testing.assert_array_equal(kept.jacobian, jacobian)
    gram = jacobian.T @ jacobian
    np.testing.assert_allclose(kept.triangle.T @ kept.triangle, gram,
                               rtol=0, atol=1e-12 * np.max(np.abs(gram)))
    assert not kept.jacobian.flags.writeable and not kept.triangle.flags.writeable


def test_rows_weighted_before_factorising(setup) -> None:
    """With row weights the rows are scaled and R is that of the scaled Jacobian."""
    model, x, data = setup
    weight = np.linspace(0.5, 1.5, len(data))
    kept = linearise(model, x, data, weight)
    plain = linearise(model, x, data)
    np.testing.assert_allclose(kept.jacobian, plain.jacobian * weight[:, None], rtol=1e-15)
    gram = kept.jacobian.T @ kept.jacobian
    np.testing.assert_allclose(kept.triangle.T @ kept.triangle, gram,
                               rtol=0, atol=1e-12 * np.max(np.abs(gram)))


def test_kept_by_content_not_by_identity(setup) -> None:
    """The same poses made apart share the linearisation; other poses, another x or another
    reading do not."""
    model, x, data = setup
    first = linearise(model, x, data)
    again = data.subset(np.arange(len(data)))
    assert again is not data and linearise(model, x, again) is first
    assert linearise(model, x + 1e-9, data) is not first
    fewer = data.subset(np.arange(len(data) - 1))
    assert fingerprint(fewer) != fingerprint(data)
    assert linearise(model, x, fewer).jacobian.shape[0] == len(data) - 1
    read = replace(data, values={"length_m": data.value("length_m") + 1e-6})
    assert fingerprint(read) != fingerprint(data)
    np.testing.assert_allclose(linearise(model, x, read).residuals, first.residuals - 1e-6,
                               rtol=0, atol=1e-15)


def test_chain_jacobian_is_the_models(setup, irb120: RobotModel) -> None:
    """The flange's and the measured point's Jacobians, each kept apart."""
    model, x, _ = setup
    poses = model.poses(random_poses(irb120, 30, np.random.default_rng(4)))
    np.testing.assert_array_equal(chain_jacobian(model, x, poses, measured=False),
                                  model.flange_jacobian(x, poses))
    np.testing.assert_array_equal(chain_jacobian(model, x, poses, measured=True),
                                  model.position_jacobian(x, poses))


def test_model_jacobian_is_the_models_and_shared_without_gauge_directions(setup) -> None:
    """The model's own rows and Jacobian, read-only and kept; for a kind without known gauge
    directions (a cable) they are the linearisation's, the same arrays."""
    model, x, data = setup
    r, jacobian = model_jacobian(model, x, data)
    expected = model.jacobian(x, data)
    np.testing.assert_array_equal(r, expected[0])
    np.testing.assert_array_equal(jacobian, expected[1])
    assert not jacobian.flags.writeable
    assert model_jacobian(model, x, data.subset(np.arange(len(data))))[1] is jacobian
    assert linearise(model, x + 1e-12, data).jacobian \
        is model_jacobian(model, x + 1e-12, data)[1]


def test_checks_on_r_agree_with_the_checks_on_j(setup) -> None:
    """Identifiability (rank, base, null space, singular values) and the held covariance are
    the same computed from J or from its R factor, at the nominal (rank 19 of 24)."""
    model, _, data = setup
    kept = linearise(model, np.zeros(model.n_params), data)
    on_j = identifiability(kept.jacobian, model.names)
    on_r = identifiability(kept.jacobian, model.names, triangle=kept.triangle)
    assert on_r.rank == on_j.rank == 19
    np.testing.assert_array_equal(on_r.base, on_j.base)
    assert on_r.unidentifiable == on_j.unidentifiable
    np.testing.assert_allclose(on_r.singular_values[: on_r.rank],
                               on_j.singular_values[: on_j.rank], rtol=1e-10)
    np.testing.assert_allclose(on_r.null_space, on_j.null_space, rtol=0, atol=1e-10)
    seen = np.linalg.svd(on_j.null_space.T)[2][on_j.null_space.shape[1]:].T  # (p, 19)
    np.testing.assert_allclose(seen_covariance(kept.triangle, seen, 1e-5),
                               seen_covariance(kept.jacobian, seen, 1e-5), rtol=1e-8,
                               atol=1e-12 * np.max(parameter_covariance(kept.jacobian @ seen,
                                                                        1e-5)))


def test_measurements_fingerprint_covers_the_columns(irb120: RobotModel) -> None:
    """Ports and approach labels are part of what is recognised."""
    q = random_poses(irb120, 5, np.random.default_rng(0))
    one = length_measurements(q, np.ones(5), port=np.zeros(5, dtype=np.intp))
    other = length_measurements(q, np.ones(5), port=np.array([0, 1, 0, 1, 0]))
    approach = length_measurements(q, np.ones(5), approach=np.ones(q.shape, dtype=np.int8))
    assert len({fingerprint(one), fingerprint(other), fingerprint(approach),
                fingerprint(length_measurements(q, np.ones(5)))}) == 4

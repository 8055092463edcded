"""The compiled kernel (:mod:`twin.geometry.compiled`, extra ``fast``) against the numpy path
it replaces, which stays the reference: positions and Jacobians of every parametrisation, with
base and tool transforms, for the batch shapes the model uses, equal to round-off. (The numpy
path's own Jacobians are held to finite differences in tests/test_kinematics.py and
tests/test_model.py, which run on whichever kernel is installed.)"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from twin.arrays import lengths, read_only
from twin.choices import MAX_JOINTS
from twin.geometry import kinematics
from twin.geometry.kinematics import (
    JOINT_TYPES,
    KERNEL_VARIABLE,
    PARAMETRISATIONS,
    Structure,
    Turns,
    point_distances,
    point_position,
    point_sum_squares,
    trace_point,
    turns,
)

pytest.importorskip("numba")

RTOL = 1e-12
"""Both kernels run the same operations in another order: round-off apart."""


def _rigid(rng: np.random.Generator) -> np.ndarray:
    transform = np.eye(4)
    transform[:3, :3] = Rotation.random(random_state=rng).as_matrix()
    transform[:3, 3] = rng.normal(scale=0.1, size=3)
    return transform


def _mixed(rng: np.random.Generator) -> Structure:
    """A chain of 4 to MAX_JOINTS joints of random parametrisations and types, with a base and
    a tool transform."""
    n = int(rng.integers(4, MAX_JOINTS + 1))
    return Structure(tuple(rng.choice(PARAMETRISATIONS, n)), base=_rigid(rng), tool=_rigid(rng),
                     joint_types=tuple(rng.choice(JOINT_TYPES, n)))


def _both(monkeypatch: pytest.MonkeyPatch, compute):  # type: ignore[no-untyped-def]
    """compute() on the compiled kernel, then on the numpy path."""
    monkeypatch.setenv(KERNEL_VARIABLE, "numba")
    kinematics._compiled.cache_clear()
    assert kinematics._compiled() is not None
    fast = compute()
    monkeypatch.setenv(KERNEL_VARIABLE, "numpy")
    kinematics._compiled.cache_clear()
    assert kinematics._compiled() is None
    reference = compute()
    monkeypatch.delenv(KERNEL_VARIABLE)
    kinematics._compiled.cache_clear()
    return fast, reference


def test_a_single_command_takes_the_numpy_path(monkeypatch: pytest.MonkeyPatch) -> None:
    """Under TWIN_KERNEL=auto numba is not even imported until a process declares bulk work
    (a study's worker): one calibration would pay more for the import than it saves."""
    monkeypatch.delenv(KERNEL_VARIABLE, raising=False)
    kinematics._compiled.cache_clear()
    assert kinematics._compiled() is None
    monkeypatch.setattr(kinematics, "_BULK", [True])
    kinematics._compiled.cache_clear()
    assert kinematics._compiled() is not None
    kinematics._compiled.cache_clear()


NO_NUMBA = "import sys; sys.modules['numba'] = None  # as without the extra fast\n"
"""Code that makes numba fail to import in the process it starts."""


def _calibrate(tmp_path: Path, kernel: str, prelude: str = "") -> subprocess.CompletedProcess[str]:
    """The README's `twin calibrate` in a fresh interpreter under ``TWIN_KERNEL=kernel``, after
    ``prelude``."""
    example = Path(__file__).resolve().parents[1] / "examples" / "irb120_lm"
    argv = ["calibrate", str(example / "measurements.csv"), "--port", "600,-400,100", "--json",
            str(tmp_path / "result.json")]
    code = f"{prelude}from twin.cli import main\nraise SystemExit(main({argv!r}))"
    return subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          env={**os.environ, KERNEL_VARIABLE: kernel}, check=False)


@pytest.mark.slow
@pytest.mark.parametrize(("kernel", "prelude", "found"), [
    ("Numba", "", "found unknown kernel 'Numba', expected one of auto, numba, numpy"),
    ("numba", NO_NUMBA, "found no module 'numba', expected the optional extra that installs "
                        "it: pip install 'cabletwin[fast]'"),
])
def test_a_kernel_that_cannot_be_taken_is_one_line(tmp_path: Path, kernel: str, prelude: str,
                                                   found: str) -> None:
    """A TWIN_KERNEL that names no kernel, or numba without the extra fast, is refused in one
    line with exit code 2 (both had run the numpy path unsaid), and nothing is written."""
    done = _calibrate(tmp_path, kernel, prelude)
    assert (done.returncode, done.stderr) == (2, f"twin: error: TWIN_KERNEL: {found}\n")
    assert not (tmp_path / "result.json").exists()


@pytest.mark.slow
def test_auto_without_numba_takes_the_numpy_path(tmp_path: Path) -> None:
    """Under TWIN_KERNEL=auto (the default) a process without numba takes the numpy path,
    bulk work or not: the extra fast is optional."""
    code = NO_NUMBA + ("from twin.geometry import kinematics\n"
                       "kinematics.for_bulk_work()\n"
                       "print(kinematics.takes_compiled())")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          env={**os.environ, KERNEL_VARIABLE: "auto"}, check=True)
    assert done.stdout.split() == ["False"]
    assert _calibrate(tmp_path, "auto", NO_NUMBA).returncode == 0


def _close(fast: np.ndarray, reference: np.ndarray) -> None:
    assert fast.shape == reference.shape
    np.testing.assert_allclose(fast, reference, rtol=0, atol=RTOL * np.max(np.abs(reference)))


@pytest.mark.parametrize("seed", range(8))
def test_positions_and_jacobians_equal_the_numpy_path(seed: int,
                                                      monkeypatch: pytest.MonkeyPatch) -> None:
    """Mixed parametrisations and joint types (revolute, prismatic), base and tool, one table
    and a batch of tables, a point per table, joints shifted per table, directions per pose or
    the base axes."""
    rng = np.random.default_rng(seed)
    structure = _mixed(rng)
    n = structure.n_joints
    m, k = 40, 5
    q = rng.uniform(-3, 3, (m, n))
    table = rng.normal(scale=0.3, size=(4, n))
    tables = table + rng.normal(scale=0.01, size=(k, 4, n))
    shifted = turns(q).shifted(rng.normal(scale=0.01, size=(k, m, n)))
    point = rng.normal(scale=0.05, size=3)
    points = rng.normal(scale=0.05, size=(k, 3))
    directions = rng.normal(size=(m, 2, 3))
    cases = [
        (table, q, None, None),
        (table, turns(q), point, directions),
        (tables, q, point, None),
        (tables, shifted, points, directions),
    ]
    for dh, angles, at, along in cases:
        fast, reference = _both(monkeypatch, lambda dh=dh, angles=angles, at=at, along=along: (
            point_position(structure, dh, angles, at),
            trace_point(structure, dh, angles, at).jacobian(along)))
        _close(fast[0], reference[0])
        for got, expected in zip(fast[1], reference[1], strict=True):
            _close(got, expected)


@pytest.mark.parametrize("seed", range(4))
def test_whole_dh_joints_carry_the_point_as_their_motions_do(seed: int) -> None:
    """The positions carry a revolute standard D-H joint in one pass over the poses, the
    Jacobian's way in motion by motion: the same operations in the same order, equal bits, in
    chains of D-H joints alone and mixed with others."""
    from twin.geometry import compiled

    rng = np.random.default_rng(seed)
    n = int(rng.integers(4, MAX_JOINTS + 1))
    kinds = ("dh",) * n if seed == 0 else tuple(rng.choice(PARAMETRISATIONS, n))
    types = ("revolute",) * n if seed < 2 else tuple(rng.choice(JOINT_TYPES, n))
    structure = Structure(kinds, base=_rigid(rng), tool=_rigid(rng), joint_types=types)
    q = rng.uniform(-3, 3, (30, n))
    tables = rng.normal(scale=0.3, size=(6, 4, n))
    inputs = kinematics._compiled_inputs(structure, tables, turns(q), rng.normal(size=3))
    assert inputs is not None
    plan = kinematics._plan_rows(structure.parametrisation, structure.joint_types)
    assert plan[:, 6].sum() == sum(kind == "dh" and joint_type == "revolute"
                                   for kind, joint_type in zip(kinds, types, strict=True))
    whole = compiled.positions(inputs.table, plan, inputs.cos, inputs.sin, inputs.slides,
                               inputs.start, inputs.base)
    by_motion = compiled.jacobian(inputs.table, plan, inputs.cos, inputs.sin, inputs.slides,
                                  inputs.start, inputs.base, inputs.tool,
                                  read_only(np.eye(3)[None, None]), structure.n_columns)[0]
    np.testing.assert_array_equal(whole, by_motion)


def test_the_kernels_get_read_only_arrays_whatever_the_callers(
        monkeypatch: pytest.MonkeyPatch) -> None:
    """Numba compiles a version of a kernel per writeable flag of each input (2–5 s each on a
    fresh install, in every process that meets it first): a model's tables are read-only, a
    swarm's candidates are not; a data set's cached angles are, fresh poses' are not. Every
    array the kinematics hands the kernels is read-only whichever the caller's were — one
    version each — and the caller's arrays stay writeable."""
    from twin.geometry import compiled

    monkeypatch.setenv(KERNEL_VARIABLE, "numba")
    kinematics._compiled.cache_clear()
    handed: list[tuple[object, ...]] = []

    def recorded(kernel):  # type: ignore[no-untyped-def]
        return lambda *args: handed.append(args) or kernel(*args)

    for name in ("positions", "jacobian", "distances", "anchored_distances",
                 "anchored_sum_squares"):
        monkeypatch.setattr(compiled, name, recorded(getattr(compiled, name)))
    rng = np.random.default_rng(7)
    structure = Structure(("dh", "dh", "mdh", "hayati", "dh", "dh"),
                          joint_types=("revolute", "prismatic") + ("revolute",) * 4)
    q = rng.uniform(-1.0, 1.0, (7, 6))
    table = rng.normal(scale=0.1, size=(4, 6))
    frozen_table = read_only(table.copy())
    for dh in (table, frozen_table, np.stack([table, table])):
        for angles in (q, turns(q), Turns(*map(read_only, turns(q)))):
            point_position(structure, dh, angles)
            trace_point(structure, dh, angles, np.ones(3)).jacobian(rng.normal(size=(7, 2, 3)))
    kinematics.distances(rng.normal(size=(3, 7, 3)), rng.normal(size=(7, 3)))
    point_distances(structure, np.stack([table, table]), q, None, rng.normal(size=(7, 3)))
    point_sum_squares(structure, np.stack([table, table]), q, None, rng.normal(size=(7, 3)),
                      rng.normal(size=7))
    arrays = [a for args in handed for a in args if isinstance(a, np.ndarray)]
    assert len(handed) == 3 * 3 * 3 + 3 and not any(a.flags.writeable for a in arrays)
    assert table.flags.writeable and q.flags.writeable
    kinematics._compiled.cache_clear()


def test_shapes_beyond_the_kernel_take_the_numpy_path() -> None:
    """A batch of poses against one table broadcasts in numpy: the kernel is not asked."""
    structure = Structure.standard(6)
    q = np.zeros((3, 7, 6))
    assert kinematics._compiled_inputs(structure, np.zeros((4, 6)), turns(q), None) is None
    assert point_position(structure, np.zeros((4, 6)), q).shape == (3, 7, 3)


@pytest.mark.parametrize("anchored", ["per row", "per table and row"])
def test_distances_equal_the_written_out_lengths(anchored: str,
                                                 monkeypatch: pytest.MonkeyPatch) -> None:
    """A length kind's distances from the compiled pass equal twin.arrays.lengths of the
    differences bit for bit, on a batch of tables and on one; the numpy path is that."""
    rng = np.random.default_rng(5)
    points = rng.normal(scale=0.8, size=(7, 30, 3))
    anchors = rng.normal(scale=0.8, size=(30, 3) if anchored == "per row" else (7, 30, 3))
    for batch, anchor in ((points, anchors), (points[2], anchors if anchors.ndim == 2
                                              else anchors[2])):
        fast, reference = _both(monkeypatch, lambda batch=batch, anchor=anchor:
                                kinematics.distances(batch, anchor))
        np.testing.assert_array_equal(fast, lengths(batch - anchor))
        np.testing.assert_array_equal(reference, lengths(batch - anchor))
        assert fast.shape == batch.shape[:-1]


@pytest.mark.parametrize("anchored", ["per row", "per table and row"])
@pytest.mark.parametrize("seed", range(3))
def test_point_distances_are_the_distances_of_the_points(
        anchored: str, seed: int, monkeypatch: pytest.MonkeyPatch) -> None:
    """A swarm's cable lengths in one pass of the chain, the points never stored, are the
    distances of the points bit for bit, on either path: mixed parametrisations and joint
    types, base and tool, a point per table, a batch of tables and one."""
    rng = np.random.default_rng(seed)
    structure = _mixed(rng)
    n = structure.n_joints
    m, k = 30, 6
    q = rng.uniform(-3, 3, (m, n))
    tables = rng.normal(scale=0.3, size=(k, 4, n))
    points = rng.normal(scale=0.05, size=(k, 3))
    anchors = rng.normal(scale=0.8, size=(m, 3) if anchored == "per row" else (k, m, 3))
    one = anchors if anchors.ndim == 2 else anchors[2]
    for dh, at, anchor in ((tables, points, anchors), (tables[2], points[2], one)):
        fast, reference = _both(monkeypatch, lambda dh=dh, at=at, anchor=anchor: (
            point_distances(structure, dh, q, at, anchor),
            kinematics.distances(point_position(structure, dh, q, at), anchor)))
        for together, apart in (fast, reference):
            assert together.shape == (*dh.shape[:-2], m)
            np.testing.assert_array_equal(together, apart)


@pytest.mark.parametrize("anchored", ["per row", "per table and row"])
@pytest.mark.parametrize("m", [30, 96])
def test_sums_of_squares_are_those_of_the_distances(
        anchored: str, m: int, monkeypatch: pytest.MonkeyPatch) -> None:
    """A swarm's least-squares cost summed in the distances' pass is the sum of the squared
    distances less the readings: that sum itself on the numpy path, to round-off on the
    compiled one (its sum runs in lanes: 30 rows leave a remainder, 96 none), on a batch of
    tables and on one."""
    rng = np.random.default_rng(m)
    structure = _mixed(rng)
    n, k = structure.n_joints, 6
    q = rng.uniform(-3, 3, (m, n))
    tables = rng.normal(scale=0.3, size=(k, 4, n))
    points = rng.normal(scale=0.05, size=(k, 3))
    anchors = rng.normal(scale=0.8, size=(m, 3) if anchored == "per row" else (k, m, 3))
    readings = rng.uniform(0.5, 1.5, m)
    one = anchors if anchors.ndim == 2 else anchors[2]
    for dh, at, anchor in ((tables, points, anchors), (tables[2], points[2], one)):
        fast, reference = _both(monkeypatch, lambda dh=dh, at=at, anchor=anchor: (
            point_sum_squares(structure, dh, q, at, anchor, readings),
            np.sum((point_distances(structure, dh, q, at, anchor) - readings) ** 2, axis=-1)))
        np.testing.assert_array_equal(*reference)
        np.testing.assert_allclose(*fast, rtol=RTOL, atol=0)
        np.testing.assert_allclose(fast[0], reference[0], rtol=RTOL, atol=0)
        assert fast[0].shape == reference[0].shape == dh.shape[:-2]


def test_distances_of_no_rows(monkeypatch: pytest.MonkeyPatch) -> None:
    """No rows (a calibration that trains on every pose has no validation poses) give no
    distances on either path."""
    for shape in ((0, 3), (7, 0, 3)):
        fast, reference = _both(monkeypatch, lambda shape=shape: kinematics.distances(
            np.zeros(shape), np.zeros((0, 3))))
        assert fast.shape == reference.shape == shape[:-1]

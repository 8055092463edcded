"""Identified models read back from a calibration result (`twin calibrate --json`).

:func:`load_result` rebuilds the whole identified measurement model from the result's
``unknowns`` (kind, groups, rig, every unknown's value); :func:`load_result_delta` reads the
D-H errors alone.

A result is applied (exported, compensated) only where it can be right:

- to the robot it was identified for: a result carries that robot whole (``robot.files``,
  :func:`twin.io.robot_file.robot_from_files`), so it needs no ``--robot``; a robot given anyway
  must have the same digest (:func:`twin.io.robot_file.robot_digest`). A result written before
  twin kept the robot needs it given, and its ``robot`` (name and nominal D-H table) must be
  it, the table within :data:`ROBOT_TOLERANCE_MM` and :data:`ROBOT_TOLERANCE_DEG` (a model
  file stores 1 µm and 1e-6 degree);
- within the search box the calibration kept to — the one the result records (each unknown's
  ``lower`` and ``upper``, the user's ``--bounds``), else the paper's (±5 mm, ±8°,
  :data:`twin.unknowns.dh.BOUND_M` and :data:`twin.unknowns.dh.BOUND_RAD`) — give or take
  :data:`BOUND_TOLERANCE_MM` and :data:`BOUND_TOLERANCE_DEG` for the rounding of the file.

The model is rebuilt with the calibration's fixed parameters, box and priors (``unknowns``).
"""

from __future__ import annotations

import math
import warnings
from dataclasses import replace
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np
from numpy.typing import NDArray

from twin.choices import MAX_TENSION_N
from twin.errors import InputError, UnknownChoiceError
from twin.io.capture_file import parse_port_mm
from twin.io.paths import read_json
from twin.io.robot_file import default_robot, robot_digest, robot_from_files
from twin.io.truth import parse_dh_rows
from twin.kinds import KINDS, Kind
from twin.model import Model
from twin.report.display import in_unit, mm, plain
from twin.rig import Distance, Part, Rig
from twin.robot import RobotModel
from twin.units import (
    DH_IS_LENGTH,
    DH_KEYS,
    THERMAL_UNIT,
    deg_to_rad,
    display_unit,
    from_display,
    m_to_mm,
    mm_to_m,
    rad_to_deg,
    to_display,
)
from twin.unknowns import Group, make_groups
from twin.unknowns.dh import BOUND_M as DH_BOUND_M
from twin.unknowns.dh import BOUND_RAD as DH_BOUND_RAD
from twin.unknowns.thermal import grown

RESULT_FILE = "a calibration result JSON file (twin calibrate --json)"
ROBOT_TOLERANCE_MM = 1e-3
"""Largest difference of a length of the nominal D-H tables that still names the same robot."""
ROBOT_TOLERANCE_DEG = 1e-5
"""Largest difference of an angle of the nominal D-H tables that still names the same robot."""
BOUND_TOLERANCE_MM = 1e-3
"""How far beyond ±5 mm an identified length error may lie (rounding), mm."""
BOUND_TOLERANCE_DEG = 1e-3
"""How far beyond ±8° an identified angle error may lie (rounding), degrees."""
MASS_TOLERANCE_KG = 1e-3
"""Largest difference of a link mass that still names the same robot (a file keeps 1 g)."""
BOUND_SLACK = 1e-6
"""How far beyond its search bound an unknown of :func:`load_result` may lie (rounding), as a
fraction of its range."""


class ResultWarning(UserWarning):
    """A result that is applied, but could not be checked in full."""


def _pick(document: Any, path: Path, method: str | None) -> tuple[dict[str, Any], str]:
    """The one result of a file, and where it sits in the file."""
    if not isinstance(document, dict):
        raise InputError(f"a JSON {type(document).__name__}", "a JSON object", source=path)
    if "methods" in document:
        methods = document["methods"]
        if not isinstance(methods, dict) or not all(isinstance(r, dict)
                                                    for r in methods.values()):
            raise InputError("a 'methods' that is not an object of results",
                             '{"methods": {"lm": {result}, …}}', source=path, where="methods")
        if method is None:
            raise InputError(
                "results of several methods (" + ", ".join(methods) + ")",
                "--method NAME to pick one", source=path,
            )
        if method not in methods:
            raise UnknownChoiceError("method", method, methods, source=str(path))
        return methods[method], f"methods.{method}."
    if method is not None and document.get("method") != method:
        raise UnknownChoiceError("method", method, [str(document.get("method"))],
                                 source=str(path))
    return document, ""


def check_result_robot(entry: dict[str, Any], robot: RobotModel, path: Path,
                       where: str) -> None:
    """Refuse a result identified for another robot than ``robot``.

    Raises:
        InputError: if the result's robot has another name or nominal table.
    """
    if "robot" not in entry:
        warnings.warn(f"{path}: the result does not say which robot it was identified for (a "
                      f"file written before twin recorded it); applied to {robot.name} "
                      "unchecked", ResultWarning, stacklevel=2)
        return
    recorded = entry["robot"]
    if not isinstance(recorded, dict) or not isinstance(recorded.get("name"), str):
        raise InputError("a 'robot' without a name", '"robot": {"name": …, "dh": {…}}',
                         source=path, where=f"{where}robot")
    if recorded["name"] != robot.name:
        raise InputError(f"a result identified for {recorded['name']!r}",
                         f"a result for {robot.name!r}, the robot it is applied to (--robot)",
                         source=path, where=f"{where}robot.name")
    # A result written before parametrisations were recorded is of a standard D-H arm.
    kinds = recorded.get("parametrisation", ["dh"] * robot.n_joints)
    if kinds != list(robot.structure.parametrisation):
        raise InputError(f"a result identified for the parametrisation {kinds!r}",
                         f"the robot's, {list(robot.structure.parametrisation)!r} (load it with "
                         "the same parametrisation)", source=path,
                         where=f"{where}robot.parametrisation")
    nominal = parse_dh_rows(recorded.get("dh"), robot.n_joints, path, f"{where}robot.dh", "dh",
                            robot.is_length)
    tolerance = np.where(robot.is_length, mm_to_m(ROBOT_TOLERANCE_MM),
                         deg_to_rad(ROBOT_TOLERANCE_DEG))
    apart = np.abs(nominal - robot.dh) > tolerance
    if np.any(apart):
        row, joint = np.argwhere(apart)[0]
        key = DH_KEYS[row]
        raise InputError(
            f"a result identified for another nominal table of {robot.name} ({key}{joint + 1} "
            f"differs)", f"the nominal table of the robot it is applied to, within "
            f"{ROBOT_TOLERANCE_MM:g} mm and {ROBOT_TOLERANCE_DEG:g} deg",
            source=path, where=f"{where}robot.dh.{key}")


def result_robot(entry: dict[str, Any], given: RobotModel | None, path: Path, where: str
                 ) -> tuple[RobotModel, bool]:
    """The nominal robot of a result: the one it carries, or for a result written before twin
    kept it, ``given`` (the packaged IRB 120 without one).

    A robot given beside a result that carries one must be the same robot: the same digest,
    or the same name, parametrisation, nominal table (to the file's rounding), limits, ends
    and URDF (:func:`check_same_robot`).

    Returns:
        The robot, and whether the result is such an older one (then :func:`check_result_robot`
        is the caller's, once the result's other fields are read).

    Raises:
        InputError: for a robot given that is not the result's, naming the first difference.
    """
    recorded = entry.get("robot")
    files = recorded.get("files") if isinstance(recorded, dict) else None
    if not isinstance(files, dict):
        return (default_robot() if given is None else given), True
    assert isinstance(recorded, dict)
    robot = robot_from_files(files, f"{path}: {where}robot.files")
    if given is not None and robot_digest(given) != robot_digest(robot):
        check_result_robot(entry, given, path, where)
        check_same_robot(robot, given, path, where)
    return robot, False


def check_same_robot(recorded: RobotModel, given: RobotModel, path: Path, where: str) -> None:
    """Refuse a robot given that differs from the result's in anything but the rounding of a
    file: joint limits, the base and tool transforms, the URDF it was read from.

    Raises:
        InputError: naming what differs.
    """
    limits = np.concatenate([recorded.lower_rad - given.lower_rad,
                             recorded.upper_rad - given.upper_rad])
    travel = np.tile(np.where(recorded.prismatic, mm_to_m(ROBOT_TOLERANCE_MM),
                              deg_to_rad(ROBOT_TOLERANCE_DEG)), 2)
    ends = np.concatenate([(recorded.structure.base - given.structure.base).ravel(),
                           (recorded.structure.tool - given.structure.tool).ravel()])
    differences = (
        ("joint limits or types", recorded.structure.joint_types
         != given.structure.joint_types or bool(np.any(np.abs(limits) > travel))),
        ("base or tool transform", bool(np.any(np.abs(ends) > mm_to_m(ROBOT_TOLERANCE_MM)))),
        ("URDF", (recorded.urdf is None) != (given.urdf is None) or (
            recorded.urdf is not None and given.urdf is not None
            and (recorded.urdf.text, recorded.urdf.base_link, recorded.urdf.tip_link)
            != (given.urdf.text, given.urdf.base_link, given.urdf.tip_link))),
    )
    for what, differs in differences:
        if differs:
            raise InputError(
                f"a result identified for {recorded.name!r} with another {what} (robot "
                f"{robot_digest(recorded)[:12]})", f"the robot --robot names (robot "
                f"{robot_digest(given)[:12]}) to be the result's; leave out --robot to use the "
                "result's own", source=path, where=f"{where}robot")


def check_bounds(delta: NDArray[np.float64], path: Path, where: str,
                 is_length: NDArray[np.bool_] | None = None,
                 box: tuple[NDArray[np.float64], NDArray[np.float64]] | None = None) -> None:
    """Refuse table errors beyond the search bounds: no method returns them, so the file is not
    what a calibration wrote.

    Args:
        delta: Table errors, shape (4, n), m and rad.
        is_length: Which entries are lengths, (4, n); D-H's rows if None.
        box: The search box the result records, (lower, upper), each (4, n), m and rad (0 and
            0 where a parameter was fixed); the paper's ±5 mm / ±8° if None.
    """
    lengths = np.broadcast_to(np.array(DH_IS_LENGTH)[:, None], delta.shape) \
        if is_length is None else is_length
    tolerance = np.where(lengths, mm_to_m(BOUND_TOLERANCE_MM), deg_to_rad(BOUND_TOLERANCE_DEG))
    bound = np.where(lengths, DH_BOUND_M, DH_BOUND_RAD)
    lower, upper = (-bound, bound) if box is None else box
    beyond = (delta < lower - tolerance) | (delta > upper + tolerance)
    if np.any(beyond):
        row, joint = np.argwhere(beyond)[0]
        key = DH_KEYS[row]
        length = bool(lengths[row, joint])
        unit = display_unit(key, length)
        value, low, high = (float(m_to_mm(v) if length else rad_to_deg(v))
                            for v in (delta[row, joint], lower[row, joint], upper[row, joint]))
        shown = f"±{high:g}" if np.isclose(-low, high) else f"{low:g} to {high:g}"
        raise InputError(f"δ{key}{joint + 1} = {value:g} {unit}",
                         f"D-H errors within the search bounds ({shown} {unit} for "
                         f"δ{key}{joint + 1})", source=path, where=f"{where}delta.{key}")


def _robot_and_table(entry: dict[str, Any], where: str, robot: RobotModel | None, path: Path
                     ) -> tuple[RobotModel, NDArray[np.float64]]:
    """The nominal robot a result is for (:func:`result_robot`, checked against ``robot`` for a
    result written before twin kept the robot) and its D-H errors as written, shape (4, n)."""
    nominal, older = result_robot(entry, robot, path, where)
    delta = parse_dh_rows(entry.get("delta"), nominal.n_joints, path, f"{where}delta", "delta",
                          nominal.is_length)
    if older:
        check_result_robot(entry, nominal, path, where)
    return nominal, delta


def load_result_delta(
    path: str | Path, robot: RobotModel | None = None, method: str | None = None
) -> NDArray[np.float64]:
    """The identified D-H errors of a result file for ``robot``, shape (4, n), m and rad.

    A file of one result has ``"delta"`` at the top; a file written with ``--method all`` has
    ``{"methods": {name: result}}`` and needs ``method`` to pick one.

    Args:
        path: The result JSON file.
        robot: The nominal robot the result is to be applied to, if given: it must be the
            result's own (:func:`result_robot`).
        method: Name of the result to take from a multi-method file; must match the single
            result's ``"method"`` if given for a single-result file.

    Raises:
        InputError: if the file is not a result, ``method`` is missing or unknown, the result
            was identified for another robot, or its errors lie beyond the search bounds.
    """
    path = Path(path)
    entry, where = _pick(read_json(path, RESULT_FILE), path, method)
    if isinstance(entry.get("unknowns"), dict):  # checked against the box it records
        return load_result(path, robot, method).delta
    robot, delta = _robot_and_table(entry, where, robot, path)
    check_bounds(delta, path, where, robot.is_length)
    return delta


def result_groups(path: str | Path, method: str | None = None) -> tuple[str, ...]:
    """The unknown groups a result file names (``unknowns.groups``), or none for a result
    written before they were recorded.

    Raises:
        InputError: if the file is not a result, or ``method`` is missing or unknown.
    """
    path = Path(path)
    entry, _ = _pick(read_json(path, RESULT_FILE), path, method)
    unknowns = entry.get("unknowns")
    groups = unknowns.get("groups") if isinstance(unknowns, dict) else None
    return tuple(str(g) for g in groups) if isinstance(groups, list) else ()


def warn_result_cautions(path: str | Path, method: str | None, use: str, *,
                         frames: bool = True) -> None:
    """Warn (:class:`ResultWarning`) before ``use`` (``"exporting"``, ``"compensating"``…) a
    result whose data could not see some motions of the flange (``unobservable.motions``: the
    identified model is placed along them by its start, not by the data), with directions held
    at the nominal (``held_at_nominal``, named), with unknowns a bound
    of the search box decided (``at_bounds``, named) or a prior decided (``prior_decided``,
    named), or whose model did not fit its data (``misfit``). Nothing for a result written
    before they were recorded. ``frames``: whether ``use`` carries the robot's frames (an
    export, a compensation), which the held directions reach; a prediction of the measured
    point is not moved by them.

    Raises:
        InputError: if the file is not a result, or ``method`` is missing or unknown.
    """
    path = Path(path)
    entry, _ = _pick(read_json(path, RESULT_FILE), path, method)
    unobservable = entry.get("unobservable")
    if not isinstance(unobservable, dict):
        unobservable = {}
    motions = unobservable.get("motions")
    if isinstance(motions, list) and motions:
        pins = unobservable.get("pin")
        pin = " or ".join(str(p) for p in pins) if isinstance(pins, list) and pins else ""
        warnings.warn(f"{path}: the data could not see {', '.join(map(str, motions))}: the "
                      "identified model sits along them where the calibration started, not "
                      f"where the robot is, and {use} inherits that"
                      + (f"; pin them with {pin}" if pin else ""), ResultWarning, stacklevel=2)
    held = entry.get("held_at_nominal")
    directions = held.get("directions") if isinstance(held, dict) else None
    if frames and isinstance(directions, list) and directions:
        warnings.warn(f"{path}: the data did not see {', '.join(map(str, directions))}, held at "
                      f"the nominal: {use} carries the nominal robot's values along them, so "
                      "what depends on them (a tool away from the measured point, the flange's "
                      "orientation) is as accurate as the nominal robot's, no more",
                      ResultWarning, stacklevel=2)
    bounded = entry.get("at_bounds")
    if isinstance(bounded, list) and bounded:
        warnings.warn(f"{path}: the search box, not the data, decided "
                      f"{', '.join(map(str, bounded))} (each ended on a bound): the truth may lie "
                      f"beyond it, or the data barely see it, and {use} uses the bound's value",
                      ResultWarning, stacklevel=2)
    decided = entry.get("prior_decided")
    if isinstance(decided, list) and decided:
        warnings.warn(f"{path}: the prior, not the data, decided {', '.join(map(str, decided))} "
                      "(the data add less to each than its prior): they sit near the nominal "
                      f"because the prior says so, and {use} inherits that", ResultWarning,
                      stacklevel=2)
    misfit = entry.get("misfit")
    if isinstance(misfit, dict) and misfit.get("misfit") is True:
        warnings.warn(f"{path}: the model did not fit its data (training RMSE {misfit.get('rmse')}"
                      f" mm against a noise of {misfit.get('noise')} mm), and {use} inherits that",
                      ResultWarning, stacklevel=2)


class IdentifiedModel(NamedTuple):
    """A calibration result as a model and its unknowns, ready to predict or compensate with."""

    model: Model
    """The measurement model the calibration fitted (robot, rig, kind, groups)."""
    x: NDArray[np.float64]
    """The identified unknowns, shape (p,), SI."""
    method: str
    """The method that identified them."""

    @property
    def robot(self) -> RobotModel:
        """The nominal robot the result was identified for."""
        return self.model.robot

    @property
    def delta(self) -> NDArray[np.float64]:
        """The identified errors of the kinematic table, shape (4, n), m and rad."""
        return np.asarray(self.model.table(self.x) - self.model.robot.dh, dtype=np.float64)


def at_temperature(identified: IdentifiedModel, temperature_c: float | None,
                   path: str | Path) -> IdentifiedModel:
    """The result with its links grown to a cell's temperature (``--temperature-c``): its
    model's nominal robot grown by each length's k · (T − T_ref) (:func:`twin.unknowns.thermal.
    grown`), so that every table the model makes — the identified one an export writes, the
    arm a compensation solves on — is the links' at T. Unchanged for None.

    Raises:
        InputError: for a temperature with a result that identified no thermal growth.
    """
    if temperature_c is None:
        return identified
    model = identified.model
    reference = model.rig.temperature_ref_c
    if not model.has("thermal") or reference is None:
        raise InputError(f"--temperature-c with {path}, a result without thermal growth",
                         "a result calibrated with --errors dh,thermal (its links' growth per "
                         "kelvin), or no --temperature-c", source="--temperature-c")
    robot = grown(model.robot, model.block(identified.x, "thermal"), temperature_c - reference)
    return identified._replace(model=replace(model, robot=robot))


def warn_temperature(identified: IdentifiedModel, temperature_c: float | None,
                     path: str | Path, use: str) -> None:
    """Warn (:class:`ResultWarning`) that ``use`` holds the links at the calibration's mean
    temperature when a result identified their growth and no cell temperature was given: the
    robot at another temperature is longer or shorter by k · (T − T_ref) per length."""
    model = identified.model
    reference = model.rig.temperature_ref_c
    if temperature_c is not None or not model.has("thermal") or reference is None:
        return
    largest = float(np.max(np.abs(model.block(identified.x, "thermal")), initial=0.0))
    at = f"{plain(reference, 2)} °C"
    warnings.warn(f"{path}: {use} holds the links at {at}, the calibration's mean temperature; "
                  f"the robot at another temperature T differs by k·(T − {at}) per length (k "
                  f"up to {in_unit(largest, THERMAL_UNIT)}: {mm(10.0 * largest, significant=3)}"
                  " at 10 K): --temperature-c T grows them to the cell's", ResultWarning,
                  stacklevel=2)


def _rig(document: Any, kind: Kind, path: Path, where: str) -> Rig:
    here = f"{where}unknowns.rig"
    if not isinstance(document, dict) or not isinstance(document.get("ports"), dict):
        raise InputError("no rig", '"rig": {"ports": {name: [x, y, z]}, "attachment": [...]}',
                         source=path, where=here)
    ports, names = [], []
    for name, value in document["ports"].items():
        ports.append(parse_port_mm(value, path, f"{here}.ports.{name}"))
        names.append(str(name))
    attachment = parse_port_mm(document.get("attachment", [0.0, 0.0, 0.0]), path,
                               f"{here}.attachment")
    points = document.get("points", {})
    estimated = document.get("estimated_ports", [])
    tracker = document.get("base_in_tracker", {"exact": np.eye(4).ravel().tolist()})
    distances = document.get("distances", [])
    exact = tracker.get("exact") if isinstance(tracker, dict) else None
    if not isinstance(points, dict) or not isinstance(estimated, list) \
            or not isinstance(distances, list) or not isinstance(exact, list) \
            or len(exact) != 16 or not all(isinstance(v, int | float)
                                           and not isinstance(v, bool) for v in exact):
        raise InputError("a rig that is not one twin writes", "the rig of a result written by "
                         "this version of twin calibrate", source=path, where=here)
    reference = document.get("temperature_ref_c")
    if reference is not None and (isinstance(reference, bool)
                                  or not isinstance(reference, int | float)):
        raise InputError(f"{reference!r}", "the reference temperature in °C",
                         source=path, where=f"{here}.temperature_ref_c")
    tension = document.get("tension_n", 0.0)
    if isinstance(tension, bool) or not isinstance(tension, int | float) \
            or not 0.0 <= tension <= MAX_TENSION_N:
        raise InputError(f"{tension!r}", f"a cable tension in N from 0 to {MAX_TENSION_N:g}",
                         source=path, where=f"{here}.tension_n")
    try:
        return Rig(np.reshape(ports, (-1, 3)), tuple(names), attachment,
                   tension_n=float(tension),
                   estimated_ports=tuple(str(name) for name in estimated),
                   unknown_ports=tuple(str(name) for name in _names(document, "unknown_ports",
                                                                    path, here)),
                   sessions=tuple(str(name) for name in _names(document, "sessions", path,
                                                               here)),
                   base_in_tracker=np.reshape(exact, (4, 4)),
                   point_names=tuple(str(name) for name in points),
                   points_m=np.reshape([parse_port_mm(value, path, f"{here}.points.{name}")
                                        for name, value in points.items()], (-1, 3)),
                   distances=tuple(_distance(value, path, f"{here}.distances")
                                   for value in distances),
                   part=_part(document.get(kind.name), kind, path, f"{here}.{kind.name}"),
                   temperature_ref_c=None if reference is None else float(reference))
    except ValueError as exc:
        raise InputError(str(exc), "the rig of a result written by this version of twin "
                         "calibrate", source=path, where=here) from None


def _names(document: dict[str, Any], key: str, path: Path, where: str) -> list[Any]:
    """A rig's list of names (``sessions``…), empty when absent."""
    names = document.get(key, [])
    if not isinstance(names, list):
        raise InputError(f"{names!r}", "a list of names", source=path, where=f"{where}.{key}")
    return names


def _part(document: Any, kind: Kind, path: Path, where: str) -> Part | None:
    """The kind's part of the rig (:meth:`twin.kinds.base.Kind.read_part`), or None."""
    if document is None:
        return None
    try:
        return kind.read_part(document)
    except InputError as exc:
        raise InputError(exc.found, exc.expected, source=path,
                         where=f"{where}.{exc.where}" if exc.where else where) from None


def _distance(value: Any, path: Path, where: str) -> Distance:
    if not isinstance(value, dict) or not isinstance(value.get("points"), list) \
            or len(value["points"]) != 2 or isinstance(value.get("length"), bool) \
            or not isinstance(value.get("length"), int | float):
        raise InputError(f"{value!r}", '{"points": [A, B], "length": mm}', source=path,
                         where=where)
    return Distance(str(value["points"][0]), str(value["points"][1]),
                    float(mm_to_m(value["length"])))


def check_result_inertia(entry: dict[str, Any], robot: RobotModel, path: Path,
                         where: str) -> None:
    """Refuse compliances identified with other link masses or centres of mass than
    ``robot``'s: the torques they multiply would not be the same.

    Raises:
        InputError: naming the first mass or centre of mass that differs.
    """
    recorded = entry.get("robot", {})
    for key, what, mine, scale, tolerance, unit in (
            ("mass_kg", "link masses", robot.mass_kg, 1.0, MASS_TOLERANCE_KG, "kg"),
            ("com_mm", "centres of mass", robot.com_m, float(m_to_mm(1.0)), ROBOT_TOLERANCE_MM,
             "mm")):
        given = recorded.get(key) if isinstance(recorded, dict) else None
        try:
            theirs = None if given is None else np.asarray(given, dtype=np.float64)
        except (TypeError, ValueError):
            theirs = np.full(1, np.nan)
        if mine is None or theirs is None or theirs.shape != mine.shape \
                or not np.all(np.abs(theirs - mine * scale) <= tolerance):
            raise InputError(
                f"compliances identified with other {what} than the robot's",
                f"the masses and centres of mass of the robot file it is applied to (within "
                f"{tolerance:g} {unit})", source=path, where=f"{where}robot.{key}")


def _parameter_values(parameters: list[Any], path: Path, where: str
                      ) -> tuple[list[float], list[str], NDArray[np.float64]]:
    """The unknowns' values and units as written, and x in SI."""
    values, labels = [], []
    for k, parameter in enumerate(parameters):
        value, label = parameter.get("value"), parameter.get("unit")
        if isinstance(value, bool) or not isinstance(value, int | float) \
                or not math.isfinite(value) or not isinstance(label, str):
            raise InputError(f"{parameter!r}", "a finite value with its unit", source=path,
                             where=f"{where}unknowns.parameters[{k}]")
        values.append(float(value))
        labels.append(label)
    try:
        return values, labels, from_display(values, labels)
    except KeyError as exc:
        raise InputError(f"the unit {exc.args[0]!r}", "a unit twin writes", source=path,
                         where=f"{where}unknowns.parameters") from None


def _limit_values(parameters: list[Any], key: str, path: Path, where: str
                  ) -> dict[str, float]:
    """Each parameter's recorded ``key`` (``lower``, ``upper``, ``prior_sigma``) in SI, by name;
    parameters without it (a result written before the limits were recorded, or no prior) are
    left out."""
    found = {}
    for k, parameter in enumerate(parameters):
        if not isinstance(parameter, dict) or parameter.get(key) is None:
            continue
        value, unit = parameter[key], parameter.get("unit")
        if isinstance(value, bool) or not isinstance(value, int | float) \
                or not math.isfinite(value) or not isinstance(unit, str):
            raise InputError(f"{value!r}", "a finite number in the parameter's unit",
                             source=path, where=f"{where}unknowns.parameters[{k}].{key}")
        try:
            found[str(parameter.get("name"))] = float(from_display([value], [unit])[0])
        except KeyError:
            raise InputError(f"the unit {unit!r}", "a unit twin writes", source=path,
                             where=f"{where}unknowns.parameters[{k}]") from None
    return found


def _recorded_limits(groups: tuple[Group, ...], unknowns: dict[str, Any], path: Path,
                     where: str) -> tuple[Group, ...]:
    """The groups as the calibration restricted them: its fixed parameters left out, its box
    and priors (``unknowns.fixed``, each parameter's ``lower``, ``upper``, ``prior_sigma``);
    each group's own where the file records none.

    Raises:
        InputError: for a fixed name no group has, or a box or prior that is not one.
    """
    fixed = unknowns.get("fixed", [])
    every = [name for group in groups for name in group.names]
    if not isinstance(fixed, list) or not all(name in every for name in fixed):
        raise InputError(f"{fixed!r}", "a list of the groups' parameter names", source=path,
                         where=f"{where}unknowns.fixed")
    parameters = unknowns["parameters"]
    lower, upper, sigma = (_limit_values(parameters, key, path, where)
                           for key in ("lower", "upper", "prior_sigma"))
    restricted = []
    for group in groups:
        low = np.array([lower.get(name, bound) for name, bound in zip(
            group.names, group.lower, strict=True)])
        high = np.array([upper.get(name, bound) for name, bound in zip(
            group.names, group.upper, strict=True)])
        weight = np.array([1.0 / sigma[name] if sigma.get(name, 0.0) > 0 else 0.0
                           for name in group.names])
        if np.any((low > 0) | (high < 0) | (low >= high)):
            k = int(np.argmax((low > 0) | (high < 0) | (low >= high)))
            raise InputError(f"{group.names[k]} bounds {low[k]:g} to {high[k]:g}",
                             "a box that holds the nominal (0)", source=path,
                             where=f"{where}unknowns.parameters")
        keep = ~np.isin(np.asarray(group.names, dtype=object), np.asarray(fixed, dtype=object))
        try:
            restricted.append(group.restricted(keep, low, high, weight))
        except ValueError as exc:
            raise InputError(str(exc), "fixed parameters of the robot's errors or the "
                             "attachment", source=path, where=f"{where}unknowns.fixed") from None
    return tuple(restricted)


def load_result(path: str | Path, robot: RobotModel | None = None, method: str | None = None
                ) -> IdentifiedModel:
    """The identified model of a result file, on the nominal robot it carries.

    Args:
        path: The result JSON file.
        robot: The nominal robot the result is to be applied to, if given: it must be the
            result's own (:func:`result_robot`); needed only by results written before twin
            kept the robot.
        method: Name of the result to take from a multi-method file.

    Raises:
        InputError: if the file is not a result, was identified for another robot, names
            unknowns this version does not know, or holds values beyond their search bounds.
    """
    path = Path(path)
    entry, where = _pick(read_json(path, RESULT_FILE), path, method)
    # The D-H errors are written twice (``delta`` for people, the ``dh`` unknowns for the
    # model): checked as export checks them, then held to agree.
    robot, delta = _robot_and_table(entry, where, robot, path)
    unknowns = entry.get("unknowns")
    if not isinstance(unknowns, dict) or not isinstance(unknowns.get("parameters"), list):
        raise InputError("no 'unknowns'", "a result written by this version of twin calibrate",
                         source=path, where=f"{where}unknowns")
    try:
        kind = KINDS.lookup(str(unknowns.get("kind")))
    except InputError as exc:
        raise InputError(exc.found, exc.expected, source=path,
                         where=f"{where}unknowns") from None
    rig = _rig(unknowns.get("rig"), kind, path, where)
    groups = unknowns.get("groups")
    if not isinstance(groups, list) or not all(isinstance(g, str) for g in groups):
        raise InputError(f"{groups!r}", "a list of unknown group names", source=path,
                         where=f"{where}unknowns.groups")
    try:
        model = Model(robot, rig, kind, _recorded_limits(make_groups(groups, robot, rig),
                                                         unknowns, path, where))
    except InputError as exc:
        if exc.source is not None:
            raise
        raise InputError(exc.found, exc.expected, source=path,
                         where=f"{where}unknowns") from None
    if model.has("compliance"):
        check_result_inertia(entry, robot, path, where)
    parameters = unknowns["parameters"]
    names = [p.get("name") if isinstance(p, dict) else None for p in parameters]
    if names != list(model.names):
        raise InputError(f"{len(parameters)} unknowns ({', '.join(map(str, names[:4]))}…)",
                         f"the {model.n_params} unknowns of groups {', '.join(groups)} "
                         f"({', '.join(model.names[:4])}…)", source=path,
                         where=f"{where}unknowns.parameters")
    box = model.bounds()
    dh = model.group("dh")
    check_bounds(delta, path, where, robot.is_length,
                 (dh.spread(model.block(box[0], "dh")).reshape(robot.dh.shape),
                  dh.spread(model.block(box[1], "dh")).reshape(robot.dh.shape)))
    values, labels, x = _parameter_values(parameters, path, where)
    expected = to_display(np.zeros(model.n_params), model.units)[1]
    lower, upper = model.bounds()
    slack = BOUND_SLACK * (upper - lower)
    beyond = (x < lower - slack) | (x > upper + slack) | (np.array(labels) != np.array(expected))
    if np.any(beyond):
        k = int(np.argmax(beyond))
        raise InputError(f"{model.names[k]} = {values[k]:g} {labels[k]}",
                         "a value within its search bounds, in the unit twin writes",
                         source=path, where=f"{where}unknowns.parameters[{k}]")
    tolerance = np.where(robot.is_length, mm_to_m(ROBOT_TOLERANCE_MM),
                         deg_to_rad(ROBOT_TOLERANCE_DEG))
    apart = np.abs(model.table(x) - robot.dh - delta) > tolerance
    if np.any(apart):
        row, joint = np.argwhere(apart)[0]
        raise InputError(f"delta.{DH_KEYS[row]}{joint + 1} and the unknowns disagree",
                         "a result as twin calibrate wrote it", source=path,
                         where=f"{where}delta.{DH_KEYS[row]}")
    return IdentifiedModel(model, x, str(entry.get("method")))

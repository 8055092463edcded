"""One plug-in mechanism: every family's members in a :class:`twin.distribution.Registry`,
looked up by name (or alias), unknown names listed, adapters imported only when asked for."""

from __future__ import annotations

import inspect
import subprocess
import sys

import pytest

from twin.distribution import Lazy, Registry
from twin.errors import UnknownChoiceError
from twin.export import FORMATS
from twin.hardware.encoders import ENCODERS
from twin.hardware.encoders.base import Encoder
from twin.hardware.robot_sources import SOURCES, get_source
from twin.hardware.robot_sources.base import SourceKind
from twin.io.robot_file import default_robot
from twin.kinds import KINDS
from twin.rig import Rig
from twin.solvers import SOLVERS, get_solver
from twin.solvers.base import Solver
from twin.study.executors import EXECUTORS
from twin.unknowns import GROUPS
from twin.unknowns.group import Group


def test_lookup_takes_names_and_aliases_and_lists_the_choices() -> None:
    """A member by name or alias (case folded where asked); an unknown name is an
    UnknownChoiceError naming the kind, the name and every choice with its alias."""
    registry = Registry("colour", {"red": 1, "green": 2}, aliases={"r": "red"},
                        ignore_case=True)
    assert registry.lookup(" RED ") == 1 and registry.lookup("R") == 1
    assert list(registry) == ["red", "green"] and registry["green"] == 2
    with pytest.raises(UnknownChoiceError) as raised:
        registry.lookup("blue", source="--colour", also=["all"])
    assert str(raised.value) == ("--colour: found unknown colour 'blue', expected one of "
                                 "red (r), green, all")
    assert raised.value.choices == ("red (r)", "green", "all")
    with pytest.raises(UnknownChoiceError):
        Registry("colour", {"red": 1}).lookup("RED")
    with pytest.raises(ValueError, match="aliases of no member"):
        Registry("colour", {"red": 1}, aliases={"b": "blue"})


@pytest.mark.slow
def test_a_lazy_member_is_imported_when_first_asked_for() -> None:
    """Registering an adapter's member does not import its module; asking for it does."""
    code = ("import sys\n"
            "from twin.export import FORMATS\n"
            "from twin.hardware.encoders import ENCODERS\n"
            "from twin.study.executors import EXECUTORS\n"
            "assert list(FORMATS) == ['dh', 'urdf', 'yaml', 'mjcf', 'ur-calibration', 'xacro']\n"
            "assert 'mujoco' not in sys.modules and 'serial' not in sys.modules\n"
            "assert 'dask' not in sys.modules\n"
            "FORMATS['mjcf']\n"
            "assert 'mujoco' in sys.modules\n")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          check=False)
    assert done.returncode == 0, done.stderr
    registry = Registry("function", {"sqrt": Lazy("math:sqrt")})
    assert registry["sqrt"](4.0) == 2.0


def test_every_family_registers_members_of_its_interface() -> None:
    """Each registry's members are what its family's interface says: solvers, kinds that
    name themselves, group factories that make groups of their own name, encoder drivers,
    robot sources that name themselves, executors, export functions of one robot."""
    assert all(isinstance(solver, Solver) and solver.name == name
               for name, solver in SOLVERS.items())
    assert get_solver("M2") is SOLVERS["lm"]
    assert all(kind.name == name for name, kind in KINDS.items())
    robot = default_robot()
    rig = Rig.cable([0.6, -0.4, 0.1])
    for name, make in GROUPS.items():
        if name not in ("base", "points", "planes"):  # need a tracker's, points' or planes' rig
            group = make(robot, rig)
            assert isinstance(group, Group) and group.name == name
    assert all(issubclass(driver, Encoder) for driver in ENCODERS.values())
    assert isinstance(SOURCES, Registry)
    assert all(isinstance(kind, SourceKind) and kind.name == name
               for name, kind in SOURCES.items())
    assert get_source("rws2://10.0.0.5") is SOURCES["rws2"]
    for make in EXECUTORS.values():
        assert callable(getattr(make, "run", None)) and hasattr(make, "workers")
    assert all(list(inspect.signature(export).parameters) == ["robot"]
               for export in FORMATS.values())

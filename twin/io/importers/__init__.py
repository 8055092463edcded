"""Measurements from other tools' files into twin's measurement CSV (`twin import`): ROS 1 and
ROS 2 bags and MCAP (:mod:`~twin.io.importers.bag`, ``rosbags``), CSV files of any units and
layout (:mod:`~twin.io.importers.csv_files`). Each gives :class:`~twin.io.importers.base.Imported`:
the poses kept and a reason for every one left out."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

from twin.errors import InputError
from twin.io.importers.bag import is_bag, read_bag
from twin.io.importers.base import Imported, StillRule
from twin.io.importers.csv_files import read_csv_files
from twin.robot import RobotModel


def import_files(paths: Sequence[str | Path], robot: RobotModel, *, angle_unit: str | None,
                 length_unit: str = "mm", headerless: bool = False,
                 rule: StillRule | None = None, joints_topic: str | None = None,
                 reading_topic: str | None = None, session_by: str | None = None
                 ) -> Imported:
    """The poses of bags (one) or CSV files (one or more); CSV rows labelled with their
    session when ``session_by`` says how (:data:`twin.choices.SESSION_BY`).

    Raises:
        InputError: for a mix of bags and CSV files, several bags, CSV without its angle
            unit, a session of a bag's rows, or anything its importer refuses.
    """
    files = [Path(p) for p in paths]
    bags = [p for p in files if is_bag(p)]
    if bags:
        if len(files) > 1:
            raise InputError(f"{len(bags)} bags among {len(files)} inputs", "one bag, or CSV "
                             "files", source=", ".join(map(str, files)))
        if session_by is not None:
            raise InputError("--session-by with a bag", "CSV files (a bag is one recording: "
                             "one session)", source=str(bags[0]))
        return read_bag(bags[0], robot, rule or StillRule(), joints_topic=joints_topic,
                        reading_topic=reading_topic)
    if angle_unit is None:
        raise InputError("CSV input without --angle-unit", "--angle-unit rad or deg (a CSV "
                         "does not say its unit)", source="command line")
    return read_csv_files(files, robot, angle_unit=angle_unit, length_unit=length_unit,
                          headerless=headerless, session_by=session_by)


__all__ = ["Imported", "StillRule", "import_files"]

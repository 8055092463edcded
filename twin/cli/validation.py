"""How `twin calibrate` scores a model on poses it did not train on: a separate file
(``--validate FILE``), k-fold cross-validation (``--cv K``) or leaving out one group of a label
column at a time (``--cv-by COLUMN``) — else the seeded split of ``--train-fraction``."""

from __future__ import annotations

import argparse

from twin.calibration.crossval import CrossValidation, cross_validate
from twin.cli.inputs import Inputs, Validation, prepare_error
from twin.dataset import Measurements
from twin.errors import InputError
from twin.io.measurements import load_labels, load_measurements


def _refuse_mixed(args: argparse.Namespace) -> None:
    """Refuse flags that ask for two ways of holding poses out."""
    if args.train_fraction is not None and (args.validate or args.cv or args.cv_by):
        flag = "--validate" if args.validate else "--cv" if args.cv else "--cv-by"
        raise InputError(f"--train-fraction with {flag}", f"one of them: with {flag} every "
                         "pose of INPUT trains the model it reports", source="--train-fraction")
    if args.cv and args.cv_by:
        raise InputError("--cv with --cv-by", "one of them: K random folds, or one fold per "
                         "group of a column", source="--cv")


def validation_file(args: argparse.Namespace, inputs: Inputs) -> Validation | None:
    """The file ``--validate`` names, read as the training data are; None without it."""
    _refuse_mixed(args)
    if args.validate is None:
        return None
    return Validation(args.validate, load_measurements(args.validate, inputs.robot))


def cross_validation(args: argparse.Namespace, inputs: Inputs, measurements: Measurements,
                     methods: list[str]) -> CrossValidation | None:
    """The cross-validation ``--cv`` or ``--cv-by`` asks for; None without them.

    Raises:
        InputError: with several methods, or reading standard input twice (``--cv-by``).
    """
    _refuse_mixed(args)
    if not (args.cv or args.cv_by):
        return None
    flag = "--cv" if args.cv else "--cv-by"
    if len(methods) != 1:
        raise InputError(f"{flag} with --method all", "one method to cross-validate",
                         source=flag)
    groups = None
    if args.cv_by:
        if str(inputs.measurements_path) == "-":
            raise InputError("--cv-by with standard input", "a measurement file (its column "
                             "is read again)", source="--cv-by")
        groups = load_labels(inputs.measurements_path, args.cv_by)
    try:
        return cross_validate(inputs.robot, measurements, rig=inputs.rig, method=methods[0],
                              settings=inputs.calibration, seed=args.seed, folds=args.cv,
                              groups=groups, group_name=args.cv_by or "group")
    except InputError as exc:
        if exc.where in ("cv", "cv_by"):
            raise exc.at(flag, where="") from None
        raise prepare_error(inputs, exc) from None


__all__ = ["cross_validation", "validation_file"]

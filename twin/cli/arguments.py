"""The parser every subcommand shares, the types of its numeric flags, and the arguments several
subcommands take alike.

A bad flag is one line on stderr, like any other user mistake::

    twin: error: --seed: found 'abc', expected an integer in 0..9223372036854775807

Each numeric flag is checked where it is parsed: finite, in its range, counts with an upper
limit that keeps a typo (``--poses 1e9``) from exhausting memory, times finite or an explicit
``none`` where waiting for ever makes sense. Paths say whether they are read or written
(:class:`~twin.io.paths.InputPath`, :class:`~twin.io.paths.OutputFile`,
:class:`~twin.io.paths.OutputFolder`), so that the CLI checks every output before any work.
"""

from __future__ import annotations

import argparse
import difflib
import math
import re
import sys
from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING, Any, NoReturn

from twin.choices import JOINT_RANGE
from twin.io.paths import InputPath, OutputFile, output_folder

if TYPE_CHECKING:
    from twin.robot import RobotModel

SEED_MAX = 2**63 - 1
"""Largest seed (a TOML integer holds no more)."""
MAX_SECONDS = 86400.0
"""Longest time limit or pause a flag may set: a day."""
NONE = "none"
"""The word that turns a time limit off."""


class UsageError(Exception):
    """A flag the parser refused; the CLI prints it as one line and exits with code 2."""


NEGATIVE_VALUE = re.compile(r"^-\.?[0-9][0-9.,eE+-]*$")
"""What argparse takes for a value, not a flag, though it starts with '-': a number or a list of
numbers (``--port -500,-300,150``; argparse alone knows only a plain ``-5``)."""


def _choices(text: str) -> str:
    """argparse's ``'a', 'b'`` as ``a, b``."""
    return ", ".join(name.strip().strip("'") for name in text.split(","))


_FLAG_MESSAGES: tuple[tuple[str, Callable[[re.Match[str]], str]], ...] = (
    (r"expected one argument", lambda _: "found no value, expected one (a value that starts "
     "with '-' and is not a number: --flag=VALUE)"),
    (r"expected (.+) arguments?", lambda m: f"found too few values, expected {m[1]}"),
    (r"invalid choice: (.*) \(choose from (.*)\)",
     lambda m: f"found {m[1]}, expected one of {_choices(m[2])}"),
    (r"not allowed with argument (.*)", lambda m: f"found it with {m[1]}, expected one of the "
     "two"),
    (r"ignored explicit argument (.*)", lambda m: f"found the value {m[1]}, expected the flag "
     "alone (it takes no value)"),
    (r"invalid (\w+) value: (.*)", lambda m: f"found {m[2]}, expected a {m[1]} value"),
)
"""argparse's messages about one flag, in the form ``found X, expected Y``."""
_COMMAND_MESSAGES: tuple[tuple[str, Callable[[re.Match[str], str], str]], ...] = (
    (r"unrecognized arguments: (.*?)( \(did you mean .*\))?", lambda m, prog:
     f"found unrecognized arguments {m[1]}, expected only those `{prog} COMMAND --help` lists"
     if prog == "twin" else
     f"found unrecognized arguments {m[1]}, expected only those `{prog} --help` lists"
     + (m[2] or "")),
    (r"the following arguments are required: (.*)", lambda m, prog: f"found no {m[1]}, "
     f"expected every argument `{prog} --help` marks as required"),
    (r"ambiguous option: (\S+) could match (.*)", lambda m, prog: f"found {m[1]}, which could "
     f"be {m[2]}, expected one of them written out"),
)
"""argparse's messages about the whole command line, in the form ``found X, expected Y``."""


class ArgumentParser(argparse.ArgumentParser):
    """argparse, with errors raised as :class:`UsageError` (one line, ``--flag: found X,
    expected Y``) instead of the usage, and values such as ``-500,-300,150`` taken as values."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        # argparse asks this matcher whether a word starting with '-' is a negative number.
        self._negative_number_matcher = NEGATIVE_VALUE

    def parse_known_args(self, args: Any = None, namespace: Any = None) -> Any:
        """As argparse's, but a command (a parser without subcommands of its own) refuses what
        it does not know itself, naming the command: flags first, before it asks for a
        required argument that a mistyped flag may have been (``--frmat urdf`` for
        ``--format urdf`` was refused as "found no --format"), then any word left over."""
        words = list(sys.argv[1:] if args is None else args)
        if self._subparsers is None:
            unknown = self._unknown_flags(words)
            if unknown:
                self.error("unrecognized arguments: " + " ".join(unknown)
                           + self._suggestion(unknown[0]))
        parsed, extras = super().parse_known_args(words, namespace)
        if extras and self._subparsers is None:
            self.error("unrecognized arguments: " + " ".join(extras))
        return parsed, extras

    def _unknown_flags(self, words: Sequence[str]) -> list[str]:
        """The words before ``--`` that argparse reads as flags (not ``-`` for stdin, a
        negative number or a word with a space) and that name none of this parser's, whole or
        as the start of one (argparse takes an abbreviation)."""
        known = list(self._option_string_actions)  # argparse's own table of its flags
        unknown = []
        for word in words:
            if word == "--":
                break
            flag = word.split("=", 1)[0]
            if not word.startswith("-") or len(word) == 1 or " " in word \
                    or self._negative_number_matcher.match(word) or flag in known:
                continue
            if not (flag.startswith("--") and any(name.startswith(flag) for name in known)):
                unknown.append(flag)
        return unknown

    def _suggestion(self, flag: str) -> str:
        """`` (did you mean --format?)`` for a flag close to one of the parser's, else ''."""
        close = difflib.get_close_matches(flag, [name for name in self._option_string_actions
                                                 if name.startswith("--")], n=1)
        return f" (did you mean {close[0]}?)" if close else ""

    def error(self, message: str) -> NoReturn:
        """Raise the message in the form ``--flag: found X, expected Y``."""
        flag = re.match(r"argument ([^:]+): (.*)", message, flags=re.S)
        if flag:
            text = flag[2]
            for pattern, rewrite in _FLAG_MESSAGES:
                if (found := re.fullmatch(pattern, text, flags=re.S)) is not None:
                    text = rewrite(found)
                    break
            raise UsageError(f"{flag[1]}: {text}")
        for pattern, whole in _COMMAND_MESSAGES:
            if (found := re.fullmatch(pattern, message, flags=re.S)) is not None:
                raise UsageError(f"{self.prog}: {whole(found, self.prog)}")
        raise UsageError(f"{self.prog}: {message} (see {self.prog} --help)")


def method_name(text: str) -> str:
    """An argparse type: a calibration method's name or paper alias, or ``all``."""
    from twin.errors import InputError
    from twin.solvers import get_solver

    if text.strip().lower() != "all":
        try:
            get_solver(text)
        except InputError as exc:
            raise argparse.ArgumentTypeError(str(exc)) from None
    return text


def _number(text: str) -> float:
    try:
        return float(text)
    except ValueError:
        return math.nan


def integer(minimum: int, maximum: int) -> Callable[[str], int]:
    """An argparse type: a whole number in ``minimum..maximum``."""

    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            value = minimum - 1
        if not minimum <= value <= maximum:
            raise argparse.ArgumentTypeError(
                f"found {text!r}, expected an integer in {minimum}..{maximum}")
        return value

    return parse


seed = integer(0, SEED_MAX)
"""An argparse type: a seed, a non-negative integer."""


def number(minimum: float, maximum: float, *, above: bool = False) -> Callable[[str], float]:
    """An argparse type: a finite number in ``[minimum, maximum]`` (``(minimum, maximum]`` if
    ``above``)."""
    low = "(" if above else "["

    def parse(text: str) -> float:
        value = _number(text)
        if not (minimum < value if above else minimum <= value) or not value <= maximum:
            raise argparse.ArgumentTypeError(
                f"found {text!r}, expected a number in {low}{minimum:g}, {maximum:g}]")
        return value

    return parse


def share(text: str) -> float:
    """An argparse type: a share above 0, at most 1."""
    value = _number(text)
    if not 0 < value <= 1:
        raise argparse.ArgumentTypeError(f"found {text!r}, expected a share in (0, 1]")
    return value


def seconds(*, zero: bool) -> Callable[[str], float | None]:
    """An argparse type: a time limit in s, finite and at most :data:`MAX_SECONDS` (above 0
    unless ``zero``), or ``none`` for no limit."""
    within = number(0.0, MAX_SECONDS, above=not zero)

    def parse(text: str) -> float | None:
        if text.strip().lower() == NONE:
            return None
        try:
            return within(text)
        except argparse.ArgumentTypeError:
            raise argparse.ArgumentTypeError(
                f"found {text!r}, expected a time in {'[' if zero else '('}0, {MAX_SECONDS:g}] "
                f"s, or {NONE} for no limit") from None

    return parse


sigma_mm = number(0.0, 1000.0, above=True)
"""An argparse type: a length noise 1σ in mm."""
sigma_deg = number(0.0, 90.0, above=True)
"""An argparse type: an angle noise 1σ in degrees."""
AUTO_SIGMA = "auto"
"""The ``--sigma`` value that lets the data say σ (:mod:`twin.calibration.noise`)."""


def sigma_or_auto(text: str) -> float | str:
    """An argparse type: a length noise 1σ in mm, or ``auto``."""
    if text.strip().lower() == AUTO_SIGMA:
        return AUTO_SIGMA
    try:
        return sigma_mm(text)
    except argparse.ArgumentTypeError:
        raise argparse.ArgumentTypeError(f"found {text!r}, expected a noise 1σ in mm in (0, "
                                         f"1000], or {AUTO_SIGMA}") from None


def angles_deg(text: str) -> tuple[float, ...]:
    """An argparse type: one angle in degrees, or one per joint, comma-separated, each in
    [0, 10]."""
    parse = number(0.0, 10.0)
    try:
        return tuple(parse(item) for item in text.split(","))
    except argparse.ArgumentTypeError:
        raise argparse.ArgumentTypeError(f"found {text!r}, expected an angle in degrees from 0 "
                                         "to 10, or one per joint, comma-separated") from None
pause = number(0.0, MAX_SECONDS)
"""An argparse type: a pause in s, finite, at most :data:`MAX_SECONDS`."""


def add_scenario(parser: argparse.ArgumentParser, help: str = "scenario file") -> None:
    """The positional ``SCENARIO.toml``, read."""
    parser.add_argument("scenario", type=InputPath, metavar="SCENARIO.toml", help=help)


def add_input(parser: argparse.ArgumentParser, help: str) -> None:
    """The positional ``INPUT`` of a calibration: a measurement CSV or a capture.toml."""
    parser.add_argument("input", type=InputPath, metavar="INPUT", help=help)


RESULT_HELP = "calibration result written by `twin calibrate --json`"


def add_result(parser: argparse.ArgumentParser, *, positional: bool = False,
               required: bool = True) -> None:
    """The calibration result a command applies: positional ``RESULT.json``, or
    ``--identified RESULT.json``."""
    if positional:
        parser.add_argument("result", type=InputPath, metavar="RESULT.json", help=RESULT_HELP)
    else:
        parser.add_argument("--identified", type=InputPath, required=required,
                            metavar="RESULT.json", help=RESULT_HELP)


def add_output(parser: argparse.ArgumentParser, metavar: str, help: str, *,
               folder: tuple[str, ...] | None = None, flag: str = "--out",
               required: bool = True) -> None:
    """An output file, or a folder into which the command writes files named as ``folder``
    (patterns, :func:`twin.io.paths.output_folder`), that the CLI checks before any work."""
    parser.add_argument(flag, type=OutputFile if folder is None else output_folder(*folder),
                        required=required, metavar=metavar, help=help)


def add_seed(parser: argparse.ArgumentParser, help: str, default: int | None = None) -> None:
    """``--seed``, a non-negative integer."""
    parser.add_argument("--seed", type=seed, default=default, help=help)


def add_error_groups(parser: argparse.ArgumentParser, help: str, *, auto: bool = False,
                     default: tuple[str, ...] | None = None) -> None:
    """``--errors``: the robot's error groups, comma-separated (or ``auto`` when ``auto``)."""
    parser.add_argument("--errors", type=error_groups(auto=auto), default=default,
                        metavar="GROUPS", help=help)


def add_cable_tension(parser: argparse.ArgumentParser, help: str,
                      default: float | None = None) -> None:
    """``--cable-tension``: the cable's pull in N, from 0 to :data:`twin.choices.MAX_TENSION_N`.
    """
    from twin.choices import MAX_TENSION_N

    parser.add_argument("--cable-tension", type=number(0.0, MAX_TENSION_N), default=default,
                        metavar="N", help=help)


def add_temperature(parser: argparse.ArgumentParser, use: str) -> None:
    """``--temperature-c``: the cell's temperature in °C, at which a result with thermal growth
    is applied (its links grown to it from the calibration's mean temperature)."""
    parser.add_argument("--temperature-c", type=number(-50.0, 150.0), metavar="C",
                        help=f"the robot's temperature in °C for {use}, with a result that "
                        "identified thermal growth (--errors dh,thermal): its links grown to it "
                        "from the calibration's mean temperature (default: that temperature)")


RESULT_ROBOT = "the nominal robot, only to check it is the result's (a result carries its own)"
"""What ``--robot`` is for on the commands that read a result."""


def add_robot_flags(parser: argparse.ArgumentParser, what: str = "robot model") -> None:
    """``--robot`` (a model TOML or a URDF) and, for a URDF, ``--base-link`` / ``--tip-link``."""
    default = "the result's" if what == RESULT_ROBOT else "the ABB IRB 120"
    parser.add_argument("--robot", type=InputPath, help=f"{what}: a model TOML file, a .urdf "
                        f"or a .xacro, {JOINT_RANGE} joints (default: {default})")
    parser.add_argument("--xacro-arg", action="append", metavar="NAME:=VALUE",
                        help="with a .xacro --robot: an argument of the description, repeated")
    parser.add_argument("--base-link", metavar="LINK", help="with a URDF --robot: the link "
                        "the chain starts from (default: the URDF's root link)")
    parser.add_argument("--tip-link", metavar="LINK", help="with a URDF --robot: the flange "
                        "link (default: tool0, else flange, else the one leaf link)")


def robot_from_flags(args: argparse.Namespace) -> RobotModel:
    """The robot ``--robot`` names (with its links), or the packaged IRB 120 without it.

    Raises:
        InputError: for --base-link or --tip-link without a URDF --robot, or a bad file.
    """
    from twin.errors import InputError
    from twin.io.robot_file import load_robot_or_default
    from twin.io.xacro_reader import parse_xacro_args

    if args.robot is None and (args.base_link or args.tip_link):
        flag = "--base-link" if args.base_link else "--tip-link"
        raise InputError(f"{flag} without --robot", "--robot ARM.urdf beside it", source=flag)
    return load_robot_or_default(args.robot, base_link=args.base_link, tip_link=args.tip_link,
                                 xacro_args=parse_xacro_args(getattr(args, "xacro_arg", None)))


def given_robot(args: argparse.Namespace) -> RobotModel | None:
    """The robot ``--robot`` names, or None without it: for commands that read a result, which
    carries its own robot (a robot given must be that one).

    Raises:
        InputError: as :func:`robot_from_flags`.
    """
    if args.robot is None and not (args.base_link or args.tip_link):
        return None
    return robot_from_flags(args)


def rules(kind: str) -> Callable[[str], tuple[Any, ...]]:
    """An argparse type: comma-separated rules of :mod:`twin.unknowns.limits`, each a bound,
    a prior or a fix as ``kind`` says (read when the flag is, so that ``--help`` loads
    nothing)."""

    def read(text: str) -> tuple[Any, ...]:
        from twin.errors import InputError
        from twin.unknowns.limits import Bound, Prior, parse_fix

        parse = {"bounds": Bound.parse, "priors": Prior.parse, "fix": parse_fix}[kind]
        try:
            return tuple(parse(item) for item in text.split(","))
        except InputError as exc:
            raise argparse.ArgumentTypeError(f"found {exc.found}, expected {exc.expected}"
                                             ) from None

    return read


def add_limit_flags(parser: argparse.ArgumentParser) -> None:
    """``--bounds``, ``--prior``, ``--fix``: what may move and how far (repeated or
    comma-separated, applied in order after a capture's)."""
    from twin.choices import QUANTITY_UNITS

    parser.add_argument(
        "--bounds", type=rules("bounds"), action="append", metavar="SELECT=W|LOW:HIGH",
        help="the search box instead of each group's own (the paper's ±5 mm / ±8° for the D-H "
        "table): SELECT an unknown (a2), a family (a, theta) or a group (dh, port), W a "
        f"half-width or LOW:HIGH with a unit ({', '.join(QUANTITY_UNITS)}); dh=20mm bounds "
        "the table's lengths, dh=10deg its angles; later rules win (docs/measurements.md)")
    parser.add_argument(
        "--prior", type=rules("priors"), action="append", metavar="SELECT=SIGMA",
        help="a Gaussian prior N(0, σ²) around the nominal (Tikhonov rows x/σ appended to the "
        "residuals), e.g. dh=1mm,dh=0.5deg; the report names the unknowns the prior, not the "
        "data, decided")
    parser.add_argument(
        "--fix", type=rules("fix"), action="append", metavar="SELECT",
        help="unknowns held at the nominal and left out, e.g. theta6,d (robot errors and the "
        "attachment; a rig unknown is fixed by not estimating it)")


def add_validation_flags(parser: argparse.ArgumentParser) -> None:
    """``--validate``, ``--cv``, ``--cv-by``: where held-out figures come from."""
    from twin.choices import MAX_FOLDS, MIN_FOLDS

    parser.add_argument("--validate", type=InputPath, metavar="FILE.csv",
                        help="score the model on this measurement file (same robot and rig); "
                        "every pose of INPUT trains")
    parser.add_argument("--cv", type=integer(MIN_FOLDS, MAX_FOLDS), metavar="K",
                        help="k-fold cross-validation: each of K seeded random folds held out "
                        "in turn; then the model is fitted on every pose")
    parser.add_argument("--cv-by", metavar="COLUMN",
                        help="leave one group out: the poses grouped by this label column of "
                        "INPUT (a placement, a session), each group held out in turn; then "
                        "the model is fitted on every pose")


AUTO_ERRORS = "auto"
"""The ``--errors`` value that lets the data choose the error groups
(:mod:`twin.calibration.selection`)."""


def error_groups(*, auto: bool) -> Callable[[str], tuple[str, ...]]:
    """An argparse type: comma-separated error groups among :data:`twin.unknowns.ERRORS` (in the
    registry's order), or ``auto`` (returned as ``("auto",)``) when ``auto``."""
    from twin.errors import InputError
    from twin.unknowns import ERRORS, check_errors

    choices = ",".join(ERRORS) + (f" (any of them, comma-separated) or {AUTO_ERRORS}" if auto
                                  else " (any of them, comma-separated)")

    def parse(text: str) -> tuple[str, ...]:
        names = [name.strip().lower() for name in text.split(",")]
        if auto and names == [AUTO_ERRORS]:
            return (AUTO_ERRORS,)
        if any(name not in ERRORS for name in names):
            raise argparse.ArgumentTypeError(f"found {text!r}, expected {choices}")
        try:
            return check_errors(names)
        except InputError as exc:
            raise argparse.ArgumentTypeError(f"found {exc.found}, expected {exc.expected}"
                                             ) from None

    return parse


def add_input_flags(parser: argparse.ArgumentParser, *, input_help: str, errors_help: str,
                    tension_help: str, auto: bool = False) -> None:
    """INPUT, the robot and rig flags, ``--errors`` (with ``auto`` when asked) and
    ``--cable-tension``: what `twin calibrate` and `twin identify` read alike."""
    add_input(parser, input_help)
    add_robot_flags(parser)
    add_rig_flags(parser)
    add_error_groups(parser, errors_help, auto=auto)
    add_cable_tension(parser, tension_help)


def add_rig_flags(parser: argparse.ArgumentParser) -> None:
    """The flags that tell the rig and which of its unknowns to identify (calibrate, identify).
    """
    parser.add_argument("--port", action="append", metavar="[NAME=]X,Y,Z",
                        help="encoder port in mm, robot base frame; NAME=X,Y,Z, repeated, for "
                        "an encoder moved between ports (the CSV's port column names each "
                        "row's); 'unknown' for X,Y,Z: nobody measured it, found from the "
                        "lengths (multilateration, then searched within ±2 m; needs "
                        "--estimate-port)")
    parser.add_argument("--estimate-port", action="append", nargs="?", const=ALL_PORTS,
                        metavar="NAME", help="also identify a correction of the ports (of the "
                        "named one, repeated for several; the others stay as measured)")
    parser.add_argument("--attachment", metavar="X,Y,Z",
                        help="the measured point (cable eyelet, tracker target, ball) in the "
                        "flange frame, mm (default 0,0,0: the flange centre)")
    parser.add_argument("--estimate-attachment", action="store_true",
                        help="also identify the measured point in the flange frame")
    parser.add_argument("--estimate-base", action="store_true",
                        help="tracker positions and 6-D poses: also identify the "
                        "instrument-to-base transform, started at a rigid fit of the nominal "
                        "model's points")
    parser.add_argument("--estimate-tool", action="store_true",
                        help="6-D poses: also identify the tool frame on the flange, 6-D: its "
                        "origin (as --estimate-attachment) and its rotation, started at the "
                        "mean the readings say")
    parser.add_argument("--sigma-deg", type=sigma_deg, metavar="DEG",
                        help="6-D poses: the instrument's angle noise 1σ in degrees, what an "
                        "orientation row weighs against a position row of --sigma (default: "
                        "the capture's [encoder] sigma_deg, else 0.01)")
    parser.add_argument("--distance", action="append", metavar="A,B=MM",
                        help="fixed points: a known distance between the points named A and B, "
                        "mm (a ball fixture's socket spacing); touches of planes: between two "
                        "parallel planes (a gauge block's faces); repeat for several")
    parser.add_argument("--angle", action="append", metavar="A,B=DEG",
                        help="touches of planes: a known angle between the normals of the "
                        "planes named A and B, degrees (a square's faces: 90); repeat for "
                        "several")


ALL_PORTS = ""
"""What a bare --estimate-port stands for: every port."""

"""`twin predict`: where an identified model puts the measured point (and what the cable reads)
at joint angles of one's choosing."""

from __future__ import annotations

import argparse

from twin.cli.arguments import (
    RESULT_ROBOT,
    add_output,
    add_result,
    add_robot_flags,
    given_robot,
)
from twin.errors import InputError
from twin.io.paths import InputPath

NAME = "predict"
HELP = "predict the measured point (and cable length) with an identified model"
DESCRIPTION = (
    "For each row of joint angles (q1..q6 in degrees; approach1..approach6 "
    "when the model has backlash), write where the identified model puts the measured "
    "point — the rig's attachment point, the flange centre unless one is set — as x,y,z "
    "in mm in the robot's base frame, with every identified group applied (D-H, "
    "transmission error, backlash for the row's approach, compliance at the pose), and "
    "the cable length in mm when --port is given or the result has one port, and "
    "tracker_x,tracker_y,tracker_z in mm in the tracker frame when the result is of "
    "tracker positions; with thermal growth, at each row's temperature_c (°C; the "
    "result's reference temperature without one). Compare it with anything else: a "
    "tracker, another capture, the twin's truth."
)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """The subcommand's arguments."""
    add_result(parser)
    parser.add_argument("--joints", type=InputPath, required=True, metavar="POSES.csv",
                        help="joint angles q1..qN in degrees (and approach1..approachN: +1 "
                        "or -1), one row per pose (- for standard input)")
    add_robot_flags(parser, RESULT_ROBOT)
    parser.add_argument("--method", help="result to use from a `--method all` result file")
    parser.add_argument("--port", metavar="X,Y,Z", help="encoder port in mm, base frame: "
                        "the length column is the distance from it, the cable pulling "
                        "towards it (default: the result's port, with its identified "
                        "correction and offset, when it has one)")
    add_output(parser, "PRED.csv", "where to write the predictions")


def run(args: argparse.Namespace) -> int:
    """Run the subcommand."""
    import numpy as np

    from twin.calibration.predict import predict
    from twin.io.capture_file import parse_port_mm
    from twin.io.identified import load_result, warn_result_cautions
    from twin.io.measurements import joint_units_said, load_poses
    from twin.io.pose_tables import write_prediction

    identified = load_result(args.identified, given_robot(args), args.method)
    robot = identified.robot
    port_m = None if args.port is None else parse_port_mm(args.port, "--port", "")
    poses = load_poses(args.joints, robot,
                       f"a pose CSV ({joint_units_said(robot.n_joints, robot)})", stdin=True)
    try:
        prediction = predict(identified, poses.q_rad, approach=poses.approach, port_m=port_m,
                             temperature_c=poses.temperature_c)
    except InputError as exc:
        raise InputError(exc.found, exc.expected, source=args.joints) from None
    # After every input is checked: a refusal stays one line.
    warn_result_cautions(args.identified, args.method, "the prediction", frames=False)
    write_prediction(args.out, poses.q_rad, poses.approach, prediction, robot)
    model = identified.model
    estimated = model.has("attachment")
    point = "identified attachment point" if estimated else "attachment point" \
        if np.any(np.abs(model.rig.attachment_m) > 0) else "flange centre"
    groups = ", ".join(group.name for group in model.groups)
    columns = [name for name, _ in model.kind.prediction_columns(prediction.readings)]
    extra = f", {','.join(columns)}{model.kind.prediction_note}" if columns else ""
    print(f"{len(poses.q_rad)} poses: x,y,z (mm, base frame) of the {point}{extra}, by the "
          f"{identified.method} model ({groups})")
    reference = model.rig.temperature_ref_c
    if model.has("thermal") and reference is not None:
        print(f"  the links grown to each row's temperature_c from {reference:.2f} °C"
              if poses.temperature_c is not None else
              f"  at the reference temperature {reference:.2f} °C: {args.joints} has no "
              "temperature_c column")
    print(f"wrote {args.out}")
    return 0

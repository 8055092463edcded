"""Program filtering: robtargets of a RAPID module rewritten per second, the batched filter
(`twin.io.rapid_filter.filter_module`, every target's IK in one batch) against the same filter
called target by target (a module of one target at a time, as a plain loop would).

Run by hand: ``python bench/bench_rapid.py`` (40 targets; ``--tiny``: 3). Prints the median
wall time of repeated runs, targets per second and the ratio, and how many targets both ways
write alike (random IK starts differ between a batch and a single target, so a target may land
a few 1e-6 on the last digit apart).
"""

from __future__ import annotations

import numpy as np
from _timing import median_time, tiny_run
from scipy.spatial.transform import Rotation

from twin.calibration.setup import make_model
from twin.compensation.configuration import configuration
from twin.compensation.poses import controller_tool0
from twin.compensation.targets import reachable_targets
from twin.io.rapid import format_number, parse_module
from twin.io.rapid_filter import Filtered, TargetFrames, filter_module
from twin.io.robot_file import default_robot
from twin.rig import Rig

REPEATS = 3
NO_AXES = "[9E9,9E9,9E9,9E9,9E9,9E9]"


def module_text(n: int) -> str:
    """A module of n robtargets of the IRB 120 (tool0, wobj0) on random reachable poses."""
    robot = default_robot()
    q, _ = reachable_targets(robot, n, np.random.default_rng(0))
    tool0 = robot.flange_transforms(q) @ controller_tool0(robot)  # type: ignore[operator]
    quaternion = Rotation.from_matrix(tool0[:, :3, :3]).as_quat(scalar_first=True)
    conf = configuration(robot, q)
    lines = ["MODULE Bench"]
    for k in range(n):
        trans = ",".join(format_number(v, 6) for v in tool0[k, :3, 3] * 1000)
        rot = ",".join(format_number(v, 9) for v in quaternion[k])
        lines.append(f"  CONST robtarget p{k} := [[{trans}],[{rot}],"
                     f"[{','.join(map(str, conf[k]))}],{NO_AXES}];")
    lines += ["  PROC main()", *[f"    MoveL p{k}, v100, fine, tool0;" for k in range(n)],
              "  ENDPROC", "ENDMODULE", ""]
    return "\n".join(lines)


def main() -> None:
    global REPEATS
    n = 40
    if tiny_run(__doc__):
        REPEATS, n = 1, 3
    robot = default_robot()
    model = make_model(robot, Rig.cable(np.array([0.6, -0.4, 0.1])))
    rng = np.random.default_rng(1)
    x = np.zeros(model.n_params)
    x[:24] = rng.uniform(-1, 1, 24) * np.where(robot.is_length.ravel(), 1e-3, np.deg2rad(0.1))
    text = module_text(n)
    tool0 = controller_tool0(robot)

    def batched() -> Filtered:
        return filter_module(parse_module(text, "bench.mod"), model, x, robot, tool0,
                             TargetFrames({}, {}), np.random.default_rng(2))

    def one_by_one() -> list[Filtered]:
        lines = text.splitlines()
        return [filter_module(parse_module("\n".join([lines[0], lines[1 + k], *lines[n + 1:]]),
                                           "bench.mod"), model, x, robot, tool0,
                              TargetFrames({}, {}), np.random.default_rng(2))
                for k in range(n)]

    batched_s, together = median_time(batched, REPEATS)
    loop_s, apart = median_time(one_by_one, REPEATS)
    corrected = [row.status for row in together.rows].count("corrected")
    same = sum(a.text.splitlines()[1] == together.text.splitlines()[1 + k]
               for k, a in enumerate(apart))
    print(f"{n} robtargets ({corrected} corrected; {same} written alike both ways)")
    print(f"  twin, batched      {batched_s * 1e3:10.1f} ms  {n / batched_s:10.0f} targets/s")
    print(f"  target by target   {loop_s * 1e3:10.1f} ms  {n / loop_s:10.0f} targets/s")
    print(f"  ratio              {loop_s / batched_s:10.1f}×")


if __name__ == "__main__":
    main()

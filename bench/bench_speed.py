"""Where users wait, each ratio measured side by side in one run and printed beside its goal.

Run by hand: ``.venv/bin/python bench/bench_speed.py`` (about three minutes on 2 cores);
``--tiny`` runs every part at a smoke size (CI: ``tests/test_bench_smoke.py``), whose figures
mean nothing. BLAS is pinned to one thread in this process (set before numpy loads), as every
study worker is.

1. **Start-up**: ``twin --version`` against ``python -c "import numpy"``, median wall time of
   repeated runs. Goal: at most 2×. Beside it, a whole command: the README's ``twin
   calibrate`` of ``examples/irb120_lm`` (LM, the checks and the report), against the same.
2. **The hot kernel**: residuals and their 24-column D-H Jacobian at 96 poses of the IRB 120,
   evaluations per CPU-second of :meth:`twin.model.Model.jacobian` — on the numpy path a single
   command takes, and on the compiled kernel a study's workers take (extra ``fast``;
   :func:`twin.geometry.kinematics.for_bulk_work`) — against a plain batched
   finite-difference reference in the same run (the lengths of the 25 tables x and x + h·e_k,
   the flange centre carried through each joint's D-H motions on arrays over every table and
   pose at once, then forward differences), the two timed in alternating blocks (as in 3).
   Both are checked to agree first. Goal: at least 6×.
3. **M9 under the paper's protocol** (AMLM 30 + BIPSO 30, 100 particles) against LM run to
   convergence, CPU time of the solve on the same simulated paper rig, with the kernel a study
   takes (parts 3 to 5 alike), the two timed in alternating blocks. Goal: at most 5×.
4. **Study CPU per trial**: geometric_irb120 with LM, every column of a trial's row included
   (the hold, the identifiability, the bound, the truth; not the checks only a report shows),
   trials one after the other in one process, BLAS pinned: this tree beside the commit this
   work started from (:data:`BEFORE_COMMIT`, its files extracted by git and run by
   ``_study_cpu.py`` in a process of their own, as this tree's are), the two processes running
   the same trials in turn, a worker's batch at a time (:data:`STUDY_BLOCK`, each block run as
   a worker runs a batch). Goal: at most 1/5. The
   trials' results are the same to 1e-7 relative (iterative solvers carry the kernel's
   round-off; the same iterations). Then, where this tree's trial spends its CPU: the first
   :data:`STAGE_TRIALS` trials again with each stage's functions timed
   (``_study_cpu.STAGES``).
5. **Study throughput**: as `twin study` runs trials, from a shell that does not pin BLAS:
   the CPU per trial of the run (the command's process and its workers) on 1 and 2 local
   processes, both trees (goal: at most 1/5), and
   trials per second of wall time on 1 and 2 workers, local processes and a Dask
   LocalCluster, once running: over the middle half of a run's trials, from when a quarter of
   them had been recorded to when three quarters had (what a run pays once — the executor's
   start and stop, the workers' imports, the last batches' tail — left out), best of two runs
   each; whole runs beside it. Every executor's runs share one process per tree (local
   processes first, then Dask), after a trial that loads what only a command's first run
   loads (imports, numba's first call). Goal: 2 local workers at least 1.8× one. Beside it,
   before and after those runs, what two busy processes of a pure-Python loop give against one
   on this machine at the time: the ceiling of any such ratio (a shared VM's moves from 1.5× to
   2.0× within a minute).
6. **Every scenario's trial**: each scenario of ``scenarios/`` with LM as part 4 runs
   geometric_irb120 (one process per tree, BLAS pinned, the trees in turn a few trials at a
   time, after a warm-up trial of each scenario), this tree beside :data:`BEFORE_COMMIT` where
   that commit has the scenario: the CPU per trial of each, and of one trial of every scenario
   both have, in all. No goal of its own (part 4 measures the goal): how far the other studies
   have come.
"""

from __future__ import annotations

import os

BLAS_VARIABLES = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")
for _variable in BLAS_VARIABLES:
    os.environ[_variable] = "1"  # before numpy loads

import argparse  # noqa: E402
import json  # noqa: E402
import multiprocessing  # noqa: E402
import statistics  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from collections.abc import Callable  # noqa: E402
from contextlib import ExitStack  # noqa: E402
from dataclasses import replace  # noqa: E402
from pathlib import Path  # noqa: E402
from typing import IO, Any  # noqa: E402

import numpy as np  # noqa: E402
from _timing import median_time  # noqa: E402

from twin.calibration.setup import make_model, make_problem  # noqa: E402
from twin.geometry import kinematics  # noqa: E402
from twin.io.robot_file import default_robot  # noqa: E402
from twin.rig import Rig  # noqa: E402
from twin.robot import random_poses  # noqa: E402
from twin.solvers import get_solver  # noqa: E402
from twin.study.executors import MAX_BATCH  # noqa: E402
from twin.units import mm_to_m  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
EXAMPLE = ("calibrate", str(ROOT / "examples" / "irb120_lm" / "measurements.csv"), "--port",
           "600,-400,100")
"""The README's first command (its ``--json`` output goes to a temporary folder)."""
GEOMETRIC = ROOT / "scenarios" / "geometric_irb120.toml"
PAPER = ROOT / "scenarios" / "paper_irb120.toml"
PORT_M = mm_to_m([600.0, -400.0, 100.0])
STEP = 1e-7
"""Forward-difference step of the reference, m and rad."""
BEFORE_COMMIT = "599d482"
"""The commit this work started from: parts 4 and 5 run its tree beside this one (extracted by
git; skipped where the checkout does not hold it)."""
DRIVER = Path(__file__).resolve().parent / "_study_cpu.py"
BLOCK = 4
"""Timed calls of each function per round of :func:`_cpu`."""
SPIN, SPIN_TINY = 8_000_000, 100_000
"""Loop steps per process of :func:`machine_scaling` (about a second), and at the smoke size."""
SPIN_TRIALS = 20
"""Runs of fewer trials than this are the smoke size's."""
STUDY_BLOCK = MAX_BATCH
"""Trials per block of part 4, whose trees run block by block in turn: as many as a worker's
batch holds, each block one batch (``run_batch``), as a study's worker runs it."""
STAGE_TRIALS = 20
"""Trials part 4 runs again in this tree, each stage's CPU counted."""
SCENARIO_TRIALS, SCENARIO_BLOCK = 6, 2
"""Trials of each scenario part 6 runs, and per block of the trees' turns."""
TINY_SCENARIOS = ("geometric_irb120.toml", "few_poses_irb120.toml")
"""The scenarios part 6 runs at the smoke size (this tree only)."""


def _goal(label: str, ratio: float, goal: str, met: bool | None) -> None:
    verdict = "" if met is None else "met" if met else "NOT MET"
    print(f"  {label:<52} {ratio:8.2f}×   goal {goal:<8} {verdict}")


def startup(repeats: int) -> None:
    """`twin --version` and the README's `twin calibrate` vs `python -c "import numpy"`,
    median wall time."""
    twin = [sys.executable, "-m", "twin", "--version"]
    numpy_only = [sys.executable, "-c", "import numpy"]

    def run(command: list[str], env: dict[str, str] | None = None) -> Callable[[], None]:
        return lambda: subprocess.run(command, check=True, capture_output=True, env=env)

    # The first run writes the bytecode of twin's modules, as a user's first run (or pip's
    # install) does; a shell with PYTHONDONTWRITEBYTECODE set would have every run compile
    # them again (about 55 ms of each run here), which no install does and numpy never pays.
    writes = {name: value for name, value in os.environ.items()
              if name != "PYTHONDONTWRITEBYTECODE"}
    with tempfile.TemporaryDirectory() as folder:
        calibrate = [*twin[:-1], *EXAMPLE, "--json", str(Path(folder) / "result.json")]
        run(twin, writes)()
        run(calibrate, writes)()
        run(numpy_only)()
        twin_s, _ = median_time(run(twin), repeats)
        numpy_s, _ = median_time(run(numpy_only), repeats)
        command_s, _ = median_time(run(calibrate), repeats)
    print(f"1. start-up, median of {repeats}: twin --version {twin_s * 1e3:.0f} ms, "
          f"import numpy {numpy_s * 1e3:.0f} ms; twin {EXAMPLE[0]} (README) "
          f"{command_s * 1e3:.0f} ms")
    _goal("twin --version / import numpy", twin_s / numpy_s, "<= 2", twin_s <= 2 * numpy_s)
    _goal(f"twin {EXAMPLE[0]} (a whole command) / import numpy", command_s / numpy_s, "none",
          None)


def _dh_lengths(tables: np.ndarray, q: np.ndarray, port_m: np.ndarray) -> np.ndarray:
    """The reference: cable lengths of K standard D-H tables (K, 4, n) at poses q (m, n), the
    flange centre carried from the flange to the base through each joint's
    Rz(q + θ) · Tz(d) · Tx(a) · Rx(α), arrays over tables and poses; shape (K, m)."""
    shape = (tables.shape[0], q.shape[0])
    x, y, z = np.zeros(shape), np.zeros(shape), np.zeros(shape)
    for i in range(tables.shape[-1] - 1, -1, -1):
        a, d, alpha, theta = (tables[:, k, i, None] for k in range(4))
        ca, sa = np.cos(alpha), np.sin(alpha)
        y, z = ca * y - sa * z, sa * y + ca * z
        x = x + a
        z = z + d
        angle = q[:, i] + theta
        ct, st = np.cos(angle), np.sin(angle)
        x, y = ct * x - st * y, st * x + ct * y
    return np.sqrt((x - port_m[0]) ** 2 + (y - port_m[1]) ** 2 + (z - port_m[2]) ** 2)


def kernel(poses: int, seconds: float) -> None:
    """Model.jacobian against the batched finite-difference reference, evaluations per second,
    on the numpy path (what a single command takes) and the compiled kernel (a study's)."""
    robot = default_robot()
    rng = np.random.default_rng(0)
    model = make_model(robot, Rig.cable(PORT_M))
    x = rng.uniform(-1, 1, model.n_params) * model.radius
    data = model.measure(x, random_poses(robot, poses, rng))
    lengths = data.value("length_m")
    steps = np.vstack([np.zeros(model.n_params), STEP * np.eye(model.n_params)])

    def reference() -> tuple[np.ndarray, np.ndarray]:
        tables = (robot.dh.ravel() + x + steps).reshape(-1, *robot.dh.shape)
        r = _dh_lengths(tables, data.q_rad, PORT_M) - lengths
        return r[0], ((r[1:] - r[0]) / STEP).T

    def ours() -> tuple[np.ndarray, np.ndarray]:
        return model.jacobian(x, data)

    rates = {}
    for label, mode in (("numpy", "numpy"), ("compiled", "numba")):
        os.environ[kinematics.KERNEL_VARIABLE] = mode
        kinematics._compiled.cache_clear()
        (r_ref, j_ref), (r_ours, j_ours) = reference(), ours()
        assert np.allclose(r_ref, r_ours, rtol=0, atol=1e-12), "residuals disagree"
        assert np.allclose(j_ref, j_ours, rtol=0, atol=1e-5), "Jacobians disagree"
        cpu = _cpu({"reference": reference, label: ours}, 2 * seconds)
        rates[label], rates[f"reference ({label})"] = 1 / cpu[label], 1 / cpu["reference"]
    del os.environ[kinematics.KERNEL_VARIABLE]
    kinematics._compiled.cache_clear()
    print(f"2. residual + {model.n_params}-column Jacobian at {poses} poses: numpy path "
          f"{rates['numpy']:,.0f}/s beside the reference's {rates['reference (numpy)']:,.0f}/s;"
          f" compiled {rates['compiled']:,.0f}/s beside {rates['reference (compiled)']:,.0f}/s")
    for label in ("numpy", "compiled"):
        ratio = rates[label] / rates[f"reference ({label})"]
        _goal(f"twin ({label}) / finite-difference reference", ratio, ">= 6", ratio >= 6)


def _cpu(functions: dict[str, Callable[[], object]], seconds: float) -> dict[str, float]:
    """Median CPU time of each function's calls, s, measured in turn: rounds of a block of
    :data:`BLOCK` timed calls of each, after an untimed one that warms what the other left
    cold, for ``seconds`` of CPU in all (at least three rounds). Blocks in turn cancel the
    drift of a shared VM's speed (one after the other, 2 s each, M9 / LM read 4.58-6.37x over
    five runs of one tree); single calls in turn would time each cold from the other (LM
    2.5-2.7 ms against 2.0-2.1 ms warm)."""
    times: dict[str, list[float]] = {name: [] for name in functions}
    while len(times[next(iter(functions))]) < 3 * BLOCK or sum(map(sum, times.values())) < seconds:
        for name, function in functions.items():
            function()
            for _ in range(BLOCK):
                start = time.process_time()
                function()
                times[name].append(time.process_time() - start)
    return {name: statistics.median(values) for name, values in times.items()}


def paper_m9(poses: int, seconds: float, particles: int | None) -> None:
    """M9 under the paper's protocol vs LM to convergence, CPU of the solve."""
    from twin.scenario import load_scenario
    from twin.sim.simulate import simulate
    from twin.solvers import swarm

    if particles is not None:
        swarm.N_PARTICLES = swarm.N_INTERPOLATED = particles
    scenario = load_scenario(PAPER)
    sim = simulate(scenario, 0)
    data = sim.measurements.subset(np.arange(min(poses, len(sim.measurements))))
    solves = {}
    for method, stop in (("lm", "converge"), ("amlm-bipso", "paper")):
        settings = replace(scenario.calibration, stop=stop)
        split = make_problem(sim.robot, data, None, rig=sim.rig_told_pulled, settings=settings)
        solver = get_solver(method)
        solves[method] = lambda solver=solver, split=split: solver.solve(
            split.problem, split.settings.budget, np.random.default_rng(0))
    times = _cpu(solves, 2 * seconds)
    print(f"3. paper rig, {len(data)} poses: M9 (paper protocol) {times['amlm-bipso'] * 1e3:.1f} "
          f"ms CPU, LM to convergence {times['lm'] * 1e3:.1f} ms CPU")
    _goal("M9 (paper) / LM (converge)", times["amlm-bipso"] / times["lm"], "<= 5",
          times["amlm-bipso"] <= 5 * times["lm"])


def _before_tree(folder: Path) -> Path | None:
    """The files of :data:`BEFORE_COMMIT`, extracted into ``folder`` by git; None where this
    checkout does not hold that commit (a shallow clone, an unpacked archive)."""
    archive = subprocess.run(["git", "-C", str(ROOT), "archive", BEFORE_COMMIT],
                             capture_output=True, check=False)
    if archive.returncode:
        return None
    subprocess.run(["tar", "-x", "-C", str(folder)], input=archive.stdout, check=True)
    return folder


def _study(tree: Path, executors: list[str], sizes: list[int]
           ) -> dict[str, list[dict[str, Any]]]:
    """``_study_cpu.py EXECUTORS SIZES`` on the twin of ``tree`` (its own geometric scenario),
    in one process whose environment leaves BLAS's threads unset, as a user's shell does: each
    executor's runs, by its name."""
    env = {name: value for name, value in os.environ.items() if name not in BLAS_VARIABLES}
    env["PYTHONPATH"] = str(tree)
    mode = ",".join(executors)
    done = subprocess.run(
        [sys.executable, str(DRIVER), mode, ",".join(map(str, sizes)),
         str(tree / "scenarios" / GEOMETRIC.name)],
        cwd=tree, env=env, capture_output=True, text=True, check=False)
    if done.returncode:
        raise SystemExit(f"{DRIVER.name} {mode} on {tree}: {done.stderr[-3000:]}")
    found: dict[str, list[dict[str, Any]]] = json.loads(done.stdout.splitlines()[-1])["runs"]
    return found


def _trees(before: Path | None) -> list[tuple[str, Path]]:
    return [("now", ROOT)] + ([] if before is None else [(BEFORE_COMMIT, before)])


def _serve(stack: ExitStack, tree: Path, trials: int) -> tuple[subprocess.Popen[str], IO[str]]:
    """``_study_cpu.py inprocess`` on the twin of ``tree`` (BLAS pinned, as here), serving
    blocks of trials until ``stack`` closes its stdin; its stderr goes to a temporary file."""
    errors = stack.enter_context(tempfile.TemporaryFile("w+"))  # noqa: SIM115 (the stack closes it)
    process = stack.enter_context(subprocess.Popen(
        [sys.executable, str(DRIVER), "inprocess", str(trials),
         str(tree / "scenarios" / GEOMETRIC.name)],
        cwd=tree, env={**os.environ, "PYTHONPATH": str(tree)}, stdin=subprocess.PIPE,
        stdout=subprocess.PIPE, stderr=errors, text=True))
    return process, errors


def _answer(process: subprocess.Popen[str], errors: IO[str]) -> dict[str, Any]:
    """The driver's next JSON line; its stderr as the error where it ended instead."""
    assert process.stdout is not None
    line = process.stdout.readline()
    if not line:
        errors.seek(0)
        raise SystemExit(f"{DRIVER.name} inprocess: {errors.read()[-3000:]}")
    found: dict[str, Any] = json.loads(line)
    return found


def study_cpu(trials: int, before: Path | None) -> None:
    """CPU per trial of the geometric study with LM in one process, this tree and the one
    before, BLAS pinned in both: the same trials, :data:`STUDY_BLOCK` at a time, the trees in
    turn, so that both see the same drift of the machine's speed."""
    cpu = {label: 0.0 for label, _ in _trees(before)}
    with ExitStack() as stack:
        drivers = {label: _serve(stack, tree, trials) for label, tree in _trees(before)}
        for driver in drivers.values():
            _answer(*driver)  # ready: its warm-up trial has run
        for first in range(0, trials, STUDY_BLOCK):
            count = min(STUDY_BLOCK, trials - first)
            for label, driver in drivers.items():
                cpu[label] += _block(driver, f"{first} {count}")["cpu_s"] * count / trials
        timed = min(trials, STAGE_TRIALS)
        stages = _block(drivers["now"], f"0 {timed} stages")
    shown = ", ".join(f"{label} {value * 1e3:.1f} ms" for label, value in cpu.items())
    print(f"4. study, {GEOMETRIC.name} with LM, {trials} trials in one process, CPU per trial: "
          f"{shown} (the trees in turn, {STUDY_BLOCK} trials at a time)")
    if before is not None:
        ratio = cpu["now"] / cpu[BEFORE_COMMIT]
        _goal(f"CPU per trial in one process / at {BEFORE_COMMIT}", ratio, "<= 0.2",
              ratio <= 0.2)
    else:
        print(f"  ({BEFORE_COMMIT} is not in this checkout: nothing to compare with)")
    print(f"  where a trial's CPU goes now ({timed} trial(s) again, their stages timed, "
          f"{stages['cpu_s'] * 1e3:.1f} ms a trial): {_stages(stages)}")


def scenario_cpu(trials: int, before: Path | None, names: tuple[str, ...] | None) -> None:
    """CPU per trial of every scenario (``names`` only, when given) with LM in one process,
    this tree and the one before where it has the scenario, BLAS pinned in both, the trees in
    turn :data:`SCENARIO_BLOCK` trials at a time."""
    names = names or tuple(sorted(path.name for path in (ROOT / "scenarios").glob("*.toml")))
    trees = dict(_trees(before))
    cpu: dict[str, dict[str, float]] = {}
    with ExitStack() as stack:
        drivers = {label: _serve(stack, tree, trials) for label, tree in trees.items()}
        for driver in drivers.values():
            _answer(*driver)
        for name in names:
            here = {label: driver for label, driver in drivers.items()
                    if (trees[label] / "scenarios" / name).is_file()}
            for label, driver in here.items():
                _block(driver, f"scenario {trees[label] / 'scenarios' / name}")
            cpu[name] = dict.fromkeys(here, 0.0)
            for first in range(0, trials, SCENARIO_BLOCK):
                count = min(SCENARIO_BLOCK, trials - first)
                for label, driver in here.items():
                    cpu[name][label] += _block(driver, f"{first} {count}")["cpu_s"] \
                        * count / trials
    print(f"6. every scenario with LM, {trials} trial(s) each in one process, CPU per trial "
          f"(the trees in turn, {SCENARIO_BLOCK} trials at a time):")
    print(f"  {'scenario':<28}" + "".join(f"{label:>12}" for label in trees)
          + ("   now/then" if len(trees) == 2 else ""))
    for name, found in cpu.items():
        shown = "".join(f"{found[label] * 1e3:9.1f} ms" if label in found else f"{'—':>12}"
                        for label in trees)
        ratio = f"{found['now'] / found[BEFORE_COMMIT]:10.2f}×" if len(found) == 2 else ""
        print(f"  {name.removesuffix('.toml'):<28}{shown}{ratio}")
    both = [found for found in cpu.values() if len(found) == 2]
    if both:
        now, then = (sum(found[label] for found in both) for label in ("now", BEFORE_COMMIT))
        print(f"  one trial of each of the {len(both)} scenarios {BEFORE_COMMIT} has: "
              f"{now * 1e3:.0f} ms now, {then * 1e3:.0f} ms then")
        _goal(f"their CPU in all / at {BEFORE_COMMIT} (part 4 is the goal's)", now / then,
              "none", None)


def _block(driver: tuple[subprocess.Popen[str], IO[str]], line: str) -> dict[str, Any]:
    """A driver's answer to a block of trials (:data:`DRIVER`'s ``inprocess`` mode)."""
    process, errors = driver
    assert process.stdin is not None
    process.stdin.write(line + "\n")
    process.stdin.flush()
    return _answer(process, errors)


def _stages(found: dict[str, Any]) -> str:
    """A trial's stages as shares of its CPU: LM, the hold and the identifiability within
    calibrate, what no stage counts as the rest."""
    total, spent = found["cpu_s"], found["stages"]
    share = {label: f"{label} {100 * value / total:.0f} %" for label, value in spent.items()}
    inside = ("LM", "hold", "identifiability")
    rest = total - sum(value for label, value in spent.items() if label not in inside)
    return (f"{share['simulate']}, {share['calibrate']} (of it "
            + ", ".join(share[label] for label in inside) + "), "
            + f"{share['bound']}, {share['truth']}, the rest {100 * rest / total:.0f} %")


def _local_cpu(trials: int, before: Path | None, runs: dict[str, list[dict[str, Any]]]
               ) -> None:
    """The CPU per trial of the first run of ``trials`` on 1 and 2 local processes, this tree
    (from ``runs``) beside the one before (run here), and the ratio to its goal."""
    cpu = {f"now {name[-1]}": found[0]["cpu_s"] for name, found in runs.items()
           if name.startswith("local")}
    if before is not None:
        for name, found in _study(before, ["local1", "local2"], [trials]).items():
            cpu[f"{BEFORE_COMMIT} {name[-1]}"] = found[0]["cpu_s"]
    for workers in (1, 2):
        shown = ", ".join(f"{label} {cpu[f'{label} {workers}'] * 1e3:.1f} ms"
                          for label, _ in _trees(before))
        print(f"5. {trials} trials on {workers} local worker(s), CPU per trial: {shown}")
        if before is not None:
            ratio = cpu[f"now {workers}"] / cpu[f"{BEFORE_COMMIT} {workers}"]
            _goal(f"CPU per trial, {workers} local worker(s) / at {BEFORE_COMMIT}", ratio,
                  "<= 0.2", ratio <= 0.2)


def _running_rate(done_s: list[float]) -> float:
    """Trials per second of a run once running: over its middle half, from the time its first
    quarter of trials had been recorded to the time three quarters had (outcomes arrive a
    batch at a time; the start, the first batches and the last ones left out)."""
    count = len(done_s)
    first, last = count // 4, max((3 * count) // 4 - 1, count // 4)
    return (last - first) / max(done_s[last] - done_s[first], 1e-6)


def _spin(count: int) -> int:
    total = 0
    for value in range(count):
        total += value * value
    return total


def machine_scaling(count: int) -> float:
    """Two busy processes against one on this machine now: a pure-Python loop on each (no
    memory traffic, nothing shared), forked from here — the ceiling of any two-worker ratio,
    which a shared VM's host moves from minute to minute."""
    rates = {}
    for workers in (1, 2):
        start = time.perf_counter()
        with multiprocessing.get_context("fork").Pool(workers) as pool:
            pool.map(_spin, [count] * (2 * workers))
        rates[workers] = 2 * workers * count / (time.perf_counter() - start)
    return rates[2] / rates[1]


def study_scaling(trials: int, before: Path | None, repeats: int,
                  dask_workers: tuple[int, ...] = (1, 2)) -> None:
    """As `twin study` runs trials (a shell that does not pin BLAS): the CPU per trial of the
    command's process and its workers on 1 and 2 local processes, this tree and the one before
    (when given); trials per second of wall time on 1 and 2 local workers and on
    ``dask_workers`` Dask workers, once running (:func:`_running_rate`), and whole runs, the
    best of ``repeats`` runs of ``trials`` each."""
    names = [f"local{workers}" for workers in (1, 2)] + [f"dask{n}" for n in dask_workers]
    spin = SPIN_TINY if trials < SPIN_TRIALS else SPIN
    ceiling = [machine_scaling(spin)]
    runs = _study(ROOT, names, [trials] * repeats)
    ceiling.append(machine_scaling(spin))
    _local_cpu(trials, before, runs)
    walls = {name: min(run["wall_s"] for run in found) for name, found in runs.items()}
    rates = {name: max(_running_rate(run["done_s"]) for run in found)
             for name, found in runs.items()}
    for name in names:
        print(f"5. {name[:-1]}, {name[-1]} worker(s): {trials} trials in {walls[name]:.2f} s "
              f"(the executor's start and stop included), {rates[name]:.1f} trials/s once "
              f"running (best of {repeats})")
    for kind in ("local", "dask"):
        if f"{kind}1" not in rates or f"{kind}2" not in rates:
            continue
        ratio = rates[f"{kind}2"] / rates[f"{kind}1"]
        _goal(f"{kind}: 2 workers / 1, trials per second once running", ratio,
              ">= 1.8" if kind == "local" else "none", ratio >= 1.8 if kind == "local" else None)
        print(f"  {kind}: whole runs of {trials} trials, the executor's start included: "
              f"{walls[f'{kind}1'] / walls[f'{kind}2']:.2f}×")
    print(f"  load average (1 min) {os.getloadavg()[0]:.2f} on {os.cpu_count()} cores: other "
          "work on the machine takes cores from the workers")
    print(f"  the machine: two busy processes / one, a pure-Python loop each, "
          f"{ceiling[0]:.2f}× before these runs and {ceiling[1]:.2f}× after (the ceiling of "
          "any two-worker ratio here)")


def main() -> None:
    """Run every part and print the ratios beside their goals."""
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--tiny", action="store_true", help="smoke sizes: figures mean nothing")
    parser.add_argument("--parts", default="123456", help="which parts to run (default all)")
    args = parser.parse_args()
    tiny = args.tiny
    if "1" in args.parts:
        startup(repeats=1 if tiny else 15)
    if "2" in args.parts:
        kernel(poses=8 if tiny else 96, seconds=0.05 if tiny else 3.0)
    kinematics.for_bulk_work()  # parts 3 to 5 take the kernel a study takes
    if "3" in args.parts:
        paper_m9(poses=40 if tiny else 120, seconds=0.0 if tiny else 2.0,
                 particles=6 if tiny else None)
    if any(part in args.parts for part in "456"):
        with tempfile.TemporaryDirectory() as temporary:
            before = _before_tree(Path(temporary))
            if "4" in args.parts:
                study_cpu(1 if tiny else 40, before)
            if "5" in args.parts:
                # At the smoke size part 4 alone runs the older tree, and one Dask cluster of
                # one worker starts, once (each worker's start is seconds: it imports twin; a
                # second took 2.8 CPU-s more of the smoke test and ran the same code).
                study_scaling(4 if tiny else 160, None if tiny else before, 1 if tiny else 2,
                              (1,) if tiny else (1, 2))
            if "6" in args.parts:
                scenario_cpu(1 if tiny else SCENARIO_TRIALS, None if tiny else before,
                             TINY_SCENARIOS if tiny else None)


if __name__ == "__main__":
    main()

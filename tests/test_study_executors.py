"""Studies on real worker processes and a real Dask LocalCluster, with workers killed mid-run."""

from __future__ import annotations

import contextlib
import csv
import io
import json
import multiprocessing
import os
import signal
import subprocess
import sys
import tempfile
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from test_study import recorded, with_study, write_scenario

from twin.study.definition import StudyPlan, load_study
from twin.study.executors import make_batches
from twin.study.executors.cluster import DaskCluster
from twin.study.executors.local import LocalProcesses
from twin.study.runner import run_trials
from twin.study.store import TrialOutcome

pytest.importorskip("dask.distributed")


def numbers(folder: Path) -> list[dict[str, str]]:
    """The rows of `results.csv` in trial order, without the wall time."""
    with (folder / "results.csv").open() as handle:
        rows = [{k: v for k, v in row.items() if k != "seconds"} for row in csv.DictReader(handle)]
    return sorted(rows, key=lambda row: int(row["trial"]))


def test_batches_cover_every_item_once() -> None:
    """Batches keep order, cover every item once and give each worker several."""
    items = list(range(37))
    batches = make_batches(items, workers=2)
    assert [i for batch in batches for i in batch] == items
    assert len(batches) >= 8


@pytest.fixture(scope="module")
def calm(tmp_path_factory: pytest.TempPathFactory) -> tuple[StudyPlan, Path]:
    """A 12-trial LM + PSO study and its folder after an undisturbed run on local processes."""
    folder = tmp_path_factory.mktemp("calm")
    plan = load_study(write_scenario(folder, with_study('trials = 12\nmethods = ["lm", "pso"]')))
    run_trials(plan, folder / "out", LocalProcesses(2), stream=io.StringIO())
    return plan, folder / "out"


def _worker_signals(batch: tuple[int, ...]) -> tuple[object, object, set[int]]:
    held = signal.pthread_sigmask(signal.SIG_BLOCK, [])
    return signal.getsignal(signal.SIGINT), signal.getsignal(signal.SIGTERM), set(held)


def test_workers_take_stops_as_workers_and_the_command_gets_them_back() -> None:
    """A worker ignores SIGINT, dies of SIGTERM and holds neither once started (it was forked
    with both held, so that one stopped before its handlers were set cannot swallow them);
    this process holds neither after the run."""
    with LocalProcesses(2) as pool:
        found = list(pool.run(_worker_signals, [(0,), (1,)]))
    assert found == [(signal.SIG_IGN, signal.SIG_DFL, set())] * 2
    held = signal.pthread_sigmask(signal.SIG_BLOCK, [])
    assert not {signal.SIGINT, signal.SIGTERM} & set(held)


STOP_INSIDE_FUTURES = """
import multiprocessing, os, signal, sys
import concurrent.futures
from contextlib import closing
from twin.study.executors.local import LocalProcesses

class Stop(KeyboardInterrupt):
    pass

def stop(signum, frame):
    raise Stop

def tracer(k):
    # SIGTERM to this process at the k-th line it runs inside concurrent.futures (0: never)
    lines = [0]
    def local(frame, event, arg):
        if event == "line":
            lines[0] += 1
            if lines[0] == k:
                os.kill(os.getpid(), signal.SIGTERM)
        return local
    futures = os.path.dirname(concurrent.futures.__file__)
    return (lambda frame, event, arg: local if frame.f_code.co_filename.startswith(futures)
            else None), lines

def run(k):
    trace, lines = tracer(k)
    with LocalProcesses(2) as executor:
        try:
            with closing(executor.run(abs, range(-40, 0))) as results:
                sys.settrace(trace)
                found = sorted(results)
        except Stop:
            found = None
        finally:
            sys.settrace(None)
    assert not multiprocessing.active_children(), k
    assert signal.getsignal(signal.SIGTERM) is stop, k
    return found, lines[0]

signal.signal(signal.SIGTERM, stop)
found, total = run(0)
assert found == list(range(1, 41)), found
stopped = 0
for k in range(1, total + 1, int(sys.argv[1])):
    print(k, flush=True)  # the last printed: where it hung
    found, _ = run(k)
    stopped += found is None
print("stopped", stopped, "of", len(range(1, total + 1, int(sys.argv[1]))), "lines", total)
"""


@pytest.mark.slow
def test_a_stop_inside_concurrent_futures_stops_the_run_and_its_workers() -> None:
    """SIGTERM whose handler raises, arriving at every 11th line the run's process runs inside
    concurrent.futures: each run stops (or ends, if it came after the last result) with no
    worker left and the handler back. Raised inside ``wait()``, holding a future's lock, it
    left the pool's shutdown waiting for ever (a CI run hung; before the fix the sweep hung at
    its first such line)."""
    try:
        run = subprocess.run([sys.executable, "-c", STOP_INSIDE_FUTURES, "11"],
                             capture_output=True, text=True, timeout=60, check=False)
    except subprocess.TimeoutExpired as exc:
        printed = exc.stdout or b""  # bytes after a timeout, even in text mode
        hung = (printed.decode() if isinstance(printed, bytes) else printed).split()
        pytest.fail(f"the run hung after a stop at line {hung[-1] if hung else '?'}")
    assert run.returncode == 0, run.stderr
    summary = run.stdout.splitlines()[-1].split()
    assert int(summary[1]) > 100, run.stdout[-200:]  # stops at many points, not a few


def _blas_threads(batch: tuple[int, ...]) -> list[int]:
    from threadpoolctl import threadpool_info

    return [library["num_threads"] for library in threadpool_info()
            if library["user_api"] == "blas"]


def test_blas_runs_on_one_thread_in_the_command_while_entered_and_in_every_worker() -> None:
    """While the executor is entered, this process (which runs a run's first trial) and every
    worker run BLAS on one thread; this process gets its own count back after."""
    before = _blas_threads(())
    with LocalProcesses(2) as pool:
        assert _blas_threads(()) == [1] * len(before)
        found = list(pool.run(_blas_threads, [(0,), (1,)]))
    assert found == [[1] * len(before)] * 2
    assert _blas_threads(()) == before


KERNEL_VERSIONS = """
import io, json, sys
from functools import partial
from pathlib import Path
from twin.geometry import compiled
from twin.study.definition import load_study
from twin.study.executors.local import LocalProcesses
from twin.study.runner import run_trials

def versions():
    return {name: sorted(map(str, getattr(compiled, name).signatures))
            for name in ("positions", "jacobian", "distances")}

def observed(function, batch):
    before = versions()
    outcomes = function(batch)
    return [(outcomes, {name: [v for v in found if v not in before[name]]
                        for name, found in versions().items()})]

class Observed(LocalProcesses):
    def run(self, function, batches):
        for result in super().run(partial(observed, function), batches):
            new.append(result[0][1])
            yield result[0][0]

new = []
run_trials(load_study(Path(sys.argv[1])), Path(sys.argv[2]), Observed(1),
           stream=io.StringIO())
print(json.dumps(new))
"""


@pytest.mark.slow
def test_a_forked_worker_loads_no_kernel_version_the_command_did_not(tmp_path: Path) -> None:
    """In a fresh process, the first trial runs in the command on the trials' specs as a
    worker receives them (pickled: frozen arrays come back writeable), so the forked worker
    takes the compiled kernels' versions it loaded and loads none of its own (numba makes one
    per writeable flags of the inputs; each took tens of ms of CPU per worker)."""
    pytest.importorskip("numba")
    if not LocalProcesses().forks:
        pytest.skip("workers are spawned here: each loads its kernels")
    scenario = write_scenario(tmp_path, with_study('trials = 4\nmethods = ["lm"]'))
    env = {**os.environ, "PYTHONPATH": str(Path(__file__).resolve().parents[1])}
    env.pop("TWIN_KERNEL", None)
    done = subprocess.run([sys.executable, "-c", KERNEL_VERSIONS, str(scenario),
                           str(tmp_path / "out")], env=env, capture_output=True, text=True,
                          check=False)
    assert done.returncode == 0, done.stderr[-2000:]
    loaded = json.loads(done.stdout.splitlines()[-1])
    assert loaded and all(not versions for batch in loaded for versions in batch.values()), \
        loaded


VERSIONS = """
import json, sys
from pathlib import Path
from twin.geometry import compiled as geometry
from twin.solvers import compiled as solving
from twin.study.definition import load_study
from twin.study.trial import TrialSpec, run_batch

def versions():
    return {f"{module.__name__}.{name}": len(kernel.signatures)
            for module in (geometry, solving) for name, kernel in vars(module).items()
            if hasattr(kernel, "signatures")}
"""
"""What the scripts below share: each kernel's count of loaded versions, by name."""

SOLVE_VERSIONS = VERSIONS + """
from dataclasses import replace
import twin.calibration.pipeline as pipeline
import twin.solvers.lm as lm

def observed(solver):
    def solve(*args):
        before = versions()
        result = solver.solve(*args)
        loaded[solver.name] = sorted(k for k, v in versions().items() if v != before[k])
        return result
    return replace(solver, solve=solve)

def counted(*args):
    steps[0] += 1
    return boxed(*args)

loaded, steps, boxed, find = {}, [0], lm.boxed_damped_step, pipeline.get_solver
pipeline.get_solver = lambda name: observed(find(name))
lm.boxed_damped_step = counted
plan = load_study(Path(sys.argv[1]), trials=1)
case = plan.cases[0]
run_batch({case.label: TrialSpec(case.scenario, plan.methods, plan.workspace_poses)},
          [(case.label, 0)])
print(json.dumps({"loaded": loaded, "box_steps": steps[0]}))
"""


def _on_the_paper_rig(script: str) -> dict[str, Any]:
    """What ``script`` prints last (JSON), run in a fresh process on the paper rig's scenario
    with the kernels a study takes (no TWIN_KERNEL)."""
    pytest.importorskip("numba")
    env = {**os.environ, "PYTHONPATH": str(Path(__file__).resolve().parents[1])}
    env.pop("TWIN_KERNEL", None)
    scenario = Path(__file__).resolve().parents[1] / "scenarios" / "paper_irb120.toml"
    done = subprocess.run([sys.executable, "-c", script, str(scenario)], env=env,
                          capture_output=True, text=True, check=False)
    assert done.returncode == 0, done.stderr[-2000:]
    found: dict[str, Any] = json.loads(done.stdout.splitlines()[-1])
    return found


@pytest.mark.slow
def test_no_method_a_study_times_loads_a_kernel() -> None:
    """In a fresh process, a study's batch loads the compiled kernels before any method is
    timed (:func:`twin.solvers.compiled.load`): while each of the paper's ten methods solves
    the paper rig's first trial — LM and AMLM taking box steps, the swarms their compiled
    moves — no kernel gains a version. The first box step in each worker had cost 13–20 ms of
    LM's time, the first swarm of a run its kernels' loading (seconds on a fresh install)."""
    found = _on_the_paper_rig(SOLVE_VERSIONS)
    assert len(found["loaded"]) == 10 and found["box_steps"] > 0, found
    assert not any(found["loaded"].values()), found


LOADED_BEFORE = VERSIONS + """
from twin.geometry.kinematics import load_compiled

load_compiled()
solving.load()
before = versions()
plan = load_study(Path(sys.argv[1]), trials=1)
case = plan.cases[0]
run_batch({case.label: TrialSpec(case.scenario, plan.methods, plan.workspace_poses)},
          [(case.label, 0)])
print(json.dumps({"before": before, "after": versions()}))
"""


@pytest.mark.slow
def test_the_kernels_make_test_compiles_first_are_every_one_a_study_takes() -> None:
    """``make test`` compiles the kernels beside mypy
    (:func:`twin.geometry.kinematics.load_compiled`, :func:`twin.solvers.compiled.load`), so
    that a fresh clone's tests read them from numba's cache: in a fresh process, after those
    two, the paper rig's first trial with each of the ten methods loads no other version of
    any kernel."""
    found = _on_the_paper_rig(LOADED_BEFORE)
    entries = [f"twin.geometry.compiled.{name}" for name in (
        "positions", "jacobian", "distances", "anchored_distances", "anchored_sum_squares")] \
        + [f"twin.solvers.compiled.{name}" for name in ("box_step", "pso_candidates",
                                                        "keep_best", "curve_points")]
    assert all(found["before"][name] == 1 for name in entries), found
    assert found["after"] == found["before"], found


def test_a_run_leaves_the_commands_kernel_as_it_was(tmp_path: Path,
                                                   monkeypatch: pytest.MonkeyPatch) -> None:
    """The first trial runs in the command's process on the compiled kernel, as the workers
    do; after the run the process takes the kernel it took before, so that an API caller's
    next calibration does not depend on a study having run (BIPSO's answer differs between
    the two: docs/methods.md)."""
    pytest.importorskip("numba")
    from twin.geometry import compiled, kinematics

    if not LocalProcesses().forks:
        pytest.skip("workers are spawned here: the command's process runs no trial")
    monkeypatch.delenv("TWIN_KERNEL", raising=False)
    monkeypatch.setattr(kinematics, "_BULK", [False])
    kinematics._compiled.cache_clear()
    taken = []
    monkeypatch.setattr(compiled, "positions", lambda *args, kernel=compiled.positions:
                        taken.append(1) or kernel(*args))
    try:
        plan = load_study(write_scenario(tmp_path, with_study('trials = 2\nmethods = ["lm"]')))
        run_trials(plan, tmp_path / "out", LocalProcesses(1), stream=io.StringIO())
        assert taken and not kinematics.takes_compiled()
    finally:
        kinematics._compiled.cache_clear()


@pytest.mark.slow
def test_a_slow_first_trial_is_said_to_load_the_kernels(tmp_path: Path,
                                                        monkeypatch: pytest.MonkeyPatch) -> None:
    """While a run's first trial takes long in the command's process (numba compiling the
    kernels after an install: half a minute on 2 cores, the bar standing still), a line says
    why."""
    from twin.geometry.kinematics import bulk_work
    from twin.study import runner

    if not LocalProcesses().forks:
        pytest.skip("workers are spawned here: the command's process runs no trial")

    @contextlib.contextmanager
    def compiling() -> Iterator[None]:
        time.sleep(0.5)
        with bulk_work():
            yield

    monkeypatch.setattr(runner, "LOADING_NOTE_S", 0.05)
    monkeypatch.setattr(runner, "bulk_work", compiling)
    stream = io.StringIO()
    plan = load_study(write_scenario(tmp_path, with_study('trials = 2\nmethods = ["lm"]')))
    run_trials(plan, tmp_path / "out", LocalProcesses(1), stream=stream)
    text = stream.getvalue()
    assert text.count(runner.LOADING_NOTE) == 1
    assert text.index(runner.LOADING_NOTE) < text.index("2/2 trials")


def test_first_trial_runs_before_any_worker(tmp_path: Path) -> None:
    """Where workers are forked (Linux), the first trial of a run is recorded before a worker
    process exists (they then inherit the compiled kernel it loaded), the others by the
    workers; spawned workers run every trial."""
    plan = load_study(write_scenario(tmp_path, with_study('trials = 3\nmethods = ["lm"]')))
    children: list[int] = []

    def count(outcome: TrialOutcome) -> None:
        children.append(len(multiprocessing.active_children()))

    pool = LocalProcesses(2)
    run_trials(plan, tmp_path / "out", pool, stream=io.StringIO(), on_outcome=count)
    assert len(children) == 3
    assert (children[0] == 0) == pool.forks == sys.platform.startswith("linux")
    assert max(children) > 0


@pytest.mark.slow
def test_killed_local_worker_is_rerun(tmp_path: Path, calm: tuple[StudyPlan, Path]) -> None:
    """SIGKILL of a busy worker process breaks the pool; its batches run again on a fresh pool
    and every trial is recorded exactly once, with the same numbers as an undisturbed run."""
    plan, calm_out = calm
    killed: list[int] = []

    def kill_one(outcome: TrialOutcome) -> None:
        children = multiprocessing.active_children()
        if not killed and children:
            killed.append(children[0].pid or 0)
            os.kill(killed[0], signal.SIGKILL)

    stream = io.StringIO()
    with pytest.warns(RuntimeWarning, match="worker process died"):
        run_trials(plan, tmp_path / "killed", LocalProcesses(2), stream=stream,
                   on_outcome=kill_one)
    assert killed
    assert recorded(tmp_path / "killed") == {k: len(plan.methods) for k in range(12)}
    assert numbers(tmp_path / "killed") == numbers(calm_out)
    assert "12/12 trials" in stream.getvalue()


@pytest.mark.slow
def test_dask_local_cluster_survives_a_killed_worker(
    tmp_path: Path, calm: tuple[StudyPlan, Path], monkeypatch: pytest.MonkeyPatch
) -> None:
    """On a 2-worker LocalCluster bound to 127.0.0.1, SIGKILL of a worker that is running a
    batch gets the batch rescheduled: every trial is recorded once, with the numbers the local
    processes give for the same seeds; the scratch folders of the scheduler and of every
    worker, the killed one's too, are gone from the temporary folder when the run ends."""
    plan, calm_out = calm
    temporary = tmp_path / "tmp"
    temporary.mkdir()
    monkeypatch.setenv("TMPDIR", str(temporary))
    monkeypatch.setattr(tempfile, "tempdir", str(temporary))
    cluster = DaskCluster(workers=2)
    killed: list[str] = []

    def kill_busy(outcome: TrialOutcome) -> None:
        if killed:
            return
        client = cluster.client
        busy = [address for address, keys in client.processing().items() if keys]
        if busy:
            assert all(a.startswith("tcp://127.0.0.1:") for a in client.scheduler_info()["workers"])
            pid = client.run(os.getpid, workers=[busy[0]])[busy[0]]
            os.kill(pid, signal.SIGKILL)
            killed.append(busy[0])

    run_trials(plan, tmp_path / "dask", cluster, stream=io.StringIO(), on_outcome=kill_busy)
    assert killed
    assert recorded(tmp_path / "dask") == {k: len(plan.methods) for k in range(12)}
    assert numbers(tmp_path / "dask") == numbers(calm_out)
    assert not list(temporary.iterdir())

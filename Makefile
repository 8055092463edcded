# Two entry points: `make demo` and `make test`. Each creates .venv on first use and says what
# it installs (every extra takes about 1.7 GB in .venv, most of it Rerun and Pinocchio; the core
# install of numpy, scipy and matplotlib about 0.35 GB).
PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
DEMO := out/demo
TEST_TIME := 1 min 35 s to 4 min 45 s of pytest, 2 min 45 s to 8 min from a fresh clone (venv, install, mypy and the bytecode included)
TEST_FAST_TIME := 21 s to 58 s, 0.6 to 1.8 CPU-minutes; a fresh clone's first run also compiles numba's kernels

.PHONY: demo test test-fast lint kernels bytecode bench docs clean

$(BIN)/python:
	@echo "make: creating $(VENV) with $(PYTHON)"
	$(PYTHON) -m venv $(VENV)
	@echo "make: upgrading pip in $(VENV)"
	$(BIN)/python -m pip install --upgrade pip

$(VENV)/.installed: pyproject.toml | $(BIN)/python
	@echo "make: installing cabletwin with every extra, '.[all]' (MuJoCo, Pinocchio, Rerun, serial, Dask)"
	$(BIN)/python -m pip install -e '.[all]'
	touch $@

$(VENV)/.installed-dev: pyproject.toml | $(BIN)/python
	@echo "make: installing cabletwin with every extra and the test tools, '.[dev]'"
	$(BIN)/python -m pip install -e '.[dev]'
	touch $@ $(VENV)/.installed

# The paper's rig in the twin: simulate, then calibrate with LM (identified vs true is printed).
demo: $(VENV)/.installed
	@echo "make: simulating the paper's rig with the MuJoCo twin into $(DEMO)"
	$(BYTECODE) $(BIN)/twin simulate scenarios/paper_irb120.toml --out $(DEMO)
	@echo "make: calibrating it"
	$(BYTECODE) $(BIN)/twin calibrate $(DEMO)/capture.toml --json $(DEMO)/result.json
	@echo "paper (real IRB 120): validation RMSE 2.177 mm before -> 0.332 mm (M9), 0.372 mm (M7)"

lint: $(VENV)/.installed-dev
	@echo "make: ruff (style) and mypy (types)"
	$(BIN)/ruff check twin tests bench
	$(BIN)/mypy

# Every test on both cores (pytest-xdist). TEST_TIME and TEST_FAST_TIME were measured on a 2-core
# Intel Xeon VM (1340 and 1090 tests) on 2026-12-03 between 14:57 and 16:01 from fresh clones
# (pip's cache warm), with the bytecode written first (below): pytest 3:37, 3:45, 3:37 and 3:21,
# 5:46, 6:15, 5:55 and 5:22 in all; in one clone, side by side, 3:42 (424 CPU-s) without the bytecode and 3:11
# (358 CPU-s) with it; test-fast 42 s. That VM's speed changes by 1.8x within the hour (the same
# tree's pytest took 2 min 40 s at 12:47 and 4 min 52 s at 13:22, before the bytecode); a
# 2-core AMD EPYC VM took about 3 min 20 s and 52 s on the suite of some commits before. Three
# workers on those 2 cores took 4 min 40 s and 4 min 37 s against two's 4 min 52 s and 3 min 56 s
# (alternating, 13:13-13:34): no gain beyond the hour's drift; kept at 2, a worker per core.
# Later on 2026-12-03 (1352 tests): 3:36 and 3:43 at 16:45-17:00; at a slow hour, 4:17 at 17:40 and a
# fresh clone's 4:12 (6:45 in all) at 17:50, when the commit this day's work started from took
# 4:37 beside the new one's 4:07 (460 and 437 CPU-s): the VM's hour, not the commits;
# test-fast 58 s (110 CPU-s) at 18:00; a fresh clone's 4:43 (7:51 in all) at 18:20.
# In the evening (1352 tests): fresh clones' 3:13 (5:26 in all) at 19:24, 2:34 (4:19) at 19:38
# and 2:20 (3:47, .ci/run) at 19:42, 2:17 (3:59) at 19:47; in a worktree 4:02, 4:19 and 3:54 at
# 18:38-19:17; test-fast 45 s at 19:12. On 2026-12-04, a fast hour (1356-1358 tests): fresh
# clones' 2:20 (3:41 in all) at 16:36 and 1:52 (3:22) at 17:28; test-fast 21 s (38 CPU-s,
# 1103 tests) at 17:32; later 3:10. In the evening (1369 tests): fresh clones' 4:01 (2:21 of
# pytest, .ci/run) at 19:02 and 4:11 (2:28) at 19:07, a slow hour, when the session's first
# commit's pytest took 2:05-2:12 in a worktree beside the new one's 2:08-2:19; 3:25 (1:56) and
# 3:19 (2:00) at 19:25-19:35; test-fast 27 s at 19:20. Later (1373 tests): pytest 1:51 in a
# worktree at 20:13 and a fresh clone's 3:06 (1:56, .ci/run) at 20:16; test-fast 23 s at 20:22.
# Later still (1377-1381 tests): pytest 2:02-2:35 in worktrees at 20:40-21:03 and a fresh
# clone's 3:39 (2:14, .ci/run) at 21:20, a slow hour; test-fast 29 s (1125 tests) at 21:21.
# Later (1399 tests): a fresh clone's 3:19 (1:54 of pytest) at 22:58; test-fast 25 s (1144).
# On 2026-12-04 at 23:52 (1404 tests): a fresh clone's 3:10 (1:46 of pytest); test-fast 21 s (1146).
# On 2026-12-05 at 00:30-00:40 (1405 tests): fresh clones' 2:59 (1:40), 3:00 (1:42, .ci/run) and
# 2:58 (1:39, .ci/run), then 2:56 (1:38) at 01:00; test-fast 21 s (1147).
# At 02:30-02:37 (1407 tests): fresh clones' 2:56 (1:39) and 2:48 (1:36, .ci/run); test-fast 21 s
# (1149).
# TEST_TIME's bounds are those measured, rounded outward.
# numba compiles the kernels of the extra `fast` on their first use and caches them beside the
# sources. On a fresh clone that first use fell inside pytest: in each worker and in each study
# the tests start, some 26 s of CPU apiece. `make test` compiles them first, once, beside mypy
# (on the core it leaves idle); tests/test_study_executors.py checks that they are all a study
# takes.
kernels: $(VENV)/.installed
	@echo "make: numba's kernels, compiled once and cached (or read from the cache)"
	$(BYTECODE) $(BIN)/python -c "from twin.geometry.kinematics import load_compiled; from twin.solvers.compiled import load; load_compiled(); load()"

# Python's bytecode of the sources and of the tests as pytest rewrites them, written beside them
# (in __pycache__, where numba keeps its kernels). Where PYTHONDONTWRITEBYTECODE is set, as on
# this VM, nothing was ever written: each of the suite's ~150 processes compiled every module of
# twin it imported again (0.2-0.3 s of CPU per `twin` command) and each worker rewrote every test
# module (collecting took 10.2-10.8 s against 5.7-6.7 s, three runs each, alternating). Python
# reads bytecode that exists whatever that variable says; `make test` writes it first, beside
# mypy (11.6 s on a fresh clone), and the tests' runs write what is left; `make demo`'s commands
# write theirs too (a repeated demo took 2.06-2.39 s with them against 2.47-3.16 s without).
BYTECODE := PYTHONDONTWRITEBYTECODE=
bytecode: $(VENV)/.installed-dev
	@echo "make: Python's bytecode of twin and of the tests (as pytest rewrites them)"
	$(BYTECODE) $(BIN)/python -m compileall -q twin
	$(BYTECODE) $(BIN)/python -m pytest --collect-only -p no:cacheprovider > /dev/null

test: $(VENV)/.installed-dev
	@$(MAKE) --no-print-directory bytecode kernels & warm=$$!; \
	  $(MAKE) --no-print-directory lint; lint=$$?; wait $$warm && exit $$lint
	@echo "make: pytest on 2 workers ($(TEST_TIME))"
	$(BYTECODE) $(BIN)/python -m pytest -n 2 --dist worksteal

# The inner loop: every test not marked slow, each of which took under half a second on this
# 2-core VM at a slow hour (no study, capture or benchmark).
test-fast: $(VENV)/.installed-dev
	@echo "make: pytest -m 'not slow' on 2 workers ($(TEST_FAST_TIME))"
	$(BYTECODE) $(BIN)/python -m pytest -n 2 --dist worksteal -m "not slow"

# The speed goals side by side (bench/bench_speed.py), then every other benchmark.
bench: $(VENV)/.installed-dev
	for script in bench/bench_*.py; do $(BIN)/python $$script || exit 1; done

# Every table of figures in docs/methods.md and docs/studies.md, from fresh runs (~10 min).
docs: $(VENV)/.installed-dev
	$(BIN)/python bench/docs_tables.py

clean:
	rm -rf $(VENV) out .pytest_cache .mypy_cache .ruff_cache

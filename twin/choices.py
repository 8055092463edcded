"""The names and limits a user chooses among — stopping protocols, losses, sizes, tolerances,
units, program defaults — in one module that imports nothing.

The command line shows them in its help and checks its flags against them before any command
runs; keeping them here, free of numpy, is what lets ``twin CMD --help`` answer at once. The
module that acts on each value imports it from here (and is where its meaning is described).
"""

from __future__ import annotations

MIN_JOINTS, MAX_JOINTS = 4, 9
"""Joints a robot may have (:class:`twin.robot.RobotModel`, every robot file, plan and journal):
the serial chains twin calibrates, from a SCARA-like 4-axis arm to a 7-axis arm on a torso lift
or a two-axis track — the one place this limit is set."""
JOINT_RANGE = f"{MIN_JOINTS} to {MAX_JOINTS}"
"""The limit as help texts and messages say it."""
DEFAULT_METHOD = "lm"
"""The method `twin calibrate` and `twin identify` run unless told (:mod:`twin.solvers`): one
method by default, so that both state the same fit and the same noise estimate."""
PROTOCOLS = ("converge", "paper")
"""Names of the stopping protocols, the default first (:mod:`twin.stopping`)."""
MAX_ITERATIONS = 100_000
"""The largest iteration limit a file or flag may ask for."""
LOSSES = ("linear", "huber", "soft_l1", "cauchy")
"""The losses, least squares first (:mod:`twin.loss`)."""
DEFAULT_SCALE_SIGMAS = 3.0
"""Without a stated scale, the loss scale is this many times the stated noise σ."""
MAX_POSES = 100_000
"""The most poses a plan, a scenario or a verification may ask for: a typo like 1e9 must be an
error, not an exhausted memory."""
MAX_TRIALS = 100_000
"""Most trials per case, from ``[study] trials`` as from ``--trials``."""
DEFAULT_TOLERANCE = 0.05
"""Relative worsening below which a significant change is not a regression (5 %,
:mod:`twin.study.baseline`)."""
MAX_TOLERANCE = 1.0
"""Largest relative worsening a tolerance may allow (100 %: a metric twice as bad); beyond it
no change is a regression and the comparison can never fail."""
ANGLE_UNITS = ("rad", "deg")
"""Units of the joint angles of another tool's CSV (:mod:`twin.io.importers.csv_files`)."""
LENGTH_UNITS = ("m", "mm")
"""Units of its lengths and positions."""
SESSION_BY = ("folder", "file")
"""What `twin import --session-by` names a row's session after: its file's folder, or its
file."""
DEFAULT_SPEED = "v100"
"""The speeddata of a RAPID plan's moves (:mod:`twin.io.rapid_plan`)."""
DEFAULT_SETTLE_S = 0.5
"""The pause of a RAPID plan at each pose before the reading, s."""
DEFAULT_SIGMA_MM = 0.01
"""The noise 1σ of a reading when none is stated, mm: a 0.01 mm class instrument."""
DEFAULT_SIGMA_DEG = 0.01
"""The noise 1σ of an angle read when none is stated, degrees: a 6-DoF tracker probe's class."""
MAX_TENSION_N = 1000.0
"""Largest cable tension accepted, N: drawstring springs pull a few newtons; a kilonewton would
bend an IRB 120 rather than load it."""
QUANTITY_UNITS = ("mm", "m", "deg", "rad", "arcsec", "urad/Nm", "µrad/(N·m)", "um/N", "µm/N",
                  "um/m", "µm/m", "ppm")
"""The units a value typed with its number may carry (``--bounds a2=20mm``;
:data:`twin.units.QUANTITY_UNITS` converts them)."""
MIN_FOLDS = 2
MAX_FOLDS = 1000
"""The fewest and most folds of a cross-validation (:mod:`twin.calibration.crossval`)."""
KERNEL_VARIABLE = "TWIN_KERNEL"
"""Environment variable choosing the kernel, one of :data:`KERNELS`: ``numpy``, ``numba`` (the
compiled one, :mod:`twin.geometry.compiled`; numba from the extra ``fast``), or ``auto`` (the
default): the compiled one in a process that declared bulk work
(:func:`twin.geometry.kinematics.for_bulk_work`) when numba is installed, numpy elsewhere.
Every command checks it before it runs (:func:`twin.distribution.kernel_choice`)."""
KERNELS = ("auto", "numba", "numpy")
"""The kernels :data:`KERNEL_VARIABLE` may name, the default first."""

"""The layout the viewer opens on: 3D scene and residuals, convergence, parameter bars, report.

The 3D scene and the residuals live on the ``pose`` timeline, the convergence plots on the
``iteration`` timeline: the viewer shows one timeline at a time, so the blueprint opens on
``pose`` and the convergence tab says to switch. Bars and report are static and always shown.
"""

from __future__ import annotations

from collections.abc import Sequence

import rerun.blueprint as rrb

from twin.units import DH_KEYS, display_unit
from twin.viz import entities

EYE_POSITION_M = (1.0, -1.1, 0.8)
"""Where the 3D view's camera starts, base frame, m: in front of the arm, beside the port."""
EYE_TARGET_M = (0.3, -0.15, 0.3)
"""What the camera looks at, base frame, m: the middle of the IRB 120's workspace."""


def _scene_view() -> rrb.Spatial3DView:
    return rrb.Spatial3DView(
        name="Robot, port and cable per pose",
        origin=entities.WORLD,
        eye_controls=rrb.EyeControls3D(position=EYE_POSITION_M, look_target=EYE_TARGET_M,
                                       eye_up=(0.0, 0.0, 1.0)),
    )


def _panels() -> tuple[rrb.BlueprintPart, ...]:
    """Side panels folded away so the views get the room; the compact timeline on ``pose``."""
    return (
        rrb.BlueprintPanel(state="collapsed"),
        rrb.SelectionPanel(state="collapsed"),
        rrb.TimePanel(timeline=entities.POSE_TIMELINE, state="collapsed"),
    )


def _parameter_view(key: str, methods: Sequence[str], has_truth: bool) -> rrb.BarChartView:
    sources: list[str | None] = [None] if has_truth else []
    sources += list(methods)
    unit = "deg" if key == "beta" else display_unit(key)
    return rrb.BarChartView(
        name=f"δ{key} [{unit}] per joint",
        origin=entities.PARAMETERS,
        contents=[f"+ /{entities.parameter_bars(source, key)}" for source in sources],
    )


def _convergence_view(name: str, quantities: Sequence[str], methods: Sequence[str]) -> rrb.View:
    return rrb.TimeSeriesView(
        name=name,
        origin=entities.CONVERGENCE,
        contents=[f"+ /{entities.convergence(m, q)}" for m in methods for q in quantities],
    )


def calibration_blueprint(methods: Sequence[str], has_truth: bool,
                          keys: Sequence[str] = DH_KEYS) -> rrb.Blueprint:
    """The default layout of a calibration recording.

    Args:
        methods: The methods logged, in order.
        has_truth: Whether ``parameters/true`` and ``world/robot/true`` are logged.
        keys: The parameter rows shown (:func:`twin.viz.calibration_log.bar_keys`).
    """
    scene = rrb.Vertical(
        _scene_view(),
        rrb.TimeSeriesView(name="Residual per pose [mm]", origin=entities.RESIDUALS),
        row_shares=[3, 2],
    )
    convergence = rrb.Tabs(
        _convergence_view("f [mm²] (iteration timeline)", ["f"], methods),
        _convergence_view("RMSE [mm] (iteration timeline)", ["train_rmse", "validation_rmse"],
                          methods),
        name="Convergence",
    )
    parameters = rrb.Grid(
        *(_parameter_view(key, methods, has_truth) for key in keys), grid_columns=2,
        name="Table errors",
    )
    report = rrb.TextDocumentView(name="Report", origin=entities.REPORT)
    return rrb.Blueprint(
        rrb.Horizontal(
            scene,
            rrb.Vertical(convergence, parameters, report, row_shares=[2, 3, 2]),
            column_shares=[3, 2],
        ),
        *_panels(),
    )


def scene_blueprint() -> rrb.Blueprint:
    """The default layout of a recording of measurements only (`twin simulate`)."""
    return rrb.Blueprint(
        rrb.Horizontal(
            _scene_view(),
            rrb.TextDocumentView(name="Report", origin=entities.REPORT),
            column_shares=[3, 1],
        ),
        *_panels(),
    )

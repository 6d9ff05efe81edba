"""The default layout: the 3D view framed on the robot beside the verdict, plots in tabs below (one plot per joint
group and quantity, legends hidden: a line's name shows on hover; none without data), the time panel on `sim_time`
(`tests/test_rerun_recording.py::test_default_blueprint_pins_sim_time_and_separates_units`,
`tests/test_rerun_recording.py::test_every_plot_the_blueprint_opens_has_data`).

One time range for every view: the plots show, and the time panel plays on a loop, the span of the rollout the 3D
view plays. A tier's series can run longer than that rollout (the contact tier's horizon is longer than the PD
rollout's); showing and playing the whole timeline would leave the robot standing still for the rest of the
playback while the cursor runs on through the plots. The longer series' tail stays in the recording (widen a plot's
time range to see it) and its maximum is in the verdict
(`tests/test_rerun_recording.py::test_every_view_shows_the_span_the_robot_moves_in`).

Readable at a laptop's width: the verdict panel takes half the top row, and a tab of plots has at most GRID_COLUMNS
plots a row, so that a plot's title is not cut
(`tests/test_rerun_recording.py::test_the_verdict_table_and_plot_titles_fit_their_panels`)."""

from __future__ import annotations

from dataclasses import dataclass, field

import rerun as rr
import rerun.blueprint as rrb

from .paths import part
from .timeline import TIMELINE

GRID_COLUMNS = 4  # plots a row in a tab; even, so an actuator group's ctrl and force plots share a row
TOP_SHARES = [1, 1]  # the 3D view and the verdict panel


@dataclass
class Layout:
    """What was logged, so the blueprint names only views that have data."""

    title: str
    eye: rrb.EyeControls3D | None = None
    span: float | None = None  # seconds the 3D view moves over (its rollout's last sample); None for a still scene
    groups: list[str] = field(default_factory=list)  # joint group names (unescaped)
    positioned: list[str] = field(default_factory=list)  # the groups with position plots (not only ball joints)
    commanded: list[str] = field(default_factory=list)
    actuated: dict[str, list[str]] = field(default_factory=dict)  # tier -> actuator groups
    raw_series: bool = False


def _visible(span: float | None) -> rrb.VisibleTimeRange | None:
    """The range of `sim_time` a plot shows: from 0 to the end of the 3D view's rollout."""
    if span is None:
        return None
    return rrb.VisibleTimeRange(
        TIMELINE, start=rrb.TimeRangeBoundary.absolute(seconds=0.0), end=rrb.TimeRangeBoundary.absolute(seconds=span)
    )


def _plot(name: str, origin: str, span: float | None) -> rrb.TimeSeriesView:
    return rrb.TimeSeriesView(
        name=name, origin=origin, plot_legend=rrb.PlotLegend(visible=False), time_ranges=_visible(span)
    )


def _grid(name: str, views: list[rrb.TimeSeriesView]) -> rrb.Grid:
    return rrb.Grid(*views, name=name, grid_columns=min(GRID_COLUMNS, max(len(views), 1)))


def _tabs(layout: Layout) -> list:
    span = layout.span
    tabs: list = [_plot("tier error / tolerance (1 = tolerance)", "/tiers", span)]
    if layout.groups:
        positions = [_plot(f"{g}: position (rad or m)", f"/joints/{part(g)}/position", span) for g in layout.positioned]
        tabs.append(_grid("joint positions", positions))
        differences = [
            _plot(f"{g}: SAPIEN - MuJoCo (rad or m)", f"/joints/{part(g)}/difference", span) for g in layout.groups
        ]
        tabs.append(_grid("joint differences", differences))
    if layout.commanded:
        commands = [_plot(f"{g}: command (N m or N)", f"/commands/{part(g)}", span) for g in layout.commanded]
        tabs.append(_grid("commands", commands))
    for tier, groups in layout.actuated.items():
        views = [
            _plot(f"{g}: {what}", f"/actuators/{part(tier)}/{part(g)}/{entity}", span)
            for g in groups
            for what, entity in (("ctrl", "ctrl"), ("actuator force (N m or N)", "force"))
        ]
        tabs.append(_grid(f"{tier} actuators", views))
    if layout.raw_series:
        tabs.append(_plot("series without a tolerance", "/tier_series", span))
    return tabs


def _time_panel(span: float | None) -> rrb.TimePanel:
    """On `sim_time`; with a rollout, its span selected and played on a loop."""
    if span is None:
        return rrb.TimePanel(timeline=TIMELINE, state="collapsed")
    selection = rrb.components.AbsoluteTimeRange(rr.TimeInt(seconds=0.0), rr.TimeInt(seconds=span))
    return rrb.TimePanel(timeline=TIMELINE, state="collapsed", time_selection=selection, loop_mode="selection")


def blueprint(layout: Layout) -> rrb.Blueprint:
    return rrb.Blueprint(
        rrb.Vertical(
            rrb.Horizontal(
                rrb.Spatial3DView(
                    name=layout.title,
                    origin="/",
                    eye_controls=layout.eye,
                    contents=["+ /mujoco/**", "+ /sapien/**", "+ /deviation"],
                ),
                rrb.TextDocumentView(name="verdict", origin="/verdict"),
                column_shares=TOP_SHARES,
            ),
            rrb.Tabs(*_tabs(layout)),
            row_shares=[3, 2],
        ),
        _time_panel(layout.span),
        rrb.BlueprintPanel(state="collapsed"),
        rrb.SelectionPanel(state="collapsed"),
    )

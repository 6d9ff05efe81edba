"""The default layout: the 3D view framed on the robot beside the verdict, plots in tabs below (one plot per joint
group and quantity, legends hidden: a line's name shows on hover; none without data), the time panel on `sim_time`
(`test_rerun_recording.py::test_default_blueprint_pins_sim_time_and_separates_units`,
`test_rerun_recording.py::test_every_plot_the_blueprint_opens_has_data`)."""

from __future__ import annotations

from dataclasses import dataclass, field

import rerun.blueprint as rrb

from .paths import part
from .timeline import TIMELINE


@dataclass
class Layout:
    """What was logged, so the blueprint names only views that have data."""

    title: str
    eye: rrb.EyeControls3D | None = None
    groups: list[str] = field(default_factory=list)  # joint group names (unescaped)
    positioned: list[str] = field(default_factory=list)  # the groups with position plots (not only ball joints)
    commanded: list[str] = field(default_factory=list)
    actuated: dict[str, list[str]] = field(default_factory=dict)  # tier -> actuator groups
    raw_series: bool = False


def _plot(name: str, origin: str) -> rrb.TimeSeriesView:
    return rrb.TimeSeriesView(name=name, origin=origin, plot_legend=rrb.PlotLegend(visible=False))


def blueprint(layout: Layout) -> rrb.Blueprint:
    tabs = [_plot("tier error / tolerance (1 = tolerance)", "/tiers")]
    if layout.groups:
        tabs.append(
            rrb.Grid(
                *[_plot(f"{g}: position (rad or m)", f"/joints/{part(g)}/position") for g in layout.positioned],
                name="joint positions",
            )
        )
        tabs.append(
            rrb.Grid(
                *[_plot(f"{g}: SAPIEN - MuJoCo (rad or m)", f"/joints/{part(g)}/difference") for g in layout.groups],
                name="joint differences",
            )
        )
    if layout.commanded:
        tabs.append(
            rrb.Grid(
                *[_plot(f"{g}: command (N m or N)", f"/commands/{part(g)}") for g in layout.commanded], name="commands"
            )
        )
    for tier, groups in layout.actuated.items():
        views = [
            _plot(f"{g}: {what}", f"/actuators/{part(tier)}/{part(g)}/{entity}")
            for g in groups
            for what, entity in (("ctrl", "ctrl"), ("actuator force (N m or N)", "force"))
        ]
        tabs.append(rrb.Grid(*views, name=f"{tier} actuators"))
    if layout.raw_series:
        tabs.append(_plot("series without a tolerance", "/tier_series"))
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
                column_shares=[3, 2],
            ),
            rrb.Tabs(*tabs),
            row_shares=[3, 2],
        ),
        rrb.TimePanel(timeline=TIMELINE, state="collapsed"),
        rrb.BlueprintPanel(state="collapsed"),
        rrb.SelectionPanel(state="collapsed"),
    )

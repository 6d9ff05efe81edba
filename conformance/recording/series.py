"""Time series, one `Scalars` batch per plot with a `SeriesLines` name per line
(`test_rerun_recording.py::test_joint_series_are_grouped_batches_in_both_colours`).

Joints are grouped by limb (`joint_groups`), at most GROUP_SIZE joints a plot, actuators with their joints, and
each quantity has its own plots because its unit differs: positions (rad or m, MuJoCo in grey and SAPIEN in orange
as in the 3D view), SAPIEN - MuJoCo, commands (N m or N), actuator ctrl and actuator forces. A tier's error is
plotted divided by its metric's tolerance, so 1 is the tolerance whatever the unit."""

from __future__ import annotations

import itertools

import mujoco
import numpy as np
import rerun as rr

from ..report import ActuatorTrace, Metric, TierReport, Trace
from .geometry import MUJOCO_COLOR, SAPIEN_COLOR
from .paths import name_of, part
from .timeline import strided, times

GROUP_SIZE = 8  # joints in one plot: more lines than this are no longer told apart
TOLERANCE_COLOR = [200, 0, 0, 255]
_NQ = {0: 7, 1: 4}  # free, ball; hinge and slide have one
_NV = {0: 6, 1: 3}


def _tree(model: mujoco.MjModel) -> tuple[dict[int, list[int]], dict[int, list[int]]]:
    """Children per body and joints per body."""
    children: dict[int, list[int]] = {}
    for b in range(1, model.nbody):
        children.setdefault(int(model.body_parentid[b]), []).append(b)
    joints: dict[int, list[int]] = {}
    for j in range(model.njnt):
        joints.setdefault(int(model.jnt_bodyid[j]), []).append(j)
    return children, joints


def joint_groups(model: mujoco.MjModel) -> list[tuple[str, list[int]]]:
    """(group name, joints): a subtree of at most GROUP_SIZE joints is one group (a finger, a leg); a larger one
    gives its chain down to the first branching as one group (split evenly into plots of at most GROUP_SIZE) and
    recurses into the branches. A group is named after the bodies that carry its joints (`group_name`), so the
    name says which part of the robot it is, not only where its subtree starts
    (`tests/test_rerun_recording.py::test_groups_are_named_after_the_bodies_they_span`)."""
    children, joints = _tree(model)

    def count(b: int) -> int:
        return len(joints.get(b, [])) + sum(count(c) for c in children.get(b, []))

    out: list[list[int]] = []

    def visit(b: int) -> None:
        if count(b) <= GROUP_SIZE:
            subtree, stack = [], [b]
            while stack:
                body = stack.pop()
                subtree += joints.get(body, [])
                stack += reversed(children.get(body, []))
            if subtree:
                out.append(sorted(subtree))
            return
        chain, body = list(joints.get(b, [])), b
        while len(children.get(body, [])) == 1:
            body = children[body][0]
            chain += joints.get(body, [])
        out.extend(_pieces(chain) if chain else [])
        for child in children.get(body, []):
            visit(child)

    for root in children.get(0, []):
        visit(root)
    return [(group_name(model, members), members) for members in out]


def _lineage(model: mujoco.MjModel, b: int) -> list[int]:
    """b and its ancestors up to the world, deepest first."""
    out = [b]
    while out[-1] != 0:
        out.append(int(model.body_parentid[out[-1]]))
    return out


def group_name(model: mujoco.MjModel, joints: list[int]) -> str:
    """The bodies carrying `joints`: one body by its name, a path down the tree as `<first> to <last>` (an arm's
    `link1 to link7`), a branching subtree as `<its top> and its <n> branches` (a gripper's fingers)."""
    bodies = sorted({int(model.jnt_bodyid[j]) for j in joints})  # MuJoCo numbers a parent before its children

    def name(b: int) -> str:
        return name_of(model, mujoco.mjtObj.mjOBJ_BODY, b, "body")

    if len(bodies) == 1:
        return name(bodies[0])
    lineages = {b: _lineage(model, b) for b in bodies}
    if all(a in lineages[b] for a, b in itertools.pairwise(bodies)):
        return f"{name(bodies[0])} to {name(bodies[-1])}"
    top = max(set.intersection(*(set(line) for line in lineages.values())))
    leaves = [b for b in bodies if not any(b in lineages[other] for other in bodies if other != b)]
    return f"{name(top)} and its {len(leaves)} branches"


def _columns(model: mujoco.MjModel, joints: list[int], adr, count, labels=("x", "y", "z", "rx", "ry", "rz")):
    """(indices, names) of a group's coordinates: one per hinge/slide, a free joint's first three, none for a
    ball's quaternion (`count` says how many of a joint's entries to take)."""
    index, names = [], []
    for j in joints:
        name = name_of(model, mujoco.mjtObj.mjOBJ_JOINT, j, "joint")
        n = count(int(model.jnt_type[j]))
        index += range(int(adr[j]), int(adr[j]) + n)
        names += [name] if n == 1 else [f"{name} {labels[i]}" for i in range(n)]
    return index, names


def _plot(rec, path: str, index_columns, values: np.ndarray, names: list[str], colors=None) -> None:
    rec.log(path, rr.SeriesLines(names=names, colors=colors), static=True)
    rec.send_columns(
        path,
        indexes=index_columns,
        columns=rr.Scalars.columns(scalars=np.asarray(values, dtype=float)).partition(
            [values.shape[1]] * values.shape[0]
        ),
    )


def _plot_both(rec, path: str, index_columns, mujoco_values, sapien_values, names: list[str]) -> None:
    """One plot of the same quantity on both sides: MuJoCo's lines then SAPIEN's, each named and in its colour."""
    values = np.concatenate([mujoco_values, sapien_values], axis=1)
    labels = [f"MuJoCo {n}" for n in names] + [f"SAPIEN {n}" for n in names]
    _plot(rec, path, index_columns, values, labels, [MUJOCO_COLOR] * len(names) + [SAPIEN_COLOR] * len(names))


def log_joints(rec: rr.RecordingStream, model: mujoco.MjModel, trace: Trace) -> tuple[list[str], list[str], list[str]]:
    """Per joint group: positions of both sides (none for ball joints), SAPIEN - MuJoCo per DoF, and the command
    when there is one. Returns the groups, those with positions and those with a command."""
    idx = times(trace.time)
    groups, positioned, commanded = joint_groups(model), [], []
    positions = lambda kind: 3 if kind == 0 else 0 if kind == 1 else 1
    for name, joints in groups:
        group = part(name)
        q, names = _columns(model, joints, model.jnt_qposadr, positions)
        if q:
            _plot_both(rec, f"joints/{group}/position", idx, trace.mujoco_qpos[:, q], trace.sapien_qpos[:, q], names)
            positioned.append(name)
        dof, names = _columns(model, joints, model.jnt_dofadr, lambda kind: _NV.get(kind, 1))
        _plot(rec, f"joints/{group}/difference", idx, trace.qpos_error[:, dof], names)
        if np.any(trace.command[:, dof]):
            _plot(rec, f"commands/{group}", idx, trace.command[:, dof], names)
            commanded.append(name)
    return [g for g, _ in groups], positioned, commanded


def _pieces(members: list[int]) -> list[list[int]]:
    """`members` split evenly into pieces of at most GROUP_SIZE."""
    return [[int(i) for i in p] for p in np.array_split(members, -(-len(members) // GROUP_SIZE))]


def _split(name: str, members: list[int]) -> list[tuple[str, list[int]]]:
    """One group, split evenly into plots of at most GROUP_SIZE, numbered when split."""
    pieces = _pieces(members)
    return [(name if len(pieces) == 1 else f"{name} {k + 1}", p) for k, p in enumerate(pieces)]


def _transmission(model: mujoco.MjModel, a: int) -> str:
    """The group of an actuator on no joint, named after what drives it: `tendon actuators`, `site actuators`,
    `body actuators`, ...; `actuators unknown to MuJoCo` for a name the model lacks."""
    if a < 0:
        return "actuators unknown to MuJoCo"
    kind = mujoco.mjtTrn(int(model.actuator_trntype[a])).name.removeprefix("mjTRN_").lower()
    return f"{kind} actuators"


def actuator_groups(model: mujoco.MjModel, names: list[str]) -> list[tuple[str, list[int]]]:
    """(group name, rows of `names`): an actuator on a joint goes with its joint's group (`joint_groups`), others
    into a group per transmission kind (`_transmission`), so no group is an unnamed `other`
    (`tests/test_rerun_recording.py::test_groups_are_named_after_the_bodies_they_span`)."""
    of_joint = {j: g for g, joints in joint_groups(model) for j in joints}
    on_joint = (int(mujoco.mjtTrn.mjTRN_JOINT), int(mujoco.mjtTrn.mjTRN_JOINTINPARENT))
    groups: dict[str, list[int]] = {}
    for row, name in enumerate(names):
        a = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_ACTUATOR, name) if name else -1
        if a < 0 and len(names) == model.nu:
            a = row
        joint = int(model.actuator_trnid[a, 0]) if a >= 0 and int(model.actuator_trntype[a]) in on_joint else -1
        group = of_joint[joint] if joint in of_joint else _transmission(model, a)
        groups.setdefault(group, []).append(row)
    return [piece for name, rows in groups.items() for piece in _split(name, rows)]


def log_actuators(
    rec: rr.RecordingStream, model: mujoco.MjModel, reports: dict[str, TierReport]
) -> dict[str, list[str]]:
    """Per actuated tier and actuator group: the ctrl (as MuJoCo clamps it) and both sides' actuator force.
    Returns the groups per tier."""
    logged: dict[str, list[str]] = {}
    for tier, report in reports.items():
        trace: ActuatorTrace | None = report.actuators
        if trace is None or not trace.names:
            continue
        idx = times(trace.time)
        names = [name or f"actuator{a}" for a, name in enumerate(trace.names)]
        for group, rows in actuator_groups(model, trace.names):
            base, label = f"actuators/{part(tier)}/{part(group)}", [names[r] for r in rows]
            _plot(rec, f"{base}/ctrl", idx, np.asarray(trace.ctrl, dtype=float)[:, rows], label)
            _plot_both(rec, f"{base}/force", idx, trace.mujoco_force[:, rows], trace.sapien_force[:, rows], label)
            logged.setdefault(tier, []).append(group)
    return logged


def _metric_of(series: str, metrics: dict[str, Metric]) -> Metric | None:
    """The metric a series measures: the one of its name, or whose name it extends (`position` for
    `position_error_per_configuration`)."""
    named = [m for name, m in metrics.items() if series == name or series.startswith(name + "_")]
    return max(named, key=lambda m: len(m.name), default=None)


def _batches(reports: dict[str, TierReport], every: int) -> dict[tuple[str, str, int], list[tuple[str, np.ndarray]]]:
    """Tier series batched by (root, tier, stride) with their line labels: `tiers` holds errors over their
    metric's tolerance, `tier_series` series with no metric (MuJoCo's own chaos amplification), as measured.
    Kinematics' stride 0 stands for its configuration timeline."""
    out: dict[tuple[str, str, int], list[tuple[str, np.ndarray]]] = {}
    for tier, report in reports.items():
        metrics = {m.name: m for m in report.metrics}
        for name, values in report.series.items():
            values = np.asarray(values, dtype=float)
            stride = (
                0
                if tier == "kinematics"
                else int(report.settings.get("one_step_every", every))
                if name.startswith("one_step")
                else 1
            )
            m = _metric_of(name, metrics)
            if m is not None and m.tolerance > 0:
                key, label, values = (
                    ("tiers", tier, stride),
                    f"{tier} {name} / {m.tolerance:g} {m.unit}",
                    values / m.tolerance,
                )
            else:
                key, label = ("tier_series", tier, stride), f"{tier} {name}"
            out.setdefault(key, []).append((label, values))
    return out


def log_tiers(rec: rr.RecordingStream, reports: dict[str, TierReport], dt: float, every: int) -> bool:
    """Each tier's series, one batch per tier and sampling (`tiers/<tier>/every_<k>_steps`; a shorter series is
    padded with NaN, which draws nothing), and the line at 1. Returns whether a series without a tolerance was
    logged."""
    last = 0
    batches = _batches(reports, every)
    for (root, tier, stride), lines in batches.items():
        length = max(v.size for _, v in lines)
        values = np.full((length, len(lines)), np.nan)
        for k, (_, v) in enumerate(lines):
            values[: v.size, k] = v
        if stride == 0:
            path, idx = f"{root}/{tier}/per_configuration", [rr.TimeColumn("configuration", sequence=np.arange(length))]
        else:
            path, idx = f"{root}/{tier}/every_{stride}_steps", strided(length, stride, dt)
            last = max(last, (length - 1) * stride)
        _plot(rec, path, idx, values, [label for label, _ in lines])
    if last:
        rec.log("tiers/tolerance", rr.SeriesLines(names=["tolerance"], colors=[TOLERANCE_COLOR]), static=True)
        rec.send_columns(
            "tiers/tolerance", indexes=strided(2, last, dt), columns=rr.Scalars.columns(scalars=[1.0, 1.0])
        )
    return any(root == "tier_series" for root, _, _ in batches)

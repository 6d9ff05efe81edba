"""Model features outside what this loader maps, found in the compiled model and named one by one."""

from __future__ import annotations

import mujoco

from .contact import contacts_disabled
from .errors import Notes
from .joint import limits_disabled


def _name(obj, index: int, kind: str) -> str:
    return obj.name or f"{kind}{index}"


def find_unmapped(model: mujoco.MjModel, notes: Notes) -> None:
    for i in range(model.nu):
        notes.drop("actuator", _name(model.actuator(i), i, "actuator"),
                   "actuators are not mapped yet: apply joint forces with set_qf")
    for i in range(model.ntendon):
        notes.drop("tendon", _name(model.tendon(i), i, "tendon"), "tendons are not mapped yet")
    for i in range(model.neq):
        notes.drop("equality", _name(model.equality(i), i, "equality"), "equality constraints are not mapped yet")
    for i in range(model.nflex):
        notes.drop("flex", f"flex{i}", "deformable (flex) objects have no PhysX articulation equivalent")
    for i in range(model.nplugin):
        notes.drop("plugin", f"plugin{i}", "engine plugins (sdf, elasticity, ...) cannot run inside PhysX")
    for i in range(model.npair):
        notes.drop("contact pair", _name(model.pair(i), i, "pair"),
                   "explicit <pair> contacts (which bypass the contype/conaffinity filter) are not mapped")
    for b in range(model.nbody):
        if model.body_mocapid[b] >= 0:
            notes.approximate("body", _name(model.body(b), b, "body"),
                              "mocap body loaded as a fixed link at its initial pose")
    if contacts_disabled(model):
        notes.approximate("option", "flag contact", "contacts disabled in the model: every shape's groups are 0")
    if limits_disabled(model):
        notes.approximate("option", "flag limit", "limits disabled in the model: every joint is unlimited")

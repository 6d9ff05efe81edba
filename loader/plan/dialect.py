"""ManiSkill's MJCF dialect: what ManiSkill's own loader accepts and MuJoCo rejects, so that a file written for it
loads here too, where the loader is asked to (`MJCFLoader.maniskill_dialect`, which the ManiSkill drop-in sets).
Only a document MuJoCo has rejected is read again; one MuJoCo compiles never comes here, and without the dialect
MuJoCo's rejection stands.

- `<joint type="fixed"/>` (the hopper of ManiSkill's control tasks): no joint in MuJoCo's terms, the body welded to
  its parent, as ManiSkill's loader builds it. The element is removed from the document before MuJoCo parses it
  again; its includes are read from their own files (by absolute path), so a fixed joint inside an included file
  stays MuJoCo's error.
- A sensor on an object the document never defines (the same hopper's touch sensors): ManiSkill's loader reads no
  sensor, and neither does this one; the sensor is removed from the spec before MuJoCo compiles it again.

Each removal is a note of the load (tests/test_maniskill_dialect.py).
"""

from __future__ import annotations

import re
from pathlib import Path
from xml.etree import ElementTree

import mujoco

from ..errors import Notes

FIXED_JOINT = "invalid keyword: 'fixed'"
_SENSOR_TARGET = re.compile(r"unrecognized name '([^']*)' of sensorized object")


def without_fixed_joints(path: Path, notes: Notes) -> mujoco.MjSpec:
    """The document at `path` parsed by MuJoCo with its `<joint type="fixed"/>` elements removed (each noted); its
    files (includes, meshes, textures) found where the document's own would be."""
    root = ElementTree.parse(path).getroot()
    for parent in root.iter():
        for child in list(parent):
            if child.tag == "joint" and child.get("type") == "fixed":
                parent.remove(child)
                notes.approximate(
                    "joint",
                    child.get("name", ""),
                    'ManiSkill\'s type="fixed": the body welded to its parent (MuJoCo has no fixed joint)',
                )
    for include in root.iter("include"):
        include.set("file", str(path.parent / include.get("file", "")))
    spec = mujoco.MjSpec.from_string(ElementTree.tostring(root, encoding="unicode"))
    spec.modelfiledir = str(path.parent)
    return spec


def missing_sensor_target(message: str) -> str | None:
    """The object name of MuJoCo's "unrecognized name ... of sensorized object" rejection, or None."""
    found = _SENSOR_TARGET.search(message)
    return found.group(1) if found else None


def drop_sensors_on(spec: mujoco.MjSpec, target: str, notes: Notes) -> bool:
    """Remove the sensors on the undefined object `target` (each noted); whether any was."""
    dropped = [sensor for sensor in spec.sensors if sensor.objname == target]
    for sensor in dropped:
        notes.drop("sensor", sensor.name, f"its object '{target}' is not in the document (no sensor is mapped)")
        spec.delete(sensor)
    return bool(dropped)

"""Entity paths: MuJoCo bodies under `mujoco/body`, SAPIEN links under `sapien/link/<articulation>`."""

from __future__ import annotations

import mujoco
import rerun as rr


def part(name: str) -> str:
    return rr.escape_entity_path_part(name)


def name_of(model: mujoco.MjModel, kind, i: int, fallback: str) -> str:
    return mujoco.mj_id2name(model, kind, i) or f"{fallback}{i}"


def body_path(model: mujoco.MjModel, b: int) -> str:
    return f"mujoco/body/{part(name_of(model, mujoco.mjtObj.mjOBJ_BODY, b, 'body'))}"


def link_path(a: int, link) -> str:
    return f"sapien/link/{a}/{part(link.name)}"

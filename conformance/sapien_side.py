"""Read the built SAPIEN scene through the loader's mapping: link poses, shapes, state and commands."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import sapien

NAN_POSE = np.full(7, np.nan)


@dataclass
class Run:
    """A SAPIEN rollout in MuJoCo's layout: qpos (T+1, nq), qvel (T+1, nv), every link's world pose (T+1, L, 7),
    and for ctrl rollouts the actuator force law on SAPIEN's state (T, nu)."""

    qpos: np.ndarray
    qvel: np.ndarray
    link_pose: np.ndarray
    force: np.ndarray | None = None


def rollout(result, qpos0, qvel0, steps: int, before_step: Callable[[int, np.ndarray, np.ndarray], None]) -> Run:
    """Step SAPIEN `steps` times from (qpos0, qvel0), calling `before_step(t, qpos, qvel)` with the state read back
    before each step (it writes the step's command); records the state and every link's pose after each step."""
    set_state(result, qpos0, qvel0)
    q, v = get_state(result)
    qpos, qvel = np.zeros((steps + 1, q.size)), np.zeros((steps + 1, v.size))
    read_poses = LinkPoses(result)
    poses = np.zeros((steps + 1, len(read_poses.every), 7))
    qpos[0], qvel[0], poses[0] = q, v, read_poses()
    for t in range(steps):
        if not (np.isfinite(qpos[t]).all() and np.isfinite(qvel[t]).all()):  # diverged: `set_ctrl` refuses it, and
            qpos[t + 1 :], qvel[t + 1 :], poses[t + 1 :] = np.nan, np.nan, np.nan  # PhysX would step NaN on
            break
        before_step(t, qpos[t], qvel[t])
        result.scene.step()
        qpos[t + 1], qvel[t + 1] = get_state(result)
        poses[t + 1] = read_poses()
    return Run(qpos, qvel, poses)


def pose7(pose: sapien.Pose) -> np.ndarray:
    """x, y, z, qw, qx, qy, qz (both MuJoCo and SAPIEN store quaternions wxyz)."""
    return np.concatenate([np.asarray(pose.p, dtype=float), np.asarray(pose.q, dtype=float)])


def body_link(result, body: int):
    """The articulation link carrying MuJoCo body `body`, or None (world, static or unmapped)."""
    entry = result.mapping.bodies[body] if body < len(result.mapping.bodies) else None
    if entry is None or entry.articulation is None or entry.link is None:
        return None
    return result.articulations[entry.articulation].links[entry.link]


def body_poses(result, nbody: int) -> np.ndarray:
    """World pose (nbody, 7) of the link carrying each body; NaN rows for bodies without a link."""
    out = np.tile(NAN_POSE, (nbody, 1))
    for b in range(nbody):
        link = body_link(result, b)
        if link is not None:
            out[b] = pose7(link.entity_pose)
    return out


def links(result) -> list[tuple[int, object]]:
    """Every articulation link in a fixed order: (articulation index, link)."""
    return [(a, link) for a, art in enumerate(result.articulations) for link in art.links]


def link_poses(result, every: list | None = None) -> np.ndarray:
    """World pose (L, 7) of every link, in the order of `links` (`every`: that list, when already made). Read as
    floats: a numpy call per link would cost more than the step's own reads."""
    rows = []
    for _, link in every if every is not None else links(result):
        pose = link.entity_pose
        rows.append(pose.p.tolist() + pose.q.tolist())
    return np.array(rows, dtype=float).reshape(-1, 7)


class LinkPoses:
    """Every link's world pose (L, 7) in the order of `links`, read as `link_poses` reads it, from one packed read of
    the scene: `Scene.pack_poses` gives each entity's pose in `scene.entities` order as seven float32 (qw qx qy qz,
    x y z), the same floats as `entity_pose`, in one call where `link_poses` makes one per link. Where the packing
    is not that layout (its size, or the first link's pose, says otherwise) or a link is not among the scene's
    entities, every read falls back to `link_poses`
    (tests/test_conformance_sapien_side.py::test_packed_link_poses_are_the_links_own_poses)."""

    WIDTH = 7  # float32 per entity: a quaternion, then a position

    def __init__(self, result, every: list | None = None):
        self.result, self.every = result, every if every is not None else links(result)
        self.scene, self.rows = result.scene, None
        entities = {entity.per_scene_id: i for i, entity in enumerate(self.scene.entities)}
        ids = [link.entity.per_scene_id for _, link in self.every]
        if self.every and all(i in entities for i in ids):
            self.rows = np.array([entities[i] for i in ids])
            if not self.packed_layout(len(entities)):
                self.rows = None

    def packed_layout(self, count: int) -> bool:
        """Whether the scene's packed poses are the layout read here: its size, and the first link's pose."""
        packed = self.scene.pack_poses()
        if len(packed) != 4 * self.WIDTH * count:
            return False
        return bool(np.array_equal(self._from(packed)[0], link_poses(self.result, self.every[:1])[0]))

    def _from(self, packed: bytes) -> np.ndarray:
        rows = np.frombuffer(packed, np.float32).reshape(-1, self.WIDTH)[self.rows]
        return np.concatenate([rows[:, 4:], rows[:, :4]], axis=1).astype(float)

    def __call__(self) -> np.ndarray:
        if self.rows is None:
            return link_poses(self.result, self.every)
        return self._from(self.scene.pack_poses())


def body_link_rows(result, nbody: int) -> np.ndarray:
    """Per MuJoCo body, the row of its link in `links(result)`, or -1."""
    offsets = np.cumsum([0] + [len(art.links) for art in result.articulations])
    rows = np.full(nbody, -1)
    for b in range(nbody):
        entry = result.mapping.bodies[b] if b < len(result.mapping.bodies) else None
        if entry is not None and entry.articulation is not None and entry.link is not None:
            rows[b] = offsets[entry.articulation] + entry.link
    return rows


def bodies_from_links(link_pose: np.ndarray, rows: np.ndarray) -> np.ndarray:
    """Body poses (..., nbody, 7) picked from link poses (..., L, 7); NaN for bodies without a link."""
    out = np.full(link_pose.shape[:-2] + (rows.size, 7), np.nan)
    have = rows >= 0
    out[..., have, :] = link_pose[..., rows[have], :]
    return out


def geom_component(result, geom: int):
    """(component, shape) for MuJoCo geom `geom`, or (None, None) when the geom got no collision shape."""
    entry = result.mapping.geoms[geom] if geom < len(result.mapping.geoms) else None
    if entry is None:
        return None, None
    if entry.articulation is not None:
        component = result.articulations[entry.articulation].links[entry.link]
    else:
        component = rigid_component(result.actors[entry.actor])
    return component, component.collision_shapes[entry.shape]


def rigid_component(entity: sapien.Entity):
    for component in entity.components:
        if isinstance(component, sapien.physx.PhysxRigidBaseComponent):
            return component
    raise ValueError(f"entity {entity.name!r} has no PhysX rigid component")


def shape_world_pose(component, shape) -> sapien.Pose:
    return component.entity_pose * shape.local_pose


def set_state(result, qpos: np.ndarray, qvel: np.ndarray, act: np.ndarray | None = None) -> None:
    """A MuJoCo state (qpos, qvel, act; act None: zeros, as in a fresh `MjData`) into SAPIEN."""
    result.set_state(np.asarray(qpos, dtype=float), np.asarray(qvel, dtype=float))
    result.set_act(act)


def held_start(
    result, qpos: np.ndarray, qvel: np.ndarray, act: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """A start as SAPIEN holds it (float32), where the one-step comparisons and the contact-free rollouts start
    MuJoCo too: a joint started exactly on its limit then sits on the same side of it in both, which MuJoCo's row
    switches on (corpus/regressions/conformance-8afb1dfdf1.xml)."""
    set_state(result, qpos, qvel, act)
    return get_state(result)


def get_state(result) -> tuple[np.ndarray, np.ndarray]:
    qpos, qvel = result.get_state()
    return np.asarray(qpos, dtype=float), np.asarray(qvel, dtype=float)


def apply_generalized_force(result, qfrc: np.ndarray) -> None:
    """Write the command through the loader (its per-step terms, passive tendons among them, stay in `qf`; set_qf
    persists, so this runs before every step). The dynamics tiers run with the actuators off: ctrl is zero."""
    result.set_ctrl(None, qfrc_applied=np.asarray(qfrc, dtype=float))


def clear_command(result, nv: int) -> None:
    """After a run: no command left in `qf` (set_qf persists). No physics step follows, so the call does not begin
    one (`advance=False`): link forces it added would wait in PhysX for the next run's first step, on top of that
    step's own (tests/test_tiers_mutations.py::test_a_run_after_another_starts_with_no_link_force_left); after a run
    that ended diverged it only clears `qf`. Then `qf` is zeroed: MuJoCo's own step writes the zero command's
    whole law there (gravity's share among it), which no later tier asks for
    (tests/test_tiers_actuated.py::test_the_scene_is_left_as_the_other_tiers_expect)."""
    from loader.runtime.dof_step import clear_qf

    result.set_ctrl(None, qfrc_applied=np.zeros(nv), advance=False)
    clear_qf(result.articulations)


def contacts_enabled(result) -> bool:
    """Whether any shape can still collide (`dynamics` and `actuated` zero every shape's groups)."""
    from loader.runtime.contacts import collision_shapes

    return any(g[0] or g[1] for shape in collision_shapes(result) for g in [shape.get_collision_groups()])

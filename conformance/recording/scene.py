"""What moves in the 3D view, where the camera starts, and how far SAPIEN is from MuJoCo.

Bodies and links carry per-step world transforms; `deviation` draws, per body and step, an arrow from MuJoCo's body
origin to SAPIEN's, magnified by a power of ten (named in the view) so that a deviation far below the robot's size
is still seen (`test_rerun_recording.py::test_deviation_arrows_are_the_deviation_times_the_factor_named`); the
camera looks at the robot's bounding box from outside it
(`test_rerun_recording.py::test_the_view_is_framed_on_the_robot`)."""

from __future__ import annotations

import math

import mujoco
import numpy as np
import rerun as rr
import rerun.blueprint as rrb

from .. import sapien_side
from .paths import body_path, link_path
from .poses import Motion, xyzw
from .timeline import times

DEVIATION_COLOR = [220, 30, 30, 255]
DEVIATION_SHARE = 0.05  # the magnified largest deviation reaches at least this fraction of the box's diagonal
MAX_MAGNIFICATION = 1000  # a 1 mm deviation draws 1 m long; float32 noise (~1e-7 m) stays out of sight
EYE_DIRECTION = np.array([1.0, -1.6, 0.7])  # from the box's center: front-right and above, Z up
FOV_Y = math.radians(55.0)  # the vertical field of view of Rerun's 3D view (its `Eye::DEFAULT_FOV_Y`)
FILL = 0.9  # the share of the view's height (from its center out) the robot's box may span
MIN_DISTANCE = 0.02  # metres from the center at least: a box of no size (one body, no geom) still gets an eye off it


def _transforms(rec: rr.RecordingStream, path: str, motion: Motion, pose: np.ndarray) -> None:
    if motion.time is None:
        rec.log(path, rr.Transform3D(translation=pose[0, :3], quaternion=xyzw(pose[0, 3:])), static=True)
    else:
        rec.send_columns(
            path,
            indexes=times(motion.time),
            columns=rr.Transform3D.columns(
                translation=pose[:, :3].astype(np.float32), quaternion=xyzw(pose[:, 3:]).astype(np.float32)
            ),
        )


def log_frames(
    rec: rr.RecordingStream, model: mujoco.MjModel, result, motion: Motion, bodies: set[int], links: set[int]
) -> None:
    """The world transform along the motion of each MuJoCo body in `bodies` and each SAPIEN link (row of
    `sapien_side.links`) in `links`: those that carry something drawn."""
    for b in sorted(bodies - {0}):
        _transforms(rec, body_path(model, b), motion, motion.mujoco_body_pose[:, b])
    for row, (a, link) in enumerate(sapien_side.links(result)):
        if row in links:
            _transforms(rec, link_path(a, link), motion, motion.sapien_link_pose[:, row])


def magnification(motion: Motion, box) -> int:
    """The power of ten that makes the largest body deviation at least DEVIATION_SHARE of the box's diagonal, at
    most MAX_MAGNIFICATION."""
    error = np.linalg.norm(motion.sapien_body_pose[..., :3] - motion.mujoco_body_pose[..., :3], axis=-1)
    largest = float(np.nanmax(error, initial=0.0))
    diagonal = float(np.linalg.norm(box[1] - box[0]))
    if not math.isfinite(largest) or largest <= 0 or largest >= DEVIATION_SHARE * diagonal:
        return 1
    return min(10 ** math.ceil(math.log10(DEVIATION_SHARE * diagonal / largest)), MAX_MAGNIFICATION)


def log_deviation(rec: rr.RecordingStream, motion: Motion, scale: int) -> None:
    """Arrows MuJoCo body -> SAPIEN body, `scale` times their length, for the bodies SAPIEN carries."""
    have = np.all(np.isfinite(motion.sapien_body_pose[0, :, :3]), axis=1)
    have[0] = False
    if motion.time is None or not have.any():
        return
    origins = motion.mujoco_body_pose[:, have, :3]
    vectors = (motion.sapien_body_pose[:, have, :3] - origins) * scale
    k = int(have.sum())
    columns = rr.Arrows3D.columns(
        origins=origins.reshape(-1, 3).astype(np.float32), vectors=vectors.reshape(-1, 3).astype(np.float32)
    ).partition([k] * origins.shape[0])
    rec.log("deviation", rr.Arrows3D.from_fields(colors=[DEVIATION_COLOR]), static=True)
    rec.send_columns("deviation", indexes=times(motion.time), columns=columns)


def eye(box) -> rrb.EyeControls3D:
    """An orbit camera on the box's center from EYE_DIRECTION, as close as lets every corner of the box show within
    FILL of the view's half height from its center (and as much sideways: the view is at least as wide as high),
    at Rerun's vertical field of view. The distance follows the box, so a gripper and a humanoid alike fill most of
    the view (`tests/test_rerun_recording.py::test_the_camera_frames_the_robot_whatever_its_size`)."""
    lo, hi = (np.asarray(v, dtype=float) for v in box)
    center = (lo + hi) / 2
    back = EYE_DIRECTION / np.linalg.norm(EYE_DIRECTION)  # from the center towards the eye
    right = np.cross(-back, [0.0, 0.0, 1.0])
    right /= np.linalg.norm(right)
    up = np.cross(right, -back)
    corners = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])]) - center
    sideways = np.maximum(np.abs(corners @ right), np.abs(corners @ up))
    reach = math.tan(FOV_Y / 2) * FILL  # half the view's height at depth 1, the share the box may take
    distance = max(float(np.max(corners @ back + sideways / reach)), MIN_DISTANCE)
    return rrb.EyeControls3D(position=center + back * distance, look_target=center, eye_up=[0.0, 0.0, 1.0])

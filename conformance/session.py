"""One loaded model: the loader's result next to its MuJoCo reference, with load timings and settings."""

from __future__ import annotations

import time
import warnings
from dataclasses import dataclass, field

import mujoco

from .reference import settings as reference_settings

OWN_LOADERS = ("ours", "terms")  # this project's loader, by the law that gives set_ctrl's forces (`loaders.py`)


@dataclass
class Session:
    path: str
    result: object  # loader.LoadResult
    model: mujoco.MjModel
    load_seconds: float
    compile_seconds: float
    fix_root_link: bool
    loader: str = "ours"  # the harness's loader plug-in that made `result` (conformance/loaders.py)
    skips: dict[str, str] = field(default_factory=dict)  # tiers the loader cannot take part in, and why
    isolates: bool = True  # whether the loader loads an edited MjSpec (conformance/isolation.py)

    def load_info(self) -> dict:
        res = self.result
        return {
            **({"loader": self.loader} if self.loader != "ours" else {}),
            **({"set_ctrl_law": res.controller.law()} if self.loader in OWN_LOADERS else {}),
            "load_seconds": round(self.load_seconds, 4),
            "mujoco_compile_seconds": round(self.compile_seconds, 4),
            "fix_root_link": self.fix_root_link,
            "articulations": len(res.articulations),
            "links": sum(len(a.links) for a in res.articulations),
            "dofs": sum(a.dof for a in res.articulations),
            "unsupported": [_feature(u) for u in res.unsupported],
            "approximations": [_feature(u) for u in res.approximations],
        }

    def settings(self) -> dict:
        scene_config = self.result.scene.physx_system.config  # the scene's own, fixed when its system was made
        return {
            "mujoco": reference_settings(self.model, self.model),
            "sapien": {
                "timestep": float(self.result.scene.timestep),
                "gravity": [float(g) for g in scene_config.gravity],
                "solver": "PGS" if not scene_config.enable_tgs else "TGS",
                "solver_position_iterations": [a.solver_position_iterations for a in self.result.articulations],
                "solver_velocity_iterations": [a.solver_velocity_iterations for a in self.result.articulations],
            },
        }


def _feature(item) -> dict:
    return {"kind": str(item.kind), "name": str(item.name), "reason": str(item.reason)}


IGNORE_CLASSES: list[str] = []  # the harness compares every geom MuJoCo has (the loader's default skips "motor")


def quiet_load(source, fix_root_link: bool = True):
    """The loader as the harness, the isolation, the fragment properties and the tests run it: `IGNORE_CLASSES`,
    its warnings silenced (the result lists the same notes, and the reports show them)."""
    from loader import MJCFLoader, NoRenderDeviceWarning, UnsupportedFeatureWarning

    loader = MJCFLoader(ignore_classes=IGNORE_CLASSES)
    loader.fix_root_link = fix_root_link
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UnsupportedFeatureWarning)
        warnings.simplefilter("ignore", NoRenderDeviceWarning)
        return loader.load(source if isinstance(source, mujoco.MjSpec) else str(source))


def open_session(path: str, fix_root_link: bool | None = None) -> Session:
    """Compile with MuJoCo (timed), then load with the loader (timed); free joints stay floating roots."""
    t0 = time.perf_counter()
    mujoco.MjModel.from_xml_path(str(path))  # MuJoCo's own compile of the same file, timed for comparison
    compile_seconds = time.perf_counter() - t0
    if fix_root_link is None:
        fix_root_link = True  # free joints float whatever this says; jointless roots are welded, as in MuJoCo
    t0 = time.perf_counter()
    result = quiet_load(path, fix_root_link)
    load_seconds = time.perf_counter() - t0
    # the reference runs with actuation disabled and commands generalized forces (conformance.reference)
    result.disable_actuators()
    return Session(str(path), result, result.model, load_seconds, compile_seconds, fix_root_link)

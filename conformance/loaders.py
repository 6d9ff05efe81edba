"""The loaders the harness judges (`run --loader NAME`), one function per name: each opens a `Session` on an MJCF
file (MuJoCo's model beside what the loader built, presented as `loader.LoadResult` presents it) and names the
tiers the loader cannot take part in, with why; the worker reports those as skipped with that reason."""

from __future__ import annotations

from .session import OWN_LOADERS, Session

DEFAULT = "ours"
OWN = OWN_LOADERS  # this project's loader, whichever gives set_ctrl's forces: the manifest's expectations
# per loader, the tiers it cannot take part in on any model, and why (expected: skipped)
SKIPS = {
    "maniskill": {
        "collision": "ManiSkill's loader names no collision shape, so no geom can be matched to one by its MuJoCo name",
        "actuated_contact": "ManiSkill's loader maps no actuators",
        "actuated": "ManiSkill's loader maps no actuators",
        "maniskill": "the maniskill tier runs this project's loader inside ManiSkill, not ManiSkill's own",
        "maniskill_tensor": "the maniskill_tensor tier runs this project's loader in ManiSkill, not ManiSkill's own",
    },
    "physx": {
        "maniskill": "the maniskill tier runs this project's loader with its per-step terms, in ManiSkill",
        "maniskill_tensor": "the maniskill_tensor tier runs this project's loader with its joint actuation law",
    },
}


def ours(path: str) -> Session:
    """This project's loader (`loader.MJCFLoader`) as it loads by default: `set_ctrl`'s joint forces from MuJoCo's
    own step where the model allows, the per-step terms elsewhere."""
    from .session import open_session

    return open_session(path)


def maniskill(path: str) -> Session:
    """ManiSkill's own MJCF loader, built as ManiSkill builds it (conformance/maniskill_loader.py); it needs the
    maniskill extra."""
    from . import maniskill_loader

    result, model, compile_seconds, load_seconds = maniskill_loader.load(path)
    return Session(
        str(path),
        result,
        model,
        load_seconds,
        compile_seconds,
        fix_root_link=True,
        loader=maniskill_loader.NAME,
        skips=dict(SKIPS["maniskill"]),
        isolates=False,
    )


def physx(path: str) -> Session:
    """This project's build with PhysX alone: servos as drives, motors as joint forces, no per-step terms
    (conformance/physx_loader.py), as ManiSkill's PD modes and GPU backend run it."""
    from .physx_loader import NAME, PhysxAlone
    from .session import open_session

    session = open_session(path)
    session.result = PhysxAlone(session.result)
    session.loader, session.skips, session.isolates = NAME, dict(SKIPS[NAME]), False
    return session


def terms(path: str) -> Session:
    """This project's loader with `set_ctrl`'s joint forces from the per-step terms on every model
    (`MJCFLoader.set_ctrl_law = "terms"`), where `ours` runs MuJoCo's own step wherever the model allows."""
    from .session import open_session

    session = open_session(path)
    session.result.controller.use_mujoco_step(False)
    session.loader = "terms"
    return session


LOADERS = {"ours": ours, "maniskill": maniskill, "physx": physx, "terms": terms}
EXTRAS = {"maniskill": ("mani_skill", "the maniskill extra")}  # what a loader needs beyond the harness
DISTRIBUTIONS = {"maniskill": ("mani-skill",)}  # whose versions its reports record


def missing(name: str) -> str | None:
    """Why loader `name` cannot run here (its extra is not installed), or None."""
    import importlib.util

    module, extra = EXTRAS.get(name, (None, None))
    if module is not None and importlib.util.find_spec(module) is None:
        return f"--loader {name} needs {module} ({extra}: pip install .[{name}])"
    return None


def open_with(name: str, path: str) -> Session:
    """The session of loader `name` on `path`; ValueError naming the known loaders for another name."""
    if name not in LOADERS:
        raise ValueError(f"no loader {name!r}; choose from {', '.join(LOADERS)}")
    return LOADERS[name](path)

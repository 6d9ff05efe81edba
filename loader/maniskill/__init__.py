"""The loader inside ManiSkill 3 (the `maniskill` extra): `MJCFLoader` for a ManiSkill scene and `register_agent`,
a ManiSkill robot from an MJCF file with controllers derived from its actuators. Layout: docs/maniskill.md."""

from .agent import MJCFAgent, register_agent
from .scene_loader import MJCFLoader

__all__ = ["MJCFAgent", "MJCFLoader", "register_agent"]

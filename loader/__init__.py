"""Load MuJoCo MJCF models into SAPIEN, with MuJoCo's own compiler as the front end."""

from .errors import (
    ControlError,
    MissingAssetError,
    MJCFError,
    SceneMismatchWarning,
    Unsupported,
    UnsupportedFeatureWarning,
)
from .mjcf_loader import MJCFLoader
from .model.actuators import ActuatorMap
from .model.equalities import EqualityLink
from .model.mapping import BodyLink, GeomShape, JointDofs, Mapping
from .plan.camera import CameraConfig, SiteConfig
from .plan.texture import MJCFTexture
from .plan.visual import NoRenderDeviceWarning, has_render_device
from .result import LoadResult

__all__ = [
    "ActuatorMap",
    "BodyLink",
    "CameraConfig",
    "ControlError",
    "EqualityLink",
    "GeomShape",
    "JointDofs",
    "LoadResult",
    "MJCFError",
    "MJCFLoader",
    "MJCFTexture",
    "Mapping",
    "MissingAssetError",
    "NoRenderDeviceWarning",
    "SceneMismatchWarning",
    "SiteConfig",
    "Unsupported",
    "UnsupportedFeatureWarning",
    "has_render_device",
]

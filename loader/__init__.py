"""Load MuJoCo MJCF models into SAPIEN, with MuJoCo's own compiler as the front end."""

from .build.actuators import ActuatorMap
from .build.camera import CameraConfig, SiteConfig
from .build.equalities import EqualityLink
from .build.mapping import BodyLink, GeomShape, JointDofs, Mapping
from .build.texture import MJCFTexture
from .build.visual import NoRenderDeviceWarning, has_render_device
from .errors import (
                     ControlError,
                     MissingAssetError,
                     MJCFError,
                     SceneMismatchWarning,
                     Unsupported,
                     UnsupportedFeatureWarning,
)
from .mjcf_loader import MJCFLoader
from .result import LoadResult

__all__ = [
    "ActuatorMap", "BodyLink", "CameraConfig", "ControlError", "EqualityLink", "GeomShape", "JointDofs", "LoadResult", "MJCFError", "MJCFLoader", "MJCFTexture",
    "Mapping", "MissingAssetError", "NoRenderDeviceWarning", "SceneMismatchWarning", "SiteConfig", "Unsupported",
    "UnsupportedFeatureWarning", "has_render_device",
]

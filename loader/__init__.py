"""Load MuJoCo MJCF models into SAPIEN, with MuJoCo's own compiler as the front end."""

from .actuator import ActuatorMap
from .camera import CameraConfig, SiteConfig
from .equality import EqualityLink
from .errors import ControlError, MissingAssetError, MJCFError, Unsupported, UnsupportedFeatureWarning
from .mapping import BodyLink, GeomShape, JointDofs, Mapping
from .mjcf_loader import LoadResult, MJCFLoader
from .texture import MJCFTexture
from .visual import NoRenderDeviceWarning, has_render_device

__all__ = [
    "ActuatorMap", "BodyLink", "CameraConfig", "ControlError", "EqualityLink", "GeomShape", "JointDofs", "LoadResult", "MJCFError", "MJCFLoader", "MJCFTexture",
    "Mapping", "MissingAssetError", "NoRenderDeviceWarning", "SiteConfig", "Unsupported",
    "UnsupportedFeatureWarning", "has_render_device",
]

"""Load MuJoCo MJCF models into SAPIEN, with MuJoCo's own compiler as the front end.

A load is quiet where nothing was lost: SAPIEN's import-time note that it uses its own libvulkan is dropped, and
`NoRenderDeviceWarning` is ignored unless a filter asks for it (`warnings.simplefilter("default",
NoRenderDeviceWarning)`); what a model loses is warned (`UnsupportedFeatureWarning`)
(tests/test_packaging.py::test_a_plain_load_prints_nothing)."""

import warnings

with warnings.catch_warnings():  # SAPIEN says at import that it falls back to its own libvulkan: nothing to act on
    warnings.filterwarnings("ignore", message="Failed to find system libvulkan", category=UserWarning)
    import sapien  # noqa: F401

from .errors import (
    Approximation,
    ControlError,
    DivergenceError,
    MissingAssetError,
    MJCFError,
    Note,
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
from .runtime.batch import Batch

warnings.filterwarnings("ignore", category=NoRenderDeviceWarning, append=True)  # a filter of the caller's wins

__all__ = [
    "ActuatorMap",
    "Approximation",
    "Batch",
    "BodyLink",
    "CameraConfig",
    "ControlError",
    "DivergenceError",
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
    "Note",
    "SceneMismatchWarning",
    "SiteConfig",
    "Unsupported",
    "UnsupportedFeatureWarning",
    "has_render_device",
]

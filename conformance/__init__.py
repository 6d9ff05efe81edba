"""MuJoCo vs SAPIEN conformance harness: tiers, corpus, runner, Rerun recordings and summaries."""

from .noise import silence_imports

silence_imports()  # before the imports below bring in SAPIEN

from .manifest import TIER_NAMES, Manifest, ModelEntry
from .report import Metric, TierReport, Trace
from .tolerances import Tolerances

__all__ = ["TIER_NAMES", "Manifest", "Metric", "ModelEntry", "TierReport", "Tolerances", "Trace"]

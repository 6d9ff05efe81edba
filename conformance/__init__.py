"""MuJoCo vs SAPIEN conformance harness: tiers, corpus, runner, Rerun recordings and summaries."""

from .manifest import TIER_NAMES, Manifest, ModelEntry
from .report import Metric, TierReport, Trace
from .tolerances import Tolerances

__all__ = ["TIER_NAMES", "Manifest", "Metric", "ModelEntry", "TierReport", "Tolerances", "Trace"]

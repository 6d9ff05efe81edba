"""What a worker reports for one model: the `models/<id>.json` document, and what the summary judges."""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field, fields

STATUSES = ("ok", "error", "skipped", "timeout", "crashed", "pending")


@dataclass
class ModelResult:
    """One model's run. `status` is the worker's (ok: the tiers ran; error: the load failed; timeout, crashed: the
    worker was lost; skipped: the corpus source is not installed; pending: not finished). `tiers` maps a tier to
    its `TierReport.to_dict()`, with the isolation runs of a failing dynamic tier."""

    id: str
    status: str
    reason: str = ""
    source: str = ""
    path: str = ""
    seed: int | None = None
    versions: dict = field(default_factory=dict)
    load: dict = field(default_factory=dict)
    settings: dict = field(default_factory=dict)
    tiers: dict[str, dict] = field(default_factory=dict)
    recording: str | None = None
    seconds: float | None = None
    traceback: str | None = None
    warnings: dict[str, int] = field(default_factory=dict)  # third-party warnings by kind (conformance/noise.py)

    def __post_init__(self) -> None:
        if self.status not in STATUSES:
            raise ValueError(f"model {self.id!r}: unknown status {self.status!r} (one of {', '.join(STATUSES)})")

    def to_dict(self) -> dict:
        """The JSON document (non-finite floats as null, numpy scalars as Python numbers)."""
        return jsonable(asdict(self))

    @classmethod
    def from_dict(cls, data: dict) -> ModelResult:
        known = {f.name for f in fields(cls)}
        return cls(**{k: v for k, v in data.items() if k in known})


def jsonable(obj):
    if isinstance(obj, dict):
        return {str(k): jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [jsonable(v) for v in obj]
    if isinstance(obj, float) and not math.isfinite(obj):
        return None
    if hasattr(obj, "item") and callable(obj.item):
        return jsonable(obj.item())
    return obj

"""Tolerances as data: every number lives in `tolerances.toml` with the measurement that justifies it."""

from __future__ import annotations

from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path

import tomllib


@dataclass(frozen=True)
class Tolerance:
    """One named tolerance: its value, unit and the reason (measurement) behind it."""

    key: str
    value: float
    unit: str
    why: str


@dataclass(frozen=True)
class Tolerances:
    """All tolerances and tier settings, keyed `tier.name` (e.g. `kinematics.position`)."""

    entries: dict[str, Tolerance]
    settings: dict[str, dict] = field(default_factory=dict)

    def __getitem__(self, key: str) -> float:
        try:
            return self.entries[key].value
        except KeyError:
            raise KeyError(f"no tolerance {key!r} in tolerances.toml; known: {sorted(self.entries)}") from None

    def setting(self, tier: str, name: str):
        """A non-tolerance tier setting (horizon, sample counts) from the `[settings.<tier>]` table."""
        try:
            return self.settings[tier][name]
        except KeyError:
            raise KeyError(f"no setting {tier}.{name} in tolerances.toml") from None

    def horizon_steps(self, tier: str, timestep: float) -> int:
        """Steps of a tier's rollouts: `horizon_s` at this timestep, capped by `max_steps`, at least one."""
        steps = round(self.setting(tier, "horizon_s") / timestep)
        return max(1, min(steps, int(self.setting(tier, "max_steps"))))

    def with_overrides(
        self,
        tolerances: dict[str, float] | None = None,
        settings: dict[str, dict] | None = None,
        why: str = "per-model override",
    ) -> Tolerances:
        """A copy with some values replaced (manifest overrides); unknown keys are errors."""
        entries = dict(self.entries)
        for key, value in (tolerances or {}).items():
            old = entries.get(key)
            if old is None:
                raise KeyError(f"override of unknown tolerance {key!r}")
            entries[key] = Tolerance(key, float(value), old.unit, why)
        merged = {tier: dict(values) for tier, values in self.settings.items()}
        for tier, values in (settings or {}).items():
            if tier not in merged:
                raise KeyError(f"override of unknown settings table {tier!r}")
            for name, value in values.items():
                if name not in merged[tier]:
                    raise KeyError(f"override of unknown setting {tier}.{name}")
                merged[tier][name] = value
        return Tolerances(entries, merged)

    def to_dict(self) -> dict:
        return {
            "tolerances": {k: {"value": t.value, "unit": t.unit, "why": t.why} for k, t in self.entries.items()},
            "settings": self.settings,
        }


def parse(data: dict) -> Tolerances:
    """Build `Tolerances` from the parsed TOML document."""
    entries: dict[str, Tolerance] = {}
    for tier, table in data.get("tolerance", {}).items():
        for name, entry in table.items():
            key = f"{tier}.{name}"
            missing = {"value", "unit", "why"} - set(entry)
            if missing:
                raise ValueError(f"tolerance {key} lacks {sorted(missing)}")
            entries[key] = Tolerance(key, float(entry["value"]), str(entry["unit"]), str(entry["why"]))
    return Tolerances(entries, {tier: dict(values) for tier, values in data.get("settings", {}).items()})


def load(path: str | Path | None = None) -> Tolerances:
    """Load the tolerance file (default: the packaged `tolerances.toml`)."""
    if path is None:
        text = resources.files("conformance").joinpath("tolerances.toml").read_text()
    else:
        text = Path(path).read_text()
    return parse(tomllib.loads(text))

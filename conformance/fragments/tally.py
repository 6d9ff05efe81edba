"""What a fuzz run exercised: documents compiled or rejected, tiers passed, skipped or excused, with reasons.
A run owns its tally and passes it to the properties (`properties.check_path`)."""

from __future__ import annotations

from collections import Counter


class Tally(Counter):
    """Counts across a run's documents, by what happened."""

    def summary(self) -> str:
        return ", ".join(f"{key}: {count}" for key, count in sorted(self.items()))

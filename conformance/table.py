"""README's results table, made from a run's summary.json (`python -m conformance table`), so that the figures a
reader sees are the ones a run measured: `--check README.md` fails where the README's table is not the run's
(`.ci/run` checks it against the default corpus it has just run;
tests/test_conformance_summary.py::test_the_readme_table_is_made_from_a_run_and_checked)."""

from __future__ import annotations

import json
from pathlib import Path

from .manifest import DEFAULT_TIERS

BEGIN = "<!-- results: made from a run by the harness's table command -->"
END = "<!-- /results -->"
COUNTED = list(DEFAULT_TIERS)  # the tiers a default run judges


def counts(summary: dict) -> dict[str, tuple[int, int]]:
    """Per tier, (passed, judged): a model that did not load counts as judged and failed in every tier; a skipped
    tier is not judged; `chaotic` is judged and not passed."""
    out = {tier: [0, 0] for tier in COUNTED}
    for model in summary["models"]:
        verdicts = model["verdicts"]
        for tier in COUNTED:
            outcome = verdicts.get("load", verdicts.get(tier, {})).get("outcome")
            if outcome is None or outcome == "skipped":
                continue
            out[tier][1] += 1
            out[tier][0] += outcome == "pass"
    return {tier: (passed, judged) for tier, (passed, judged) in out.items()}


ROWS = {"ours": "this loader (`set_ctrl`)", "physx": "PhysX alone (PD modes, GPU)", "maniskill": "ManiSkill's loader"}


def row(summary: dict) -> str:
    """One run's row, named after the loader it judged (`run --loader`; this project's when the run names none)."""
    label = ROWS.get(summary.get("loader", "ours"), summary.get("loader", "ours"))
    return f"| {label} | " + " | ".join(f"{p}/{j}" for p, j in counts(summary).values()) + " |"


def table(*summaries: dict) -> str:
    """The markdown table, between its markers: one row per run, in the order given."""
    first = summaries[0]
    head = (
        f"| {len(first['models'])} models, seed {first.get('seed', 0)}: pass / judged | " + " | ".join(COUNTED) + " |"
    )
    rule = "|---" * (len(COUNTED) + 1) + "|"
    return "\n".join([BEGIN, head, rule, *(row(s) for s in summaries), END])


def embedded(text: str) -> str | None:
    """The table a document holds between the markers (None without them)."""
    if BEGIN not in text or END not in text:
        return None
    start = text.index(BEGIN)
    return text[start : text.index(END, start) + len(END)]


def check(summaries: list[dict], document: Path) -> str | None:
    """None where `document` holds the runs' table, else what to do."""
    made, held = table(*summaries), embedded(document.read_text())
    if held == made:
        return None
    if held is None:
        return f"{document} has no results table between {BEGIN!r} and {END!r}"
    return f"{document}'s results table is not these runs'; replace it with:\n{made}"


def load_summary(run: Path) -> dict:
    path = run / "summary.json" if run.is_dir() else run
    return json.loads(path.read_text())

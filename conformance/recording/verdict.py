"""The verdict panel: each tier's outcome as the summary judges it (`expected-fail`, not `fail`, for a failure the
manifest expects), the outcome the manifest expects and its reason, then the numbers, seed, versions and settings
(`test_rerun_recording.py::test_the_verdict_panel_shows_the_expected_outcome_and_reason`)."""

from __future__ import annotations

import json

from ..manifest import OUTCOME_RANK
from ..report import TierReport


def _order(reports: dict[str, TierReport], judged: dict) -> list[str]:
    """The tiers, those worse than expected first, then by how bad their outcome is (passes last)."""

    def badness(tier: str) -> tuple:
        v = judged.get(tier, {})
        return (not v.get("worse", False), -OUTCOME_RANK.get(v.get("raw", reports[tier].status), 0))

    return sorted(reports, key=badness)


def headlines(reports: dict[str, TierReport], judged: dict) -> list[str]:
    """One line per tier that did not pass, the worst first: its outcome, its metric furthest past its tolerance and
    why (the manifest's reason, else the tier's first note)."""
    lines = []
    for tier in _order(reports, judged):
        report, v = reports[tier], judged.get(tier, {})
        outcome = v.get("outcome", report.status)
        if outcome == "pass":
            continue
        worst = max((m for m in report.metrics if m.tolerance > 0), key=lambda m: m.max / m.tolerance, default=None)
        parts = [f"**{tier}: {outcome}**" + (" (worse than expected)" if v.get("worse") else "")]
        if worst is not None:
            parts.append(f"{worst.name} {worst.max:.3g} against {worst.tolerance:.3g} {worst.unit}")
        why = v.get("reason") or (report.notes[0] if report.notes else "")
        if why:
            parts.append(why)
        lines.append("- " + "; ".join(parts))
    return lines or ["- every tier passes"]


def _rows(tier: str, report: TierReport, v: dict) -> list[str]:
    """A tier's table rows, five columns so that the table fits the verdict panel at a laptop's width: a metric's
    max and its tolerance share one cell
    (`tests/test_rerun_recording.py::test_the_verdict_table_and_plot_titles_fit_their_panels`)."""
    outcome = v.get("outcome", report.status) + (" (worse than expected)" if v.get("worse") else "")
    expected = v.get("expected", "")
    rows = []
    if report.divergence is not None:
        rows.append(f"| {tier} | diverged | first bad step: {report.divergence.text()} | | {expected} |")
    if not report.metrics:
        rows.append(f"| {tier} | {outcome} | | | {expected} |")
    for m in report.metrics:
        rows.append(f"| {tier} | {outcome} | {m.name} | {m.max:.3g} / {m.tolerance:.3g} {m.unit} | {expected} |")
    return rows


def verdict_markdown(reports: dict[str, TierReport], meta: dict) -> str:
    """`meta["verdicts"]` maps a tier to the summary's judgement (outcome, expected, reason, worse); without it a
    tier shows its raw status. The first lines say what did not pass and why, the worst first; the table below
    orders the tiers the same way."""
    judged = meta.get("verdicts", {})
    lines = [f"# {meta.get('model', '')}", "", *headlines(reports, judged), ""]
    if meta.get("shown"):
        lines += [f"3D view: {meta['shown']}", ""]
    lines += ["| tier | outcome | metric | max / tolerance | expected |", "|---|---|---|---|---|"]
    for tier in _order(reports, judged):
        lines += _rows(tier, reports[tier], judged.get(tier, {}))
    reasons = [(tier, v) for tier, v in judged.items() if v.get("reason")]
    if reasons:
        lines += ["", "## What the manifest expects, and why", ""]
        lines += [f"- {tier}: {v.get('expected')}: {v['reason']}" for tier, v in reasons]
    isolation = {tier: runs for tier, runs in meta.get("isolation", {}).items() if runs}
    if isolation:
        from ..summary import isolation_text

        lines += ["", "## Isolation (the failing tier rerun with known gaps removed on both sides)", ""]
        lines += [f"- {tier}: " + isolation_text(runs) for tier, runs in isolation.items()]
    lines += [
        "",
        f"seed: {meta.get('seed')}",
        "",
        "versions: " + ", ".join(f"{k} {v}" for k, v in meta.get("versions", {}).items()),
        "",
        "## Notes",
    ]
    for tier, report in reports.items():
        lines += [f"- {tier}: {n}" for n in report.notes[:10]]
    lines += ["", "## Settings", "```json", json.dumps(meta.get("settings", {}), indent=1, default=str), "```"]
    return "\n".join(lines)

"""The verdict panel: each tier's outcome as the summary judges it (`expected-fail`, not `fail`, for a failure the
manifest expects), the outcome the manifest expects and its reason, then the numbers, seed, versions and settings
(`test_rerun_recording.py::test_the_verdict_panel_shows_the_expected_outcome_and_reason`)."""

from __future__ import annotations

import json

from ..report import TierReport


def verdict_markdown(reports: dict[str, TierReport], meta: dict) -> str:
    """`meta["verdicts"]` maps a tier to the summary's judgement (outcome, expected, reason, worse); without it a
    tier shows its raw status."""
    judged = meta.get("verdicts", {})
    lines = [f"# {meta.get('model', '')}", ""]
    if meta.get("shown"):
        lines += [f"3D view: {meta['shown']}", ""]
    lines += [
        "| tier | outcome | metric | max | tolerance | max / tolerance | expected |",
        "|---|---|---|---|---|---|---|",
    ]
    for tier, report in reports.items():
        v = judged.get(tier, {})
        outcome = v.get("outcome", report.status) + (" (worse than expected)" if v.get("worse") else "")
        expected = v.get("expected", "")
        if report.divergence is not None:
            lines.append(f"| {tier} | diverged | first bad step: {report.divergence.text()} | | | | {expected} |")
        if not report.metrics:
            lines.append(f"| {tier} | {outcome} | | | | | {expected} |")
        for m in report.metrics:
            ratio = f"{m.max / m.tolerance:.3g}" if m.tolerance > 0 else ""
            lines.append(
                f"| {tier} | {outcome} | {m.name} | {m.max:.3g} | {m.tolerance:.3g} {m.unit} | {ratio} | {expected} |"
            )
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

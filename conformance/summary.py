"""Judge results against the manifest's expectations and write summary.json / summary.md atomically."""

from __future__ import annotations

import json
import os
import re
import tempfile
from dataclasses import dataclass
from pathlib import Path

from .divergence import Divergence
from .isolation import claim_holds, order_in_timestep
from .manifest import LOAD, OUTCOME_RANK, Expectation, ModelEntry
from .results import ModelResult


@dataclass(frozen=True)
class Verdict:
    """One model x tier cell: the outcome shown, the raw outcome and whether it is worse than expected."""

    model: str
    tier: str
    outcome: str  # pass / fail / expected-fail / chaotic / skipped / changed / diverged
    raw: str
    expected: str
    worse: bool
    detail: dict


def _left_band(expectation: Expectation, detail: dict) -> str | None:
    """Why an expected failure is no longer the one its reason describes (its metric left the band), or None."""
    lo, hi = expectation.band
    value = next((m["max"] for m in detail.get("metrics", []) if m["name"] == expectation.metric), None)
    if value is None:
        return (
            f"changed: the manifest's reason describes {expectation.metric} (seen {expectation.seen_text}); "
            "the tier reported no finite value of it"
        )
    if lo <= value <= hi:
        return None
    return (
        f"changed: {expectation.metric} {value:.3g} left the band [{lo:.3g}, {hi:.3g}] around the "
        f"{expectation.seen_text} the manifest's reason was measured at: re-measure the reason"
    )


# A manifest reason that says the loader leaves elements unmapped ("8 of its 78 actuators ... the loader does not
# map", "12 tendons / 4 equalities are not mapped") names counts of MJCF concepts; the loader's notes of the run must
# say the same, or the reason is stale.
UNMAPPED = re.compile(r"not mapped|does not map|do not map|unmapped")
COUNTED = re.compile(
    r"\b(\d+)(?: of (?:its|the) \d+)? (actuator|tendon|equalit|sensor|joint|geom|flex|plugin)(?:s|y|ies)?\b"
)
CONCEPT = {"equalit": "equality"}


def unmapped_mismatch(reason: str, load: dict | None) -> str | None:
    """Where `reason` says N elements of a kind are not mapped and the loader's notes of this run (`load`, the
    worker's load record) drop another number of them, what differs; else None
    (tests/test_conformance_summary.py::test_a_reason_naming_unmapped_elements_is_checked_against_the_notes)."""
    if not load or not UNMAPPED.search(reason):
        return None
    dropped: dict[str, int] = {}
    for note in load.get("unsupported", []):
        dropped[note["kind"]] = dropped.get(note["kind"], 0) + 1
    wrong = []
    for count, stem in COUNTED.findall(reason):
        kind = CONCEPT.get(stem, stem)
        if dropped.get(kind, 0) != int(count):
            wrong.append(f"{count} {kind} (the loader drops {dropped.get(kind, 0)})")
    if not wrong:
        return None
    return f"stale: the manifest's reason says {', '.join(wrong)} not mapped; re-check it against the loader's notes"


UNLISTED_OK = ("skipped", "chaotic")  # for a file the manifest does not list: a reason, not a disagreement


def judge(entry: ModelEntry, result: ModelResult) -> list[Verdict]:
    """Compare a worker result with what the manifest expects, tier by tier. A divergence is worse than any
    expectation; an expected failure whose metric left its band is `changed`, also worse. For a file the manifest
    does not list, `skipped` (with its reason) and `chaotic` (MuJoCo's own spread) are not worse. A model that did
    not load
    is one `error` verdict on `load`, MuJoCo's (or the loader's) message its note, judged against the model's worst
    expectation (tests/test_conformance_summary.py::test_a_load_error_is_one_error_outcome)."""
    if result.status == "error":
        expected = max((e.outcome for e in entry.expect.values()), key=OUTCOME_RANK.get, default="pass")
        return [
            Verdict(
                entry.id,
                LOAD,
                "error",
                "error",
                expected,
                OUTCOME_RANK["error"] > OUTCOME_RANK[expected],
                {"notes": [load_message(result.reason)], "metrics": []},
            )
        ]
    verdicts = []
    for tier in entry.tiers:
        report = result.tiers.get(tier)
        if report is None:  # the worker never reached the tier: its model-level status decides
            raw = "skipped" if result.status == "skipped" else "fail"
            detail = {"notes": [result.reason or "tier did not run"], "metrics": []}
        else:
            raw, detail = report["status"], report
        expected = entry.expected(tier)
        expectation = entry.expect.get(tier)
        if expectation is not None:
            detail = {**detail, "expected_reason": expectation.reason}
        if raw == "fail" and expected == "fail" and expectation is not None:
            change = _left_band(expectation, detail)
            if change is not None:
                raw, detail = "changed", {**detail, "notes": [*detail.get("notes", []), change]}
        worse = OUTCOME_RANK[raw] > OUTCOME_RANK[expected] and not (raw in UNLISTED_OK and not entry.listed)
        claimed = expectation.passes_without if expectation is not None else ()
        if raw == "fail" and claimed and not claim_holds(detail.get("isolation", []), claimed):
            worse = True  # the manifest's reason is a claim the run could not reproduce
            claim = f"the manifest claims the tier passes without {', '.join(claimed)}; it did not"
            detail = {**detail, "notes": [*detail.get("notes", []), claim]}
        stale = unmapped_mismatch(expectation.reason, result.load) if expectation is not None else None
        if stale is not None:
            worse = True  # the reason names unmapped elements the loader's notes do not
            detail = {**detail, "notes": [*detail.get("notes", []), stale]}
        outcome = "expected-fail" if raw == "fail" and expected == "fail" and not worse else raw
        verdicts.append(Verdict(entry.id, tier, outcome, raw, expected, worse, detail))
    return verdicts


def load_message(reason: str) -> str:
    """A failed load's message on one line: what MuJoCo (or the loader) said, without the worker's prefix."""
    return " ".join(reason.removeprefix("load failed: ").split())


def headline(model_status: str, verdicts: list[Verdict]) -> str:
    """A model's worst outcome in a few words (the progress bar, the terminal summary): worse-than-expected first,
    then the worst raw outcome; a load error shows its message, a divergence its tier and first bad step, a lost
    worker how it was lost (tests/test_conformance_summary.py::test_the_headline_is_the_worst_outcome)."""
    if model_status in ("crashed", "timeout", "pending") or not verdicts:
        return model_status
    worst = max(verdicts, key=lambda v: (v.worse, OUTCOME_RANK[v.raw]))
    if worst.raw == "error":
        text = f"error: {_clip(' '.join(worst.detail.get('notes') or []), 100)}"
        return text if not worst.worse else f"{text} (expected {worst.expected})"
    text = worst.outcome if not worst.worse else f"{worst.outcome} (expected {worst.expected})"
    if worst.outcome == "pass":
        return "pass"
    where = divergence_text(worst.detail.get("divergence"))
    why = why_text(worst)
    return f"{text} in {worst.tier}" + (f" at {where}" if where else "") + (f": {why}" if why else "")


def why_text(v: Verdict, width: int = 140) -> str:
    """Why a tier did not pass, on one line: its worst metric against its tolerance, then the reason (the
    manifest's for an expected outcome, else the tier's first note: a skip's reason, MuJoCo's own spread)."""
    metric = _worst_metric(v.detail.get("metrics") or [])
    parts = [f"{metric['name']} {_fmt(metric['max'])} (tol {_fmt(metric['tolerance'])})"] if metric else []
    reason = v.detail.get("expected_reason") or "" if not v.worse else ""
    notes = v.detail.get("notes") or []
    reason = reason or (notes[0] if notes else "")
    if reason:
        parts.append(reason)
    return _clip("; ".join(parts), width)


def _worst_metric(metrics: list[dict]) -> dict | None:
    """The metric furthest past (or closest to) its tolerance, among those with one."""
    judged = [m for m in metrics if m.get("tolerance") and m.get("max") is not None]
    return max(judged, key=lambda m: m["max"] / m["tolerance"], default=None)


def _clip(text: str, width: int) -> str:
    return text if len(text) <= width else text[: width - 3] + "..."


def _verdicts(m: dict) -> list[Verdict]:
    """A summary document's model back as verdicts."""
    return [
        Verdict(m["id"], t, v["outcome"], v["raw"], v["expected"], v["worse_than_expected"], v)
        for t, v in m["verdicts"].items()
    ]


def _notes_by_kind(load: dict) -> str:
    """A model's loader notes as counts per kind: 'approximated joint 1, geom 45; unsupported tendon 10'."""
    parts = []
    for key, word in (("approximations", "approximated"), ("unsupported", "unsupported")):
        kinds: dict[str, int] = {}
        for note in (load or {}).get(key, []):
            kinds[note["kind"]] = kinds.get(note["kind"], 0) + 1
        if kinds:
            parts.append(f"{word} " + ", ".join(f"{k} {n}" for k, n in kinds.items()))
    return "; ".join(parts)


def terminal(summary: dict, run_dir: Path, verbose: bool = False) -> str:
    """The run on the terminal: one short line per model (its headline, marked where worse than the manifest
    expects, and the loader's notes counted per kind; `verbose`: each note on its own line below), the tally, the
    third-party warnings counted, and where the full report is (summary.md)
    (tests/test_conformance_runner.py::test_the_terminal_gets_one_line_per_model_and_the_file_the_table)."""
    width = max((len(m["id"]) for m in summary["models"]), default=0)
    lines = []
    for m in summary["models"]:
        verdicts = _verdicts(m)
        mark = "WORSE" if any(v.worse for v in verdicts) else "ok"
        notes = _notes_by_kind(m.get("load"))
        lines.append(
            f"{m['id']:<{width}}  {mark:<5}  {headline(m['status'], verdicts)}"
            + (f"  (loader: {notes})" if notes else "")
        )
        if verbose:
            load = m.get("load") or {}
            lines += [
                f"    {word} {n['kind']} '{n['name']}': {n['reason']}"
                for key, word in (("approximations", "approximated"), ("unsupported", "unsupported"))
                for n in load.get(key, [])
            ]
    worse = sum(1 for m in summary["models"] if any(v["worse_than_expected"] for v in m["verdicts"].values()))
    outcomes = len(summary["worse_than_expected"])
    lines.append(
        f"{len(summary['models'])} models, {worse} worse than the manifest expects"
        + (f" ({outcomes} model x tier outcomes, listed in summary.md)" if outcomes else "")
    )
    counts = [sum(m.get("warnings", {}).values()) for m in summary["models"]]
    if sum(counts):
        lines.append(
            f"third-party warnings: {sum(counts)} in {sum(1 for c in counts if c)} models, counted by kind "
            f"in summary.json (MuJoCo's in {run_dir / 'MUJOCO_LOG.TXT'})"
        )
    lines.append(f"report: {run_dir / 'summary.md'} (outcomes and notes explained: reports/README.md)")
    return "\n".join(lines)


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def atomic_write_text(path: Path, text: str) -> None:
    """Write via a temporary file in the same folder and rename: readers see the old or the new file. The file gets
    the mode `open()` would give it (0644 under the usual umask), not mkstemp's private 0600: a report is for
    sharing (tests/test_conformance_runner.py::test_summary_files_are_readable_by_everyone)."""
    atomic_write_bytes(path, text.encode())


def atomic_write_bytes(path: Path, data: bytes) -> None:
    """`atomic_write_text` for bytes (a recording a cluster's worker sent back)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", dir=path.parent)
    try:
        os.fchmod(fd, 0o666 & ~_umask())
        with os.fdopen(fd, "wb") as f:
            f.write(data)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def atomic_write_json(path: Path, data) -> None:
    atomic_write_text(path, json.dumps(data, indent=2, sort_keys=False, allow_nan=False) + "\n")


def point_latest(out_dir: Path, run_dir: Path) -> None:
    """Make `<out>/latest` point at run_dir by renaming a fresh symlink over the old one."""
    link = out_dir / "latest"
    tmp = out_dir / f".latest.{os.getpid()}"
    tmp.unlink(missing_ok=True)
    os.symlink(run_dir.name, tmp)
    os.replace(tmp, link)


def _fmt(x) -> str:
    if x is None:
        return "-"
    return f"{x:.3g}"


def divergence_text(divergence: dict | None) -> str:
    """'<run> step N (t = ... s): <what>' for a tier's first divergent step, or ''."""
    return Divergence(**divergence).text() if divergence else ""


def worst_metric(metrics: list[dict]) -> dict | None:
    """The metric closest to (or furthest past) its tolerance: the largest max / tolerance, a non-finite max (None)
    first; None without metrics."""
    return max(
        metrics,
        key=lambda m: (
            (m["max"] / m["tolerance"])
            if m["max"] is not None and m["tolerance"]
            else (float("inf") if m["max"] is None or m["max"] > 0 else 0.0)
        ),
        default=None,
    )


def _cell(v: Verdict) -> str:
    if v.raw == "error":
        return f"error: {' '.join(v.detail.get('notes') or [])}".replace("|", "\\|")
    if v.detail.get("divergence"):
        return f"{v.outcome}: {divergence_text(v.detail['divergence'])}"
    worst = worst_metric(v.detail.get("metrics") or [])
    if worst is None:
        return v.outcome
    raw = f"raw {_fmt(worst['raw_max'])}, " if worst.get("raw_max") is not None else ""
    return (
        f"{v.outcome}: {worst['name']} {_fmt(worst['max'])} ({raw}tol {_fmt(worst['tolerance'])}, "
        f"margin {_fmt(worst['margin'])})"
    )


def build(
    run: dict, entries: list[ModelEntry], results: dict[str, ModelResult], seeds: dict[str, int] | None = None
) -> dict:
    """The summary document: run metadata, per-model results and verdicts, and the overall judgement. A seed sweep
    gives each entry's seed (`seeds`, by id), recorded beside its id."""
    models, worse, better = [], [], []
    for entry in entries:
        result = results.get(entry.id) or ModelResult(entry.id, "pending", reason="not finished")
        verdicts = judge(entry, result) if result.status != "pending" else []
        worse += [
            f"{v.model}/{v.tier}: {v.raw} (expected {v.expected})" + _why_worse(entry, v) + _metric_why(v)
            for v in verdicts
            if v.worse
        ]
        better += [
            f"{v.model}/{v.tier}: {v.raw} (expected {v.expected})"
            for v in verdicts
            if OUTCOME_RANK[v.raw] < OUTCOME_RANK[v.expected]
        ]
        models.append(
            {
                "id": entry.id,
                **({"seed": seeds[entry.id]} if seeds else {}),
                "source": entry.source,
                "status": result.status,
                "reason": result.reason,
                "recording": result.recording,
                "seconds": result.seconds,
                "settings": result.settings,
                "load": result.load,
                "warnings": result.warnings,
                "verdicts": {
                    v.tier: {
                        "outcome": v.outcome,
                        "raw": v.raw,
                        "expected": v.expected,
                        "expected_reason": entry.expect[v.tier].reason if v.tier in entry.expect else "",
                        "worse_than_expected": v.worse,
                        "metrics": v.detail.get("metrics", []),
                        "notes": v.detail.get("notes", []),
                        "settings": v.detail.get("settings", {}),
                        "isolation": v.detail.get("isolation", []),
                        "divergence": v.detail.get("divergence"),
                    }
                    for v in verdicts
                },
            }
        )
    return {**run, "models": models, "worse_than_expected": worse, "better_than_expected": better, "ok": not worse}


ACTUATED_TIERS = ("actuated", "actuated_contact")


def _actuation_lines(summary: dict) -> list[str]:
    """Per model and actuated tier that ran: the integrator switch, ctrl scaling, steps on a forcerange bound
    and any limit contact that scaling could not avoid."""
    lines = []
    for m in summary["models"]:
        for tier in ACTUATED_TIERS:
            v = m["verdicts"].get(tier)
            settings = (v or {}).get("settings", {})
            if "ctrl_scale" not in settings:
                continue
            parts = []
            if settings.get("integrator_authored") != settings.get("integrator_reference"):
                parts.append(
                    f"MuJoCo {settings.get('integrator_reference')} instead of the authored "
                    f"{settings.get('integrator_authored')}"
                )
            if settings["ctrl_scale"] < 1:
                parts.append(f"ctrl deviations scaled by {settings['ctrl_scale']:g}")
            if settings.get("saturated_steps"):
                parts.append(f"forcerange reached on {settings['saturated_steps']} steps (clamped on both sides)")
            if tier == "actuated" and settings.get("limit_steps"):
                parts.append(f"a joint at its limit on {settings['limit_steps']} steps")
            if parts:
                lines.append(f"- {m['id']}/{tier}: " + "; ".join(parts))
    return lines


def _metric_why(v: Verdict) -> str:
    """A worse verdict's worst metric and the tier's first note, where `_why_worse` has nothing more to say."""
    if v.raw in ("diverged", "changed"):
        return ""
    why = why_text(v, width=300)
    return f": {why}" if why else ""


def _why_worse(entry: ModelEntry, v: Verdict) -> str:
    if v.raw == "diverged":
        return ": " + (divergence_text(v.detail.get("divergence")) or "a metric is not finite")
    if v.raw == "changed":
        return "; " + v.detail["notes"][-1]
    claimed = entry.expect[v.tier].passes_without if v.tier in entry.expect else ()
    return f"; it does not pass without {', '.join(claimed)} as the manifest claims" if claimed else ""


def _run_text(run: dict) -> str:
    if run["outcome"] == "error":
        return f"without {' + '.join(run['without'])}: error ({run['reason']})"
    worst = max(run["metrics"], key=lambda m: (m["max"] or 0) / m["tolerance"] if m["tolerance"] else 0, default=None)
    numbers = f" ({worst['name']} {_fmt(worst['max'])}, tol {_fmt(worst['tolerance'])})" if worst else ""
    return f"without {' + '.join(run['without'])}: {run['outcome']}{numbers}"


def isolation_text(runs: list[dict]) -> str:
    """One line for a tier's isolation runs: each removal, its outcome and its worst metric."""
    return "; ".join(_run_text(r) for r in runs)


def _timestep_order(metrics: list[dict], runs: list[dict]) -> float | None:
    """The order in dt of the one-step velocity error with every other gap out: the run without all physical gaps
    (or the tier itself when it has none) against the same run at half the timestep."""

    def one_step(items):
        return {x["name"]: x["max"] for x in items}.get("one_step_qvel")

    halves = [r for r in runs if "half_timestep" in r["without"]]
    if not halves:
        return None
    half = max(halves, key=lambda r: len(r["without"]))
    others = set(half["without"]) - {"half_timestep"}
    full = next((r for r in runs if set(r["without"]) == others), None) if others else {"metrics": metrics}
    if full is None or one_step(full["metrics"]) is None or one_step(half["metrics"]) is None:
        return None
    return order_in_timestep(one_step(full["metrics"]), one_step(half["metrics"]))


def _isolation_lines(summary: dict) -> list[str]:
    """Per failing dynamics-type tier: the same tier with each known gap removed on both sides."""
    lines = []
    for m in summary["models"]:
        for tier, v in m["verdicts"].items():
            runs = v.get("isolation") or []
            if not runs:
                continue
            parts = [isolation_text(runs)]
            order = _timestep_order(v["metrics"], runs)
            if order is not None:
                parts.append(
                    f"one-step velocity error order in dt, the other gaps removed: {order:.1f} "
                    "(1: a force error, 2: an integration difference)"
                )
            lines.append(f"- {m['id']}/{tier}: " + "; ".join(parts))
    return lines


def _seed_text(summary: dict) -> str:
    seeds = summary.get("seeds")
    return f"seeds {seeds[0]}..{seeds[-1]}" if seeds else f"seed {summary['seed']}"


READMELINK = (
    "What each outcome and note means (`chaotic`, `changed`, `diverged`, `expected-fail`, the ctrl scaling, the "
    "isolation runs): reports/README.md in the project."
)


def markdown(summary: dict, tiers: list[str]) -> str:
    """summary.md: a model x tier table (worst metric max/tolerance per cell), then the failures."""
    lines = [
        f"# Conformance run {summary['run']}",
        "",
        f"{_seed_text(summary)}; " + ", ".join(f"{k} {v}" for k, v in summary["versions"].items()),
        "",
    ]
    if summary.get("interrupted"):
        lines += ["**Interrupted: results below are partial.**", ""]
    lines += ["| model | " + " | ".join(tiers) + " |", "|---" * (len(tiers) + 1) + "|"]
    for m in summary["models"]:
        cells = []
        for t in tiers if LOAD not in m["verdicts"] else [LOAD]:  # a load error: one cell, the rest empty
            v = m["verdicts"].get(t)
            if v is None:
                cells.append("" if m["status"] != "pending" else "pending")
                continue
            text = _cell(Verdict(m["id"], t, v["outcome"], v["raw"], v["expected"], v["worse_than_expected"], v))
            cells.append(("**" + text + "**") if v["worse_than_expected"] else text)
        lines.append(f"| {m['id']} | " + " | ".join(cells + [""] * (len(tiers) - len(cells))) + " |")
    legend = (
        "Cells: outcome, then the metric closest to (or furthest past) its tolerance: max error, tolerance "
        "and margin = tolerance - max (units and every other metric in summary.json); where float32 cannot "
        "resolve part of an error, max is what is left beyond it and raw the error itself."
    )
    lines += ["", legend, "", READMELINK, ""]
    if summary["worse_than_expected"]:
        lines += ["## Worse than the manifest expects", ""] + [f"- {w}" for w in summary["worse_than_expected"]]
    else:
        lines += ["No outcome is worse than the manifest expects."]
    if summary.get("better_than_expected"):
        lines += ["", "## Better than the manifest expects (update its expectations)", ""]
        lines += [f"- {b}" for b in summary["better_than_expected"]]
    notes = [(m["id"], m["status"], m["reason"]) for m in summary["models"] if m["reason"]]
    if notes:
        lines += ["", "## Model notes", ""] + [f"- {i} ({s}): {r}" for i, s, r in notes]
    actuation = _actuation_lines(summary)
    if actuation:
        lines += ["", "## Actuated tiers: what the ctrl and MuJoCo's integrator were", ""] + actuation
    isolation = _isolation_lines(summary)
    if isolation:
        lines += ["", "## Isolation: failing tiers rerun with each known gap removed on both sides", ""] + isolation
    gaps = [
        (m["id"], t, v["raw"], v["expected_reason"])
        for m in summary["models"]
        for t, v in m["verdicts"].items()
        if v["expected_reason"]
    ]
    if gaps:
        lines += ["", "## Known gaps (from the manifest)", ""] + [
            f"- {i}/{t} ({raw}): {why}" for i, t, raw, why in gaps
        ]
    return "\n".join(lines) + "\n"

"""`run --compare A,B`: the same models and tiers judged for several loaders, side by side. Each loader's run is a
folder of its own inside the comparison's (`<run>/<loader>/`, a full run with its summary); `compare.json` and
`compare.md` put, per model and tier, every loader's outcome and its main metric (the one closest to or furthest
past its tolerance) next to each other, and tally the outcomes per loader. Outcomes are the raw ones: the manifest's
expectations describe this project's loader only."""

from __future__ import annotations

import secrets
from dataclasses import replace
from datetime import datetime, timezone
from pathlib import Path

from . import summary
from .manifest import LOAD, TIER_NAMES, ModelEntry
from .runner import RunOptions, run


def _side(model: dict, tier: str) -> dict:
    """One loader's outcome on one model and tier: outcome, main metric (name, max, tolerance) and first note."""
    if model["status"] in ("crashed", "timeout", "pending", "skipped"):
        return {"outcome": model["status"], "note": model.get("reason", "")}
    verdicts = model["verdicts"]
    v = verdicts.get(LOAD) or verdicts.get(tier)
    if v is None:
        return {"outcome": "not run", "note": ""}
    out = {"outcome": v["raw"], "note": (v.get("notes") or [""])[0]}
    worst = summary.worst_metric(v.get("metrics") or [])
    if worst is not None:
        out.update(metric=worst["name"], max=worst["max"], tolerance=worst["tolerance"])
    return out


def _passes(model: dict, loader: str) -> bool:
    """Whether every tier that ran on the model passed (chaotic: MuJoCo cannot predict itself), at least one."""
    outcomes = [c[loader]["outcome"] for c in model["tiers"].values()]
    return "pass" in outcomes and all(o in ("pass", "skipped", "chaotic") for o in outcomes)


def build(docs: dict[str, dict], name: str) -> dict:
    """The comparison document from each loader's summary document (by loader name, in column order)."""
    loaders = list(docs)
    tiers = [t for t in TIER_NAMES if any(t in d["tiers"] for d in docs.values())]
    by_id = {loader: {m["id"]: m for m in doc["models"]} for loader, doc in docs.items()}
    ids = [m["id"] for m in docs[loaders[0]]["models"]]
    models, tally = [], {loader: {} for loader in loaders}
    for mid in ids:
        cells = {}
        for tier in tiers:
            cells[tier] = {loader: _side(by_id[loader][mid], tier) for loader in loaders}
            for loader, side in cells[tier].items():
                tally[loader][side["outcome"]] = tally[loader].get(side["outcome"], 0) + 1
        models.append(
            {"id": mid, "status": {loader: by_id[loader][mid]["status"] for loader in loaders}, "tiers": cells}
        )
    passing = {loader: sum(1 for m in models if _passes(m, loader)) for loader in loaders}
    return {
        "run": name,
        "loaders": loaders,
        "tiers": tiers,
        "versions": {k: v for d in docs.values() for k, v in d["versions"].items()},
        "seed": docs[loaders[0]]["seed"],
        "models": models,
        "tally": tally,
        "models_passing": passing,
    }


def _fmt(x) -> str:
    return "-" if x is None else f"{x:.3g}"


def _clip(text: str, width: int = 160) -> str:
    text = " ".join(text.removeprefix("load failed: ").split())
    return text if len(text) <= width else text[: width - 3] + "..."


def _text(side: dict) -> str:
    if side["outcome"] in ("fail", "diverged", "changed") and side.get("metric"):
        return f"{side['outcome']}: {side['metric']} {_fmt(side['max'])} (tol {_fmt(side['tolerance'])})"
    return side["outcome"]


def markdown(doc: dict) -> str:
    """compare.md: one row per model, one column per tier, each cell every loader's outcome (A / B)."""
    loaders, tiers = doc["loaders"], doc["tiers"]
    lines = [
        f"# Loaders compared: {' / '.join(loaders)} ({doc['run']})",
        "",
        f"seed {doc['seed']}; " + ", ".join(f"{k} {v}" for k, v in doc["versions"].items()),
        "",
        "| model | " + " | ".join(tiers) + " |",
        "|---" * (len(tiers) + 1) + "|",
    ]
    for m in doc["models"]:
        cells = [" / ".join(_text(m["tiers"][t][loader]) for loader in loaders).replace("|", "\\|") for t in tiers]
        lines.append(f"| {m['id']} | " + " | ".join(cells) + " |")
    legend = (
        f"Cells: {' / '.join(loaders)}, each its outcome; a failure with its metric furthest past its "
        "tolerance (max and tolerance; every metric in each loader's summary.json)."
    )
    lines += ["", legend, ""]
    for loader in loaders:
        counts = ", ".join(f"{k} {v}" for k, v in sorted(doc["tally"][loader].items()))
        lines.append(
            f"- {loader}: {doc['models_passing'][loader]} of {len(doc['models'])} models pass every tier "
            f"that ran; model x tier: {counts}"
        )
    errors = [
        (loader, m["id"], c[loader]["note"])
        for m in doc["models"]
        for loader in loaders
        for c in list(m["tiers"].values())[:1]
        if c[loader]["outcome"] == "error"
    ]
    if errors:
        lines += ["", "## Not loaded", ""] + [f"- {loader}/{mid}: {_clip(note)}" for loader, mid, note in errors]
    skips: dict[tuple[str, str], dict[str, int]] = {}
    for m in doc["models"]:
        for tier, cell in m["tiers"].items():
            for loader in loaders:
                if cell[loader]["outcome"] == "skipped":
                    tiers = skips.setdefault((loader, cell[loader]["note"]), {})
                    tiers[tier] = tiers.get(tier, 0) + 1
    if skips:
        lines += ["", "## Skipped, and why (tier: models)", ""]
        lines += [
            f"- {loader}: {note} ({', '.join(f'{t}: {n}' for t, n in tiers.items())})"
            for (loader, note), tiers in sorted(skips.items())
        ]
    return "\n".join(lines) + "\n"


def new_compare_dir(out: Path, name: str | None) -> Path:
    stamp = datetime.now(timezone.utc).strftime("%Y%m%dT%H%M%SZ")
    folder = out / (name or f"{stamp}-compare-{secrets.token_hex(2)}")
    folder.mkdir(parents=True, exist_ok=False)
    return folder


def compare(entries: list[ModelEntry], options: RunOptions, loaders: list[str]) -> tuple[Path, dict, dict]:
    """Run every loader over the entries, each into `<folder>/<loader>/`; write compare.json and compare.md.
    Returns the folder, the comparison and each loader's summary document."""
    out = Path(options.out)
    folder = new_compare_dir(out, options.run_name)
    docs = {}
    for loader in loaders:
        _, docs[loader] = run(entries, replace(options, out=folder, run_name=loader, loader=loader))
    (folder / "latest").unlink(missing_ok=True)  # each run pointed it at itself: the folders are named
    doc = build(docs, folder.name)
    summary.atomic_write_json(folder / "compare.json", doc)
    summary.atomic_write_text(folder / "compare.md", markdown(doc))
    summary.point_latest(out, folder)
    return folder, doc, docs

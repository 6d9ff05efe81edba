"""The corpus manifest (TOML): which models run, which tiers, per-model overrides and expected outcomes."""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from pathlib import Path

import tomllib

from .gaps import GAPS
from .isolation import ISOLATED_TIERS
from .session import OWN_LOADERS

TIER_NAMES = (
    "structure",
    "kinematics",
    "inertia",
    "collision",
    "contact",
    "actuated_contact",
    "actuated",
    "dynamics",
    "maniskill",
    "maniskill_tensor",
)
# run only when asked (`--tiers`, a model's `tiers`): they need the maniskill extra
OPTIONAL_TIERS = ("maniskill", "maniskill_tensor")
DEFAULT_TIERS = tuple(t for t in TIER_NAMES if t not in OPTIONAL_TIERS)
# Outcomes ranked from best to worst; a run fails when an outcome ranks worse than the manifest expects.
# `changed` (an expected failure whose metric left the band its reason was measured in) and `diverged` (SAPIEN left
# the finite, physical states: conformance/divergence.py) come from the run alone: no manifest may expect them.
# `error` (the model did not load) is one outcome for the whole model, on the pseudo-tier `load`: a manifest expects
# it with `tier = "load"`, and nothing else on that tier.
OUTCOME_RANK = {"pass": 0, "chaotic": 1, "skipped": 2, "fail": 3, "error": 4, "changed": 5, "diverged": 6}
EXPECTABLE = ("pass", "chaotic", "skipped", "fail", "error")
LOAD = "load"
# An expected failure stays the failure its reason describes while its metric's max lies within this factor of the
# value `seen` when the reason was written; outside it the outcome is `changed` until the reason is re-measured.
BAND_FACTOR = 10.0
FAULTS = ("crash", "hang", "nan")  # harness self-tests: a worker that segfaults, hangs, or whose SAPIEN goes NaN


@dataclass(frozen=True)
class Expectation:
    """The outcome a tier is known to reach on a model (a known gap), and why."""

    tier: str
    outcome: str
    reason: str
    # gaps (conformance.gaps.GAPS) whose removal on both sides makes the tier pass: checked on every run
    passes_without: tuple[str, ...] = ()
    # an expected failure: the metric its reason describes and the max measured then (checked every run: `band`);
    # `seen = [low, high]` in the manifest: the range measured over several seeds
    metric: str = ""
    seen: float = 0.0
    seen_high: float = 0.0
    # the seeds the expectation holds at (empty: every seed); at the others the tier is expected to pass
    seeds: tuple[int, ...] = ()
    # the one of this project's loaders it holds for (`session.OWN_LOADERS`; empty: each), where the other passes:
    # "terms" for a gap of the per-step terms that MuJoCo's own step, the default's law on the model, does not have
    loader: str = ""

    @property
    def band(self) -> tuple[float, float]:
        """The values of `metric` the failure may take and still be the one its reason describes."""
        return self.seen / BAND_FACTOR, max(self.seen, self.seen_high) * BAND_FACTOR

    @property
    def seen_text(self) -> str:
        return f"{self.seen:.3g}" if self.seen_high <= self.seen else f"{self.seen:.3g}..{self.seen_high:.3g}"


@dataclass(frozen=True)
class ModelEntry:
    """One corpus model."""

    id: str
    # "dm_control:<file>", "menagerie:<path>", "package:<package>/<path inside it>", "fixture:<path relative to the
    # manifest>" or a path
    source: str
    tiers: tuple[str, ...] = DEFAULT_TIERS
    timeout_s: float = 300.0
    tolerances: dict[str, float] = field(default_factory=dict)
    settings: dict[str, dict] = field(default_factory=dict)
    override_reason: str = ""
    expect: dict[str, Expectation] = field(default_factory=dict)
    # a tier's further expectations, each scoped to seeds none of the tier's others hold at (`at_seed` picks)
    scoped: tuple[Expectation, ...] = ()
    fault: str | None = None  # harness self-test only: make the worker crash, hang or poison SAPIEN's state
    base_dir: str = "."
    # from a manifest, whose expectations name every skip; False for a file given on the command line, where a tier
    # the model itself rules out (no actuators) is skipped without being worse
    listed: bool = True

    def expected(self, tier: str) -> str:
        exp = self.expect.get(tier)
        return exp.outcome if exp else "pass"

    def at_seed(self, seed: int) -> ModelEntry:
        """The entry as judged at `seed`: expectations scoped to other seeds dropped
        (tests/test_conformance_summary.py::test_an_expectation_scoped_to_seeds_holds_only_there)."""
        expect = {t: e for t, e in self.expect.items() if not e.seeds or seed in e.seeds}
        expect.update({e.tier: e for e in self.scoped if seed in e.seeds})
        return replace(self, expect=expect, scoped=())


@dataclass(frozen=True)
class Manifest:
    path: str
    models: tuple[ModelEntry, ...]

    def select(self, ids: list[str] | None) -> list[ModelEntry]:
        if not ids:
            return list(self.models)
        known = {m.id: m for m in self.models}
        unknown = [i for i in ids if i not in known]
        if unknown:
            raise ValueError(f"{self.path}: no model {unknown}; known: {sorted(known)}")
        return [known[i] for i in ids]


def _entry(raw: dict, defaults: dict, where: str, base_dir: str) -> ModelEntry:
    for key in ("id", "source"):
        if key not in raw:
            raise ValueError(f"{where}: model entry lacks {key!r}")
    tiers = tuple(raw.get("tiers", defaults.get("tiers", DEFAULT_TIERS)))
    bad = [t for t in tiers if t not in TIER_NAMES]
    if bad:
        raise ValueError(f"{where}: model {raw['id']!r} names unknown tiers {bad}; known: {list(TIER_NAMES)}")
    override = raw.get("override", {})
    if override and not override.get("reason"):
        raise ValueError(f"{where}: model {raw['id']!r} overrides without a reason")
    expect, scoped = _expectations(raw, where)
    fault = raw.get("fault")
    if fault is not None and fault not in FAULTS:
        raise ValueError(f"{where}: model {raw['id']!r} fault must be one of {FAULTS}")
    return ModelEntry(
        id=str(raw["id"]),
        source=str(raw["source"]),
        tiers=tiers,
        timeout_s=float(raw.get("timeout_s", defaults.get("timeout_s", 300.0))),
        tolerances=dict(override.get("tolerances", {})),
        settings={k: dict(v) for k, v in override.get("settings", {}).items()},
        override_reason=str(override.get("reason", "")),
        expect=expect,
        scoped=scoped,
        fault=fault,
        base_dir=base_dir,
    )


def _expectations(raw: dict, where: str) -> tuple[dict[str, Expectation], tuple[Expectation, ...]]:
    """A model entry's expectations by tier, and those that scope a tier again to other seeds (every one of a
    tier's expectations then names its seeds, none shared); the opt-in tiers inherit the `actuated` one unless they
    have their own."""
    expect: dict[str, Expectation] = {}
    scoped: list[Expectation] = []
    for exp in raw.get("expect", []):
        found = _expectation(exp, raw["id"], where)
        earlier = [e for e in (expect.get(found.tier), *scoped) if e is not None and e.tier == found.tier]
        if not earlier:
            expect[found.tier] = found
            continue
        if not found.seeds or any(not e.seeds or set(e.seeds) & set(found.seeds) for e in earlier):
            raise ValueError(
                f"{where}: model {raw['id']!r} tier {found.tier!r} is expected twice: a tier's expectations must "
                "each name their seeds, none shared"
            )
        scoped.append(found)
    for tier in OPTIONAL_TIERS:  # the same rollout through ManiSkill: the same known gap, unless it has its own
        if "actuated" in expect and tier not in expect:
            known = expect["actuated"]
            expect[tier] = replace(known, tier=tier, reason=f"as actuated: {known.reason}", passes_without=())
    return expect, tuple(scoped)


def _expectation(exp: dict, model_id: object, where: str) -> Expectation:
    """One `[[model.expect]]` table, checked: tier and outcome (a load error on `load` only), an expected failure's
    metric and `seen` band, `passes_without` gaps and `seeds`."""
    tier, outcome, reason = exp.get("tier"), exp.get("outcome"), exp.get("reason")
    if tier not in (*TIER_NAMES, LOAD) or outcome not in EXPECTABLE or not reason:
        raise ValueError(
            f"{where}: model {model_id!r} has a bad expectation {exp} "
            f"(needs tier in {TIER_NAMES}, outcome in {list(EXPECTABLE)}, reason)"
        )
    if (tier == LOAD) != (outcome == "error"):
        raise ValueError(
            f"{where}: model {model_id!r}: a load error is expected as tier = {LOAD!r}, "
            f"outcome = 'error' (and only so), not {exp}"
        )
    seen = _seen_band(exp, model_id, where)
    claimed = tuple(exp.get("passes_without", ()))
    unknown = [g for g in claimed if g not in GAPS]
    if unknown or (claimed and (tier not in ISOLATED_TIERS or outcome != "fail")):
        raise ValueError(
            f"{where}: model {model_id!r} tier {tier!r}: passes_without {list(claimed)} needs "
            f"gaps from {list(GAPS)} on a 'fail' expectation of {list(ISOLATED_TIERS)}"
        )
    seeds = exp.get("seeds", [])
    if not (isinstance(seeds, list) and all(isinstance(x, int) and not isinstance(x, bool) for x in seeds)):
        raise ValueError(f"{where}: model {model_id!r} tier {tier!r}: seeds is a list of integers, not {seeds!r}")
    loader = exp.get("loader", "")
    if loader and loader not in OWN_LOADERS:
        raise ValueError(
            f"{where}: model {model_id!r} tier {tier!r}: loader {loader!r} is one of {list(OWN_LOADERS)} (this "
            "project's loader by its set_ctrl law), or left out for both"
        )
    return Expectation(
        tier,
        outcome,
        reason,
        claimed,
        str(exp.get("metric", "")),
        float(seen[0] or 0.0),
        float(seen[1] or 0.0),
        tuple(seeds),
        loader,
    )


def _seen_band(exp: dict, model_id: object, where: str) -> tuple:
    """An expectation's `seen` as (low, high); an expected failure needs its metric and a positive, ordered `seen`."""
    seen = exp.get("seen")
    seen = tuple(seen) if isinstance(seen, list) and len(seen) == 2 else (seen, seen)
    if exp.get("outcome") == "fail" and not (
        exp.get("metric") and all(isinstance(x, (int, float)) and x > 0 for x in seen) and seen[0] <= seen[1]
    ):
        raise ValueError(
            f"{where}: model {model_id!r} tier {exp.get('tier')!r}: an expected failure names the `metric` its "
            "reason describes and the positive max `seen` when it was measured, or [low, high] over seeds "
            "(the run checks "
            f"that the failure stays within {BAND_FACTOR:g}x of it)"
        )
    return seen


def load(path: str | Path) -> Manifest:
    """Parse a manifest file; errors name the file and the offending entry. `include = ["other.toml"]` (paths
    relative to this file) puts the other manifests' models first: a named corpus extends the default one."""
    path = Path(path)
    data = tomllib.loads(path.read_text())
    defaults = data.get("defaults", {})
    models = [m for other in data.get("include", []) for m in load(path.parent / other).models]
    models += [_entry(raw, defaults, str(path), str(path.parent.resolve())) for raw in data.get("model", [])]
    ids = [m.id for m in models]
    dupes = sorted({i for i in ids if ids.count(i) > 1})
    if dupes:
        raise ValueError(f"{path}: duplicate model ids {dupes}")
    return Manifest(str(path), tuple(models))


def expand_paths(paths: list[str]) -> list[Path]:
    """Command-line MJCF paths: a folder stands for the `.xml` files in it (sorted); a path that does not exist is
    a usage error (ValueError naming it), before anything runs."""
    out: list[Path] = []
    for p in paths:
        path = Path(p)
        if path.is_dir():
            found = sorted(path.glob("*.xml"))
            if not found:
                raise ValueError(f"{p}: a folder without .xml files")
            out += found
        elif path.is_file():
            out.append(path)
        else:
            raise ValueError(f"{p}: no such file or folder")
    return out


# File stems that name a role, not a robot (Menagerie's scene.xml beside every robot): the folder names the model
GENERIC_STEMS = ("robot", "scene", "model", "main", "mjmodel", "index")


def from_paths(
    paths: list[str],
    tiers: tuple[str, ...] = DEFAULT_TIERS,
    timeout_s: float = 300.0,
    known: dict[Path, ModelEntry] | None = None,
) -> Manifest:
    """An ad-hoc manifest for MJCF files given on the command line. A file that is a manifest model (`known`: its
    resolved path -> entry) is that entry, with its id, tiers and expectations; any other file expects every tier to
    pass or be skipped for the model's own reason (`listed`) and is named by its stem, or by its parent folder where
    the stem is generic (`GENERIC_STEMS`) or repeats
    (tests/test_conformance_manifest.py::test_command_line_paths_become_entries_named_by_their_folder_where_stems_repeat)."""
    files = expand_paths(paths)
    known = known or {}
    stems = [f.stem for f in files]
    models, seen = [], set()
    for f in files:
        entry = known.get(f.resolve())
        if entry is not None:
            base = entry.id
        elif f.stem.lower() in GENERIC_STEMS or stems.count(f.stem) > 1:
            base = f.resolve().parent.name or f.stem
        else:
            base = f.stem
        mid, n = base, 1
        while mid in seen:
            n += 1
            mid = f"{base}_{n}"
        seen.add(mid)
        if entry is not None:
            models.append(replace(entry, id=mid))
        else:
            models.append(ModelEntry(id=mid, source=str(f.resolve()), tiers=tiers, timeout_s=timeout_s, listed=False))
    return Manifest("<command line>", tuple(models))

"""`python -m conformance run|bench|robustness|where|table`: the command line of the harness."""

from __future__ import annotations

import argparse
import importlib.util
import sys
from pathlib import Path

from . import manifest as manifest_mod
from .manifest import OPTIONAL_TIERS, TIER_NAMES
from .versions import project_version


def _default_manifest() -> Path:
    """The corpus's manifest: the checkout's, or the installed package's copy."""
    from .corpus import corpus_root

    return corpus_root() / "manifest.toml"


DEFAULT_MANIFEST = _default_manifest()


def _needs_maniskill(what: str) -> None:
    """A usage error naming the `maniskill` extra where ManiSkill is not installed."""
    if importlib.util.find_spec("mani_skill") is None:
        raise argparse.ArgumentTypeError(
            f"{what} needs the maniskill extra: pip install 'mjcf-sapien[maniskill]' (from a clone: "
            "`pipx run nox -s maniskill` makes an environment with it)"
        )


def _tiers(text: str) -> tuple[str, ...]:
    tiers = tuple(t.strip() for t in text.split(",") if t.strip())
    bad = [t for t in tiers if t not in TIER_NAMES]
    if bad:
        raise argparse.ArgumentTypeError(f"unknown tiers {bad}; choose from {','.join(TIER_NAMES)}")
    for tier in (t for t in tiers if t in OPTIONAL_TIERS):
        _needs_maniskill(f"the {tier} tier")
    return tiers


def _seeds(text: str) -> tuple[int, ...]:
    first, sep, last = text.partition("..")
    try:
        low, high = int(first), int(last)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r}: give an inclusive range A..B of integers, e.g. 0..3") from None
    if not sep or high < low:
        raise argparse.ArgumentTypeError(f"{text!r}: give an inclusive range A..B with A <= B, e.g. 0..3")
    return tuple(range(low, high + 1))


def _loader(text: str) -> str:
    from .loaders import LOADERS

    if text not in LOADERS:
        raise argparse.ArgumentTypeError(f"unknown loader {text!r}; choose from {', '.join(LOADERS)}")
    if text == "maniskill":
        _needs_maniskill("the maniskill loader")
    return text


def _loaders(text: str) -> tuple[str, ...]:
    names = tuple(_loader(t.strip()) for t in text.split(",") if t.strip())
    if len(set(names)) < 2 or len(set(names)) != len(names):
        raise argparse.ArgumentTypeError(f"{text!r}: name two or more different loaders, e.g. ours,maniskill")
    return names


def _executor(text: str) -> str:
    from .executors import make

    try:
        make(text)  # an unknown executor, or Ray not installed: a usage error before anything runs
    except ValueError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None
    return text


class _Defaults(argparse.HelpFormatter):
    """Help that shows every option's default, where it has one (not None, False or an empty list)."""

    def _get_help_string(self, action):
        text = action.help or ""
        default = action.default
        if (
            action.option_strings
            and "(default" not in text
            and not (default is None or default is False or default == [] or default == argparse.SUPPRESS)
        ):
            text += " (default: %(default)s)"
        return text


def parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="python -m conformance", description="MuJoCo vs SAPIEN conformance harness")
    p.add_argument("--version", action="version", version=project_version())
    sub = p.add_subparsers(dest="command", required=True)
    defaults = _Defaults
    run = sub.add_parser(
        "run",
        help="run the tiers over the manifest or over MJCF files",
        formatter_class=defaults,
        description="Exit status: 0 when no outcome is worse than the manifest expects, 1 when one "
        "is, 2 for a usage error (nothing is written), 130 when interrupted.",
    )
    run.add_argument(
        "paths",
        nargs="*",
        help="MJCF files or folders of them to check instead of the manifest's "
        "models (a manifest model's file keeps its expectations)",
    )
    run.add_argument(
        "--corpus",
        default=None,
        help="a named corpus beside the default one: corpus/<NAME>.toml "
        "(full: the default corpus and more real robots, from the robots extra)",
    )
    run.add_argument("--manifest", default=str(DEFAULT_MANIFEST), help="corpus manifest (TOML)")
    run.add_argument("--model", action="append", default=[], help="only this manifest model id (repeatable)")
    run.add_argument(
        "--tiers",
        type=_tiers,
        default=None,
        help=f"comma-separated subset of {','.join(TIER_NAMES)} (default: the manifest's tiers of each model; "
        "the opt-in maniskill and maniskill_tensor tiers only when named)",
    )
    run.add_argument(
        "--loader",
        type=_loader,
        default=None,
        help="the loader judged: ours (this project's, the "
        "default: its joint forces from MuJoCo's own step where the model allows), terms (ours, its per-step terms "
        "on every model), physx (ours without set_ctrl) or maniskill (ManiSkill's own MJCF loader; the maniskill "
        "extra)",
    )
    run.add_argument(
        "--compare",
        type=_loaders,
        default=None,
        metavar="A,B",
        help="run each loader and write "
        "compare.md and compare.json (per model and tier, every loader's outcome and main metric) "
        "beside each loader's own run folder",
    )
    run.add_argument("--seed", type=int, default=0, help="seed of configurations and commands")
    run.add_argument(
        "--seeds",
        type=_seeds,
        default=(),
        metavar="A..B",
        help="a sweep instead of --seed: every model once per seed from A to B (inclusive), its id suffixed @seed<N>",
    )
    run.add_argument(
        "--out",
        default="reports",
        help="folder that receives one <run>/ folder per run (summary.md, "
        "summary.json, recordings) and the link latest",
    )
    run.add_argument(
        "--keep",
        type=int,
        default=10,
        help="the newest runs kept in --out; older ones are deleted after the run (0: keep every run)",
    )
    run.add_argument("--jobs", type=int, default=0, help="worker processes (0: all cores)")
    run.add_argument(
        "--executor",
        type=_executor,
        default="local",
        help="where the jobs run: local (worker "
        "processes), ray (a new local Ray instance), ray://HOST:PORT (a Ray cluster through Ray Client) or "
        "ray:auto (the Ray cluster this machine is part of); Ray needs the ray extra",
    )
    run.add_argument("--timeout-scale", type=float, default=1.0, help="multiply every model's timeout")
    run.add_argument("--tolerances", default=None, help="tolerance file (default: the packaged one)")
    run.add_argument("--no-record", action="store_true", help="skip the .rrd recordings")
    run.add_argument(
        "--visual-meshes",
        action="store_true",
        help="recordings also draw MuJoCo's visual-only geoms (default: collision geoms)",
    )
    run.add_argument("--quiet", action="store_true", help="no progress bar")
    run.add_argument(
        "-v",
        "--verbose",
        action="store_true",
        help="each of the loader's notes under its model (without: counted per kind on the model's line)",
    )
    bench = sub.add_parser(
        "bench", help="loader time vs MuJoCo compile time, harness steps per second", formatter_class=defaults
    )
    bench.add_argument("paths", nargs="*", help="MJCF files or folders of them instead of the manifest's models")
    bench.add_argument("--manifest", default=str(DEFAULT_MANIFEST), help="corpus manifest (TOML)")
    bench.add_argument("--model", action="append", default=[], help="only this manifest model id (repeatable)")
    bench.add_argument("--out", default=str(Path("reports") / "bench.json"), help="JSON report")
    bench.add_argument("--steps", type=int, default=200, help="simulated steps per model")
    bench.add_argument("--repeats", type=int, default=5, help="loads and compiles per model, cold and warm (median)")
    throughput = sub.add_parser(
        "maniskill-bench",
        help="ManiSkill Empty-v1 physics steps per second: mujoco_ctrl against pd_joint_pos (the maniskill extra)",
        formatter_class=defaults,
    )
    throughput.add_argument("--out", default=str(Path("reports") / "maniskill_bench.json"), help="JSON report")
    throughput.add_argument("--steps", type=int, default=100, help="control steps per robot and mode, over the rounds")
    made = sub.add_parser(
        "table",
        help="README's results table from runs (their folders or summary.json files; a row each, named after the "
        "loader the run judged); --check FILE: exit 1 where FILE's table is not the runs'",
        formatter_class=defaults,
    )
    made.add_argument(
        "runs", nargs="*", default=[str(Path("reports") / "latest")], help="run folders or summary.json files"
    )
    made.add_argument("--check", default=None, help="a document holding the table (README.md)")
    where = sub.add_parser(
        "where",
        help="print the file of a corpus model (a manifest id of the default or full corpus, or a source such as "
        "franka_emika_panda/panda.xml)",
        formatter_class=defaults,
    )
    where.add_argument("names", nargs="+", help="manifest ids or sources")
    robust = sub.add_parser(
        "robustness",
        help="mutants of the corpus's real files, each loaded and stepped in its "
        "own process; exit 1 on any bad outcome",
        formatter_class=defaults,
    )
    robust.add_argument("--mutants", type=int, default=1000, help="how many mutants")
    robust.add_argument("--seed", type=int, default=0, help="seed of the mutations and the random ctrl")
    robust.add_argument("--manifest", default=str(DEFAULT_MANIFEST), help="corpus whose files are mutated")
    robust.add_argument("--model", action="append", default=[], help="only this manifest model id (repeatable)")
    robust.add_argument("--jobs", type=int, default=0, help="processes at once (0: all cores)")
    robust.add_argument("--out", default=str(Path("reports") / "robustness.json"), help="JSON report")
    robust.add_argument(
        "--save",
        default=None,
        help="folder for shrunk bad mutants (e.g. corpus/regressions/mutants); default: not saved",
    )
    robust.add_argument("--quiet", action="store_true", help="no progress lines")
    return p


def _known(manifest_path: str) -> dict[Path, manifest_mod.ModelEntry]:
    """The manifest's models by resolved file (the first healthy entry of a file: not a harness self-test fault)."""
    from .corpus import resolve

    if not Path(manifest_path).is_file():
        return {}
    known: dict[Path, manifest_mod.ModelEntry] = {}
    for entry in manifest_mod.load(manifest_path).models:
        path = resolve(entry).path
        if path is not None and entry.fault is None:
            known.setdefault(path.resolve(), entry)
    return known


def _entries(args) -> list:
    if getattr(args, "paths", None) and getattr(args, "model", None):
        raise ValueError(
            f"--model {' '.join(args.model)} picks manifest models and the paths pick files: give one "
            "or the other (a path that is a manifest model's file keeps its expectations)"
        )
    if getattr(args, "corpus", None):
        named = Path(args.manifest).parent / f"{args.corpus}.toml"
        if not named.is_file():
            known = sorted(p.stem for p in named.parent.glob("*.toml") if p.stem != "manifest")
            raise ValueError(f"no corpus {args.corpus!r}: no {named}; named corpora: {', '.join(known) or 'none'}")
        args.manifest = str(named)
    if getattr(args, "paths", None):  # a file that is a manifest model keeps its expectations
        return list(manifest_mod.from_paths(args.paths, known=_known(args.manifest)).models)
    return manifest_mod.load(args.manifest).select(args.model)


def _chosen_loaders(args) -> tuple[str, ...]:
    """The loaders the run judges (one, or those of --compare); a usage error when one cannot run here."""
    from .loaders import DEFAULT, missing

    if args.compare and args.loader:
        raise ValueError(f"--loader {args.loader} and --compare {','.join(args.compare)}: give one or the other")
    names = args.compare or (args.loader or DEFAULT,)
    for name in names:
        why = missing(name)
        if why:
            raise ValueError(why)
    return names


def cmd_run(args) -> int:
    from . import summary
    from .runner import RunOptions, run

    loaders = _chosen_loaders(args)
    entries = _entries(args)
    if args.seeds and args.seed:
        raise ValueError(f"--seed {args.seed} and --seeds {args.seeds[0]}..{args.seeds[-1]}: give one or the other")
    options = RunOptions(
        out=Path(args.out),
        seed=args.seed,
        seeds=args.seeds,
        executor=args.executor,
        jobs=args.jobs,
        tiers=args.tiers,
        tolerance_file=args.tolerances,
        timeout_scale=args.timeout_scale,
        progress=not args.quiet,
        record=not args.no_record,
        visual_meshes=args.visual_meshes,
        loader=loaders[0],
        keep=args.keep,
        extra={"manifest": args.manifest if not args.paths else None},
    )
    if args.compare:
        return _cmd_compare(entries, options, loaders)
    try:
        run_dir, doc = run(entries, options)
    except KeyboardInterrupt:
        print("interrupted: partial summary written", file=sys.stderr)
        return 130
    print(summary.terminal(doc, run_dir, verbose=args.verbose))
    return 0 if doc["ok"] else 1


def _cmd_compare(entries, options, loaders: tuple[str, ...]) -> int:
    """Exit status: the first loader's run judged against the manifest (0 or 1), 130 when interrupted."""
    from .compare import compare

    try:
        folder, doc, docs = compare(entries, options, list(loaders))
    except KeyboardInterrupt:
        print("interrupted: the runs finished so far are written", file=sys.stderr)
        return 130
    for loader in loaders:
        counts = ", ".join(f"{k} {v}" for k, v in sorted(doc["tally"][loader].items()))
        print(
            f"{loader}: {doc['models_passing'][loader]} of {len(doc['models'])} models pass every tier that ran; "
            f"model x tier: {counts}; {folder / loader / 'summary.md'}"
        )
    print(f"report: {folder / 'compare.md'}")
    first = docs[loaders[0]]
    if not first["ok"]:
        print(
            f"{loaders[0]}: {len(first['worse_than_expected'])} outcome(s) worse than the manifest expects",
            file=sys.stderr,
        )
        return 1
    return 0


def cmd_bench(args) -> int:
    from .bench import bench

    doc = bench(_entries(args), Path(args.out), steps=args.steps, repeats=args.repeats)
    over = doc["totals"]["over_target"]
    print(
        f"bench: {args.out} ({len(doc['models'])} models); load over compile above {doc['target_load_over_compile']}: "
        f"cold {', '.join(over['cold']) or 'none'}; warm {', '.join(over['warm']) or 'none'}"
    )
    return 0


def cmd_maniskill_bench(args) -> int:
    from .maniskill_bench import maniskill_bench

    doc = maniskill_bench(Path(args.out), control_steps=args.steps)
    for name, row in doc["robots"].items():
        if "skipped" in row:
            print(f"{name}: skipped, {row['skipped']}")
        else:
            print(
                f"{name}: mujoco_ctrl {row['mujoco_ctrl']:.0f}, pd_joint_pos {row['pd_joint_pos']:.0f} physics "
                f"steps/s at {row['sim_freq']} Hz (ratio {row['ratio']:.2f})"
            )
            gpu = row.get("gpu", {})
            print(f"  physx_cuda: {gpu['skipped']}" if "skipped" in gpu else f"  physx_cuda: {gpu}")
    print(f"maniskill-bench: {args.out}")
    return 0


def cmd_robustness(args) -> int:
    import json
    import os

    from .robustness.session import print_progress, run, sources_of
    from .versions import versions

    sources = sources_of(_entries(args))
    if not sources:
        raise ValueError(f"no source file of {args.manifest} is installed")
    tally = run(
        sources,
        args.mutants,
        seed=args.seed,
        jobs=args.jobs or os.cpu_count() or 1,
        save=Path(args.save) if args.save else None,
        progress=None if args.quiet else print_progress(args.mutants),
    )
    doc = {"seed": args.seed, "sources": [s.source for s in sources], "versions": versions(), **tally.to_dict()}
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(doc, indent=1) + "\n")
    counts = ", ".join(f"{k} {v}" for k, v in doc["outcomes"].items())
    if doc["interrupted"]:
        print(f"robustness: interrupted after {doc['mutants']} of {args.mutants} mutants; the report holds those")
    print(
        f"robustness: {doc['mutants']} mutants of {len(sources)} files in {doc['seconds']} s "
        f"({doc['mutants_per_second']} per second): {counts}; bad {doc['bad']}"
    )
    for finding in doc["findings"]:
        print(
            f"  bad: {finding['outcome']} {finding['source']} #{finding['index']} {finding['kind']} "
            f"({finding['description']}): {finding['detail'][:200]}"
        )
    print(f"report: {out}")
    return 1 if doc["bad"] or doc["interrupted"] else 0


def cmd_table(args) -> int:
    """Print the run's table, or check a document's against it (exit 1 where it differs)."""
    from . import table

    summaries = [table.load_summary(Path(run)) for run in args.runs]
    if args.check is None:
        print(table.table(*summaries))
        return 0
    problem = table.check(summaries, Path(args.check))
    if problem:
        print(problem, file=sys.stderr)
        return 1
    print(f"{args.check}: the results table is the runs'")
    return 0


def cmd_where(args) -> int:
    """Each name's file, one per line; exit 2 naming what was not found."""
    from .corpus import where

    status = 0
    for name in args.names:
        try:
            print(where(name))
        except LookupError as error:
            print(f"error: {error}", file=sys.stderr)
            status = 2
    return status


def main(argv: list[str] | None = None) -> int:
    args = parser().parse_args(argv)
    try:
        commands = {
            "run": cmd_run,
            "bench": cmd_bench,
            "maniskill-bench": cmd_maniskill_bench,
            "robustness": cmd_robustness,
            "where": cmd_where,
            "table": cmd_table,
        }
        return commands[args.command](args)
    except (ValueError, FileNotFoundError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2

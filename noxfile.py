"""Every session but `maniskill` runs in one environment, `.nox/project` (uv where it is installed, else
virtualenv), made by the first of them and reused by the rest, with every extra they need: the conformance run, the
tests, the bench, fuzz, robustness and lint share one install instead of keeping a copy each. `maniskill` keeps its
own, `.nox/maniskill` (torch's CPU build). The project is installed again only when pyproject.toml changes.
`pipx run nox -s conformance` (or `uvx nox ...`) is therefore the whole set-up."""

import hashlib
import shutil
import sys
from pathlib import Path

import nox

nox.options.default_venv_backend = "uv|virtualenv"
nox.options.reuse_existing_virtualenvs = True
nox.options.sessions = ["tests"]
ROOT = Path(__file__).resolve().parent
PYPROJECT = ROOT / "pyproject.toml"
SHARED = ROOT / ".nox" / "project"  # the sessions' one environment (`project`)
EXTRAS = ("harness", "menagerie", "robots", "ray", "test")  # what the sessions sharing it need, together


def install(session: nox.Session, *extras: str, python: str = "python") -> None:
    """`pip install -e .[extras]` into the environment of `python`, skipped while a stamp there says the same
    pyproject.toml and extras are installed."""
    target = f".[{','.join(extras)}]" if extras else "."
    prefix = Path(session.virtualenv.location) if python == "python" else Path(python).parent.parent
    stamp = prefix / ".mjcf-sapien-installed"
    key = hashlib.sha256(PYPROJECT.read_bytes() + target.encode()).hexdigest()
    if stamp.is_file() and stamp.read_text() == key:
        return
    if python == "python":
        session.install("-e", target)
    elif shutil.which("uv"):
        session.run("uv", "pip", "install", "--python", python, "-e", target, external=True)
    else:
        session.run(python, "-m", "pip", "install", "--quiet", "-e", target, external=True)
    stamp.write_text(key)


def project(session: nox.Session) -> str:
    """The shared environment's Python, the environment made (with nox's own interpreter) and the project installed
    with `EXTRAS` where it is not yet."""
    python = SHARED / "bin" / "python"
    if not python.is_file():
        if shutil.which("uv"):
            session.run("uv", "venv", "--quiet", "--python", sys.executable, str(SHARED), external=True)
        else:
            session.run(sys.executable, "-m", "virtualenv", "--quiet", str(SHARED), external=True)
    install(session, *EXTRAS, python=str(python))
    return str(python)


@nox.session(venv_backend="none")
def tests(session: nox.Session) -> None:
    """The project's test suite (what CI runs)."""
    python = project(session)
    session.run(python, "-m", "pytest", *session.posargs, external=True)


@nox.session
def maniskill(session: nox.Session) -> None:
    """`loader.maniskill` inside ManiSkill 3.0.1 (tests/test_maniskill.py, tests/test_maniskill_joint_actuation.py,
    tests/test_maniskill_inertia.py), the `maniskill_tensor` tier's tests (tests/test_maniskill_tensor_tier.py) and
    the `maniskill` tier's mutation test, which skip elsewhere, then the `maniskill` and `maniskill_tensor` tiers over
    the default corpus; with `-- bench`, `Empty-v1`'s throughput under `mujoco_ctrl` against `pd_joint_pos`
    (`conformance/maniskill_bench.py`). Not part of `tests`: the extra brings torch, whose default Linux wheel pulls
    CUDA; here its CPU build is installed first."""
    session.install("torch==2.13.0", "--extra-index-url", "https://download.pytorch.org/whl/cpu")
    install(session, "harness", "menagerie", "maniskill", "test")
    if session.posargs[:1] == ["bench"]:  # `nox -s maniskill -- bench`: Empty-v1's throughput per control mode
        session.run("python", "-m", "conformance", "maniskill-bench", *session.posargs[1:])
        return
    mutation = "tests/test_tiers_mutations.py::test_the_maniskill_tier_catches_a_robot_built_there_without_armature"
    tests = [
        "tests/test_maniskill.py",
        "tests/test_maniskill_joint_actuation.py",
        "tests/test_maniskill_inertia.py",
        "tests/test_maniskill_tensor_tier.py",
        mutation,
    ]
    session.run("python", "-m", "pytest", *tests, *session.posargs)
    # both ManiSkill tiers over the default corpus against the manifest, whose expectations for them (and the gaps
    # their failures claim, `passes_without`) are then re-checked on every run
    tiers = ["--tiers", "maniskill,maniskill_tensor", "--no-record", "--quiet", "--out", "reports/maniskill"]
    session.run("python", "-m", "conformance", "run", *tiers)


@nox.session(venv_backend="none")
def lint(session: nox.Session) -> None:
    """Static checks: the formatter (`ruff format --check`), ruff's lint with line length and function complexity,
    and the house rules (no measured number in a loader docstring, no import cycle, the loader's layers, no private
    attribute read across objects, docs that name only what exists)."""
    python = project(session)
    paths = ("loader", "conformance", "tests", "noxfile.py")
    session.run(python, "-m", "ruff", "format", "--check", *paths, external=True)
    session.run(python, "-m", "ruff", "check", *paths, external=True)
    session.run(python, "tests/support/house.py", external=True)


@nox.session(venv_backend="none")
def conformance(session: nox.Session) -> None:
    """MuJoCo vs SAPIEN conformance over the corpus manifest; arguments pass through to `run`
    (e.g. `nox -s conformance -- --model humanoid --tiers dynamics`; a leading `run` is accepted too)."""
    python = project(session)
    args = list(session.posargs)
    if args[:1] != ["run"]:
        args = ["run", *args]
    session.run(python, "-m", "conformance", *args, external=True)


@nox.session(venv_backend="none")
def bench(session: nox.Session) -> None:
    """Per model: load over MuJoCo's compile, cold (fresh processes) and warm, each the median over repeats;
    set_ctrl over PhysX's step; the harness's steps per second; and totals, as JSON (reports/bench.json)."""
    python = project(session)
    session.run(python, "-m", "conformance", "bench", *session.posargs, external=True)


@nox.session(venv_backend="none")
def fuzz(session: nox.Session) -> None:
    """Generated MJCF fragments against MuJoCo, many examples, hypothesis database kept in .hypothesis/fragments;
    `nox -s fuzz -- --examples 5000` sets the total, `--workers N` the processes sharing it (default 2); prints
    examples per second and the CPU time at the end. Shrunk counterexamples are written to corpus/regressions/."""
    python = project(session)
    session.run(python, "-m", "conformance.fragments", *session.posargs, external=True)


@nox.session(venv_backend="none")
def robustness(session: nox.Session) -> None:
    """Mutants of the corpus's real files (bad numbers, dropped attributes, duplicate names, dangling references,
    missing files, truncation, binary garbage, unsupported elements, long, deep and huge models), each loaded and
    stepped in its own process and judged with MuJoCo as the oracle; `nox -s robustness -- --mutants 10000 --seed 1`.
    Exits non-zero on any crash, hang, untyped error, silently wrong load or divergence MuJoCo does not share."""
    python = project(session)
    session.run(python, "-m", "conformance", "robustness", *session.posargs, external=True)

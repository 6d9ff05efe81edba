"""The package as a user installs it: the wheel's core requirements are the loader's alone, and an installed wheel
carries its corpus, so the conformance CLI runs from any folder."""

from __future__ import annotations

import email.parser
import os
import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
CORE = {"mujoco", "sapien", "numpy"}  # what `loader` imports (tests/support/house.py checks the imports)


@pytest.fixture(scope="module")
def wheel(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("wheel")
    source = out / "source"  # a clean copy: a build folder left in the checkout would hide what the wheel lacks
    skipped = {".git", ".nox", "build", "reports", ".hypothesis", ".ruff_cache"}
    shutil.copytree(
        ROOT,
        source,
        ignore=lambda folder, names: [
            n for n in names if (Path(folder) == ROOT and n in skipped) or n.endswith(".egg-info") or n == "__pycache__"
        ],
    )
    subprocess.run(
        [sys.executable, "-m", "pip", "wheel", "--quiet", "--no-deps", "-w", str(out), str(source)], check=True, cwd=out
    )
    return next(out.glob("*.whl"))


def test_the_core_install_requires_only_what_the_loader_imports(wheel):
    with zipfile.ZipFile(wheel) as archive:
        name = next(n for n in archive.namelist() if n.endswith(".dist-info/METADATA"))
        metadata = email.parser.Parser().parsestr(archive.read(name).decode())
    required = [r for r in metadata.get_all("Requires-Dist") if "extra ==" not in r]
    names = {r.split(";")[0].split("<")[0].split(">")[0].split("=")[0].split("[")[0].strip() for r in required}
    assert names == CORE, required


def test_the_wheel_holds_every_module_of_the_source(wheel):
    """pyproject.toml lists the packages by hand (the corpus is mapped into one): a package folder left off the
    list would install a harness that fails the first time it records."""
    source = {
        str(path.relative_to(ROOT))
        for top in ("loader", "conformance")
        for path in (ROOT / top).rglob("*.py")
        if "__pycache__" not in path.parts
    }
    with zipfile.ZipFile(wheel) as archive:
        packed = {name for name in archive.namelist() if name.endswith(".py")}
    assert source - packed == set()


def test_an_installed_wheel_runs_the_cli_from_another_folder(wheel, tmp_path):
    """Unpacked as pip installs it, outside the checkout: `--model cartpole` finds the manifest the wheel carries."""
    site = tmp_path / "site"
    with zipfile.ZipFile(wheel) as archive:
        archive.extractall(site)
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    env = {**os.environ, "PYTHONPATH": str(site)}
    done = subprocess.run(
        [
            sys.executable,
            "-m",
            "conformance",
            "run",
            "--model",
            "cartpole",
            "--tiers",
            "structure",
            "--no-record",
            "--quiet",
            "--out",
            str(elsewhere / "out"),
        ],
        cwd=elsewhere,
        env=env,
        capture_output=True,
        text=True,
        timeout=600,
        check=False,
    )
    assert done.returncode == 0, done.stdout[-2000:] + done.stderr[-2000:]
    assert list((elsewhere / "out").glob("*/summary.json"))
    probe = subprocess.run(
        [sys.executable, "-c", "import conformance.corpus as c; print(c.corpus_root())"],
        cwd=elsewhere,
        env=env,
        capture_output=True,
        text=True,
        check=True,
    )
    assert Path(probe.stdout.strip()).is_relative_to(site)  # the wheel's copy, not the checkout's


def test_a_plain_load_prints_nothing(tmp_path):
    """A load of a model that loses nothing, on a machine without a render device, prints nothing at all: no
    SAPIEN import note, no render-device warning, no note on approximations (they are in the result)."""
    code = (
        "from loader import MJCFLoader\n"
        "result = MJCFLoader().load('corpus/fixtures/pendulum.xml')\n"
        "assert result.approximations and not result.unsupported\n"
    )
    done = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, check=False)
    assert done.returncode == 0 and done.stdout == "" and done.stderr == "", done.stdout + done.stderr


def test_the_core_install_names_the_harness_extra(monkeypatch):
    """`python -m conformance` in a core install (no rerun, dm_control, tqdm) says which extra to install instead
    of failing on an import; .ci/run runs it in a core install (exit 2). Here the missing packages are simulated."""
    import importlib.util

    from conformance.extras import missing_harness

    assert missing_harness() is None
    found = importlib.util.find_spec
    monkeypatch.setattr(importlib.util, "find_spec", lambda name: None if name == "tqdm" else found(name))
    assert missing_harness() == (
        "python -m conformance needs the harness extra (tqdm missing): pip install 'mjcf-sapien[harness]' (from a "
        "clone: pip install '.[harness]', or run it through `pipx run nox -s conformance`)"
    )

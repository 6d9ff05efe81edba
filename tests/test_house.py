"""The house rules (tests/support/house.py) hold on the tree, and each check bites on a small deliberate mistake."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest
from support import house

ROOT = Path(__file__).parent.parent


def test_the_tree_keeps_the_house_rules():
    assert house.findings(ROOT) == []


LINTED = ("loader", "conformance", "tests", "noxfile.py")


def _ruff(*args: str, cwd: Path = ROOT) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "ruff", *args], cwd=cwd, capture_output=True, text=True, check=False)


@pytest.mark.parametrize("command", [("format", "--check"), ("check",)], ids=["format", "lint"])
def test_the_code_is_formatted_and_linted(command):
    """What `nox -s lint` runs, so that CI holds it too: ruff's formatter and its lint (pyproject's rules: line
    length, function complexity)."""
    done = _ruff(*command, *LINTED)
    assert done.returncode == 0, done.stdout + done.stderr


def test_a_tangled_function_is_found(tmp_path):
    """The complexity rule bites: a function of twelve branches (McCabe 13) fails it, one of eleven passes."""
    (tmp_path / "pyproject.toml").write_text((ROOT / "pyproject.toml").read_text())
    branches = "".join(f"    if x == {i}:\n        return {i}\n" for i in range(11))
    (tmp_path / "ok.py").write_text(f"def f(x):\n{branches}    return -1\n")
    assert _ruff("check", "ok.py", cwd=tmp_path).returncode == 0
    (tmp_path / "ok.py").write_text(f"def f(x):\n{branches}    if x == 11:\n        return 11\n    return -1\n")
    done = _ruff("check", "ok.py", cwd=tmp_path)
    assert done.returncode == 1 and "C901" in done.stdout, done.stdout


def test_a_measured_number_in_a_loader_docstring_is_found_and_one_in_code_is_not():
    text = '"""Module."""\n\nLIMIT = 1e-6\n\n\ndef f():\n    """Measured 4.2e-7 rad over 1 s."""\n    return 2.5E3\n'
    assert house.docstring_numbers({"loader/x.py": text}) == [
        "loader/x.py:7: 4.2e-7 in a docstring; name the test that measures it instead"
    ]


def test_an_import_cycle_is_found_even_through_a_function_local_import():
    files = {
        "pkg/__init__.py": "",
        "pkg/a.py": "from .b import g\n",
        "pkg/b.py": "def g():\n    from .a import h\n    return h\n",
    }
    assert house.import_cycles(files) == ["import cycle: pkg.a -> pkg.b -> pkg.a"]
    assert house.import_cycles({**files, "pkg/b.py": "def g():\n    return 1\n"}) == []


def test_the_planning_half_importing_the_runtime_is_found_and_the_shared_layer_is_not():
    files = {
        "loader/plan/joint.py": "from ..model import mj\nfrom ..errors import Notes\n",
        "loader/runtime/rows.py": "from ..model.mapping import Mapping\nfrom .term import Term\n",
        "loader/model/mj.py": "import mujoco\n",
        "loader/result.py": "from .plan import tree\nfrom .runtime import x\n",
    }
    assert house.layering(files) == []
    crossed = {**files, "loader/plan/joint.py": "def f():\n    from ..runtime.rows import RowTerm\n"}
    assert house.layering(crossed) == [
        (
            "loader/plan/joint.py:2: loader.plan imports loader.runtime.rows.RowTerm "
            "(loader.runtime); it may import loader.model, loader.plan only"
        )
    ]
    shared = {**files, "loader/model/mj.py": "from ..plan.tree import centres\n"}
    assert house.layering(shared) == [
        (
            "loader/model/mj.py:1: loader.model imports loader.plan.tree.centres "
            "(loader.plan); it may import loader.model only"
        )
    ]
    facade = {**files, "loader/runtime/rows.py": "from ..result import LoadResult\n"}
    assert len(house.layering(facade)) == 1


def test_a_folder_named_build_is_found():
    assert house.layering({"loader/build/tree.py": ""}) == [
        "loader/build/tree.py: a folder named build (tools take it for build output)"
    ]


def test_a_quoted_identifier_the_code_lacks_is_found():
    code = {
        "loader/runtime/controller.py": 'STAGES = ("rows", "drives")\n\n\nclass Controller:\n'
        "    def without(self, *names):\n        self.terms = names\n",
        "loader/plan/tree.py": "def plan_tree(model):\n    return model.nbody\n",
    }
    good = (
        "`controller.without`, `plan_tree()`, `plan/tree.py`, `summary.json`, `mujoco.mj_step` and "
        '`controller.without("rows")`\n'
    )
    assert house.unresolved_identifiers({"docs/a.md": good}, code) == []
    bad = '`controller.within`, `plan_forest()`, `plan/forest.py`, `without("limits")`\n'
    assert house.unresolved_identifiers({"docs/a.md": bad}, code) == [
        "docs/a.md:1: without('limits'): no such stage",
        "docs/a.md:1: `controller.within`: the code has no within",
        "docs/a.md:1: `plan_forest()`: no such function or class",
        "docs/a.md:1: `plan/forest.py`: no such file",
    ]


def test_reading_another_objects_private_attribute_is_found():
    text = "def f(result):\n    return result._cache\n\n\nclass A:\n    def g(self):\n        return self._own\n"
    assert house.private_reads({"m.py": text}) == ["m.py:2: reads private attribute _cache"]


def test_a_link_to_a_missing_anchor_or_file_is_found():
    docs = {
        "README.md": "see [limits](docs/mapping.md#joint-limits) and [x](docs/mapping.md#joint-limit)\n",
        "docs/mapping.md": "# Mapping\n\n## Joint limits\n\n[back](../README.md), [gone](../nothere.py)\n",
    }
    assert house.broken_links(docs) == [
        "README.md:1: broken link docs/mapping.md#joint-limit",
        "docs/mapping.md:5: broken link ../nothere.py",
    ]
    docs["nothere.py"] = ""
    docs["README.md"] = docs["README.md"].replace("#joint-limit)", "#joint-limits)")
    assert house.broken_links(docs) == []


def test_a_heading_with_punctuation_has_githubs_anchor():
    docs = {
        "a.md": "## Visuals, cameras and sites\n## `set_ctrl` and `release()`\n[v](#visuals-cameras-and-sites) "
        "[s](#set_ctrl-and-release)\n"
    }
    assert house.broken_links(docs) == []


def test_a_readme_over_the_limit_is_found():
    assert house.long_readme("x\n" * house.MAX_README_LINES) == []
    assert house.long_readme("x\n" * (house.MAX_README_LINES + 1)) != []


def test_a_reference_to_a_moved_or_renamed_test_is_found():
    files = {"tests/test_a.py": "def test_kept():\n    pass\n"}
    docs = {
        "docs/m.md": "Measured by: `tests/test_a.py::test_kept`, `tests/test_a.py::test_gone`,\n"
        "`tests/test_b.py::test_kept`.\n"
    }
    assert house.broken_test_references(docs, files) == [
        "docs/m.md:1: no test tests/test_a.py::test_gone",
        "docs/m.md:2: no test tests/test_b.py::test_kept",
    ]


def test_a_loader_import_beyond_its_core_dependencies_is_found():
    files = {
        "loader/a.py": "import os\nimport numpy as np\nfrom sapien import physx\nfrom . import b\n",
        "loader/b.py": "def f():\n    import rerun\n    from tqdm import tqdm\n",
        "loader/c.py": "try:\n    import threadpoolctl\nexcept ImportError:\n    threadpoolctl = None\n"
        "try:\n    import torch\nexcept ValueError:\n    pass\n",
    }
    assert house.foreign_imports(files) == [
        "loader/b.py:2: imports rerun, which the loader's install does not have",
        "loader/b.py:3: imports tqdm, which the loader's install does not have",
        "loader/c.py:6: imports torch, which the loader's install does not have",
    ]  # not guarded by ImportError


def test_a_command_that_cannot_be_pasted_after_the_set_up_is_found():
    sessions, commands, environments = {"conformance", "tests"}, {"run", "where"}, {"project", "maniskill"}
    good = (
        "`pipx run nox -s conformance -- --model x`, `.nox/project/bin/rerun reports/latest/x.rrd`,\n"
        "`.nox/project/bin/python -m conformance where panda`, `.nox/maniskill/bin/python -m conformance run`\n"
    )
    assert house.unpasteable_commands({"README.md": good}, sessions, commands, environments) == []
    bad = (
        "`nox -s conformance`, `pipx run nox -s lint`, `rerun reports/latest/x.rrd`\n"
        "`python -m conformance where panda`, `.nox/project/bin/python -m conformance bench`\n"
        "`.nox/tests/bin/python -m conformance run`\n"
    )
    assert house.unpasteable_commands({"README.md": bad}, sessions, commands, environments) == [
        "README.md:1: `nox -s conformance`: README's set-up has `pipx run nox`",
        "README.md:1: nox session 'lint': the noxfile has none",
        "README.md:1: `rerun`: the set-up's viewer is .nox/project/bin/rerun",
        "README.md:2: python -m conformance: run it as .nox/project/bin/python -m conformance",
        "README.md:2: python -m conformance bench: the harness has no such command",
        "README.md:3: python -m conformance: run it as .nox/project/bin/python -m conformance",
    ]
    assert (
        house.unpasteable_commands({"docs/a.md": "`python -m conformance where x`\n"}, sessions, commands, environments)
        == []
    )


def test_the_environments_are_the_shared_one_and_each_session_that_makes_its_own():
    noxfile = (
        'SHARED = ROOT / ".nox" / "project"\n'
        '@nox.session(venv_backend="none")\ndef tests(session): pass\n'
        "@nox.session\ndef maniskill(session): pass\n"
    )
    assert house.nox_environments(noxfile) == {"project", "maniskill"}
    assert house.nox_environments((ROOT / "noxfile.py").read_text()) == {"project", "maniskill"}

"""The house rules `nox -s lint` and tests/test_house.py check on the source tree:

- no measured number (e-notation) in a docstring under `loader/`: it belongs in the test that measures it;
- no import cycle between the project's modules (function-local imports included);
- the loader's layers (`LAYERS`): the shared layer (`loader/model/`, `loader/errors.py`) imports neither half, the
  planning half (`loader/plan/`) never imports the runtime half (`loader/runtime/`) nor the runtime the planning
  half; only the façade above them (`mjcf_loader.py`, `result.py`, `maniskill/`) joins them, and no folder is named
  `build` (tools take it for build output);
- no module reading another object's private (`_name`) attribute;
- `loader/` imports nothing beyond the standard library and its core dependencies (`CORE`), but for
  `loader/maniskill/`, which may import what the `maniskill` extra installs (`MANISKILL`), and an optional import
  guarded by `except ImportError`;
- every relative link in README.md and docs/*.md resolves (file and `#anchor`), every `tests/<file>.py::<test>`
  they or the source name exists, and README.md stays under `MAX_README_LINES` lines;
- every code identifier README.md and docs/*.md quote in backticks resolves: a dotted name or a call `name()`
  against the names the code defines and uses, a `file.py` against the tree, a `without("...")` against the
  controller's stages;
- every command README.md, docs/*.md and reports/README.md give can be pasted after README's set-up: `pipx run nox
  -s SESSION` with a session the noxfile has, the viewer through the environment the set-up made
  (`.nox/project/bin/rerun`), a harness command it has (in README: `.nox/project/bin/python -m conformance
  COMMAND`).

Run as `python tests/support/house.py` from the project root; exits non-zero on a finding."""

from __future__ import annotations

import ast
import os
import re
import sys
from pathlib import Path

E_NOTATION = re.compile(r"(?<![\w.])\d+(?:\.\d+)?[eE][-+]?\d+\b")
MAX_README_LINES = 120
REPORTS = Path("reports") / "README.md"  # the one tracked file in the runs' folder
PACKAGES = ("loader", "conformance")
CORE = ("mujoco", "sapien", "numpy")  # the loader's install: everything else is an extra
MANISKILL = ("loader/maniskill/", ("mani_skill", "torch", "gymnasium"))  # the one module the `maniskill` extra adds
LINK = re.compile(r"\]\(([^)\s]+)\)")
TEST_REFERENCE = re.compile(r"(tests/[\w/]+\.py)::(\w+)")


def _docstring_nodes(tree: ast.AST):
    for node in ast.walk(tree):
        if isinstance(node, (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef)) and node.body:
            first = node.body[0]
            if (
                isinstance(first, ast.Expr)
                and isinstance(first.value, ast.Constant)
                and isinstance(first.value.value, str)
            ):
                yield first


def docstring_numbers(files: dict[str, str]) -> list[str]:
    """`path:line: <number>` for every e-notation number inside a docstring."""
    out = []
    for path, text in files.items():
        for node in _docstring_nodes(ast.parse(text)):
            for offset, line in enumerate(node.value.value.splitlines()):
                for number in E_NOTATION.findall(line):
                    out.append(
                        f"{path}:{node.lineno + offset}: {number} in a docstring; name the test that "
                        "measures it instead"
                    )
    return out


def _module_name(path: str) -> str:
    parts = list(Path(path).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def import_cycles(files: dict[str, str]) -> list[str]:
    """Every import cycle between the given modules (module-level and function-local imports)."""
    modules = {_module_name(p): p for p in files}
    graph: dict[str, set[str]] = {}
    for name, path in modules.items():
        package = name if Path(path).name == "__init__.py" else name.rpartition(".")[0]
        deps = set()
        for node in ast.walk(ast.parse(files[path])):
            if isinstance(node, ast.ImportFrom):
                base = package.split(".")[: len(package.split(".")) - (node.level - 1)] if node.level else []
                target = ".".join(base + ([node.module] if node.module else [])) if node.level else node.module
                subs = [f"{target}.{a.name}" for a in node.names if f"{target}.{a.name}" in modules]
                deps.update(subs)
                if len(subs) < len(node.names) and target in modules:
                    deps.add(target)
            elif isinstance(node, ast.Import):
                deps.update(a.name for a in node.names if a.name in modules)
        graph[name] = deps - {name}
    cycles, state = [], {}

    def visit(node: str, stack: list[str]) -> None:
        state[node] = "open"
        stack.append(node)
        for nxt in sorted(graph[node]):
            if state.get(nxt) == "open":
                cycles.append(" -> ".join(stack[stack.index(nxt) :] + [nxt]))
            elif nxt not in state:
                visit(nxt, stack)
        stack.pop()
        state[node] = "done"

    for name in sorted(graph):
        if name not in state:
            visit(name, [])
    return [f"import cycle: {cycle}" for cycle in cycles]


SHARED, PLAN, RUNTIME = "loader.model", "loader.plan", "loader.runtime"
LAYERS = {  # a layer: the layers its modules may import (the façade, every other loader module, may import any)
    SHARED: (SHARED,),
    PLAN: (SHARED, PLAN),
    RUNTIME: (SHARED, RUNTIME),
}
LEAVES = ("loader.errors",)  # top-level modules of the shared layer


def _layer(module: str) -> str | None:
    if any(module == leaf or module.startswith(leaf + ".") for leaf in LEAVES):
        return SHARED
    return next((layer for layer in LAYERS if module == layer or module.startswith(layer + ".")), None)


def _imports(name: str, path: str, text: str) -> list[tuple[int, str]]:
    """(line, absolute module) of every import in the module (function-local and TYPE_CHECKING ones too)."""
    package = name if Path(path).name == "__init__.py" else name.rpartition(".")[0]
    out = []
    for node in ast.walk(ast.parse(text)):
        if isinstance(node, ast.ImportFrom):
            parts = package.split(".")
            base = parts[: len(parts) - (node.level - 1)] if node.level else []
            target = ".".join(base + ([node.module] if node.module else [])) if node.level else node.module
            out.extend((node.lineno, f"{target}.{a.name}") for a in node.names)
        elif isinstance(node, ast.Import):
            out.extend((node.lineno, a.name) for a in node.names)
    return out


def layering(files: dict[str, str]) -> list[str]:
    """`path:line: ...` for every import that crosses the loader's layers the wrong way, and every folder named
    `build` under the packages."""
    out = [
        f"{path}: a folder named build (tools take it for build output)"
        for path in files
        if "build" in Path(path).parts[:-1]
    ]
    for path, text in files.items():
        name = _module_name(path)
        layer = _layer(name)
        if layer is None:
            continue
        for line, target in _imports(name, path, text):
            if not target.startswith("loader"):
                continue
            reached = _layer(target) or (
                None if target in ("loader", "loader.model", "loader.plan", "loader.runtime") else "the façade"
            )
            if reached is not None and reached not in LAYERS[layer]:
                out.append(
                    f"{path}:{line}: {layer} imports {target} ({reached}); it may import "
                    f"{', '.join(LAYERS[layer])} only"
                )
    return out


QUOTED = re.compile(r"`([^`\n]+)`")
DOTTED = re.compile(r"^[A-Za-z_]\w*(?:\.[A-Za-z_]\w*)+(?:\(\))?$")
CALL = re.compile(r"^([A-Za-z_]\w*)\(\)$")
PY_FILE = re.compile(r"^[\w/.-]+\.py$")
STAGE_SWITCH = re.compile(r"without\(([^)]*)\)")
FILE_SUFFIXES = ("md", "json", "txt", "TXT", "toml", "rrd", "xml", "html", "yaml", "csv", "tar")
THIRD_PARTY = (
    "mani_skill",
    "mujoco",
    "sapien",
    "numpy",
    "np",
    "rerun",
    "rr",
    "ray",
    "torch",
    "gymnasium",
    "dm_control",
    "hypothesis",
    "nox",
    "warp",
    "mjx",
)  # their names are theirs to resolve


NOX = re.compile(r"(?<![\w-])(?:(pipx run )?nox) -s (\w+)")
VIEWER = re.compile(r"(?<![\w/.-])rerun (?=\S+\.rrd)")
HARNESS = re.compile(r"(\S*)python -m conformance (\w+)")


def unpasteable_commands(
    docs: dict[str, str], sessions: set[str], commands: set[str], environments: set[str]
) -> list[str]:
    """`path:line: ...` for every command in `docs` a user could not paste after README's set-up (`sessions`: the
    noxfile's; `commands`: the harness's; `environments`: the folders under .nox/ its sessions make)."""
    out = []
    for path, text in docs.items():
        if not path.endswith(".md"):
            continue
        for number, line in enumerate(text.splitlines(), 1):
            out += [
                f"{path}:{number}: {problem}"
                for problem in _command_problems(line, path, sessions, commands, environments)
            ]
    return out


def _command_problems(
    line: str, path: str, sessions: set[str], commands: set[str], environments: set[str]
) -> list[str]:
    problems = []
    for pipx, session in NOX.findall(line):
        if not pipx:
            problems.append(f"`nox -s {session}`: README's set-up has `pipx run nox`")
        elif session not in sessions:
            problems.append(f"nox session {session!r}: the noxfile has none")
    if VIEWER.search(line):
        problems.append("`rerun`: the set-up's viewer is .nox/project/bin/rerun")
    for prefix, command in HARNESS.findall(line):
        if command not in commands:
            problems.append(f"python -m conformance {command}: the harness has no such command")
        elif path == "README.md" and prefix.lstrip("`(") not in {f".nox/{e}/bin/" for e in environments}:
            problems.append("python -m conformance: run it as .nox/project/bin/python -m conformance")
    return problems


def nox_sessions(noxfile: str) -> set[str]:
    """The noxfile's sessions: its functions decorated `@nox.session`."""
    return {
        node.name
        for node in ast.walk(ast.parse(noxfile))
        if isinstance(node, ast.FunctionDef) and any("session" in ast.unparse(d) for d in node.decorator_list)
    }


def nox_environments(noxfile: str) -> set[str]:
    """The folders under .nox/ the noxfile's sessions make: the shared one (`SHARED`) and one per session that makes
    its own (any not declared `venv_backend="none"`)."""
    tree = ast.parse(noxfile)
    own = {
        node.name
        for node in ast.walk(tree)
        if isinstance(node, ast.FunctionDef)
        and any(
            "session" in ast.unparse(d) and "venv_backend='none'" not in ast.unparse(d) for d in node.decorator_list
        )
    }
    return own | set(re.findall(r'"\.nox" / "(\w+)"', noxfile))


def harness_commands(cli: str) -> set[str]:
    """The harness's commands: what `conformance/cli.py` adds as subparsers."""
    return set(re.findall(r'sub\.add_parser\(\s*"(\w+)"', cli))


def code_names(files: dict[str, str]) -> tuple[set[str], set[str]]:
    """(every identifier the code defines or uses: names, attributes, functions, classes, arguments, modules; the
    functions and classes it defines)."""
    names, defined = set(), set()
    for path, text in files.items():
        names.update(Path(path).with_suffix("").parts)
        for node in ast.walk(ast.parse(text)):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
                names.add(node.name)
                defined.add(node.name)
            elif isinstance(node, ast.Name):
                names.add(node.id)
            elif isinstance(node, ast.Attribute):
                names.add(node.attr)
            elif isinstance(node, ast.arg):
                names.add(node.arg)
            elif isinstance(node, ast.alias):
                names.update((node.asname or node.name).split("."))
                names.update(node.name.split("."))
    return names, defined


def stages(files: dict[str, str]) -> set[str]:
    """The controller's `STAGES` (the names `without` takes)."""
    for node in ast.walk(ast.parse(files.get("loader/runtime/controller.py", ""))):
        if isinstance(node, ast.Assign) and any(getattr(t, "id", "") == "STAGES" for t in node.targets):
            return set(ast.literal_eval(node.value))
    return set()


def unresolved_identifiers(docs: dict[str, str], files: dict[str, str]) -> list[str]:
    """`path:line: ...` for every code identifier quoted in backticks in `docs` that the code (`files`) does not
    have: a dotted name or `call()` whose parts the code never names, a `.py` file the tree lacks, a stage that
    `without(...)` does not know."""
    names, defined = code_names(files)
    known_stages = stages(files)
    out = []
    for path, text in docs.items():
        if not path.endswith(".md"):
            continue
        for number, line in enumerate(text.splitlines(), 1):
            for switch in STAGE_SWITCH.findall(line):
                for stage in re.findall(r"[\"']([^\"']*)[\"']", switch):
                    if stage not in known_stages:
                        out.append(f"{path}:{number}: without({stage!r}): no such stage")
            for quoted in QUOTED.findall(line):
                problem = _unresolved(quoted.strip(), names, defined, list(files))
                if problem:
                    out.append(f"{path}:{number}: {problem}")
    return out


def _unresolved(token: str, names: set[str], defined: set[str], paths: list[str]) -> str | None:
    """What the code lacks of one quoted token (None: it resolves, or it is not a code identifier)."""
    call = CALL.match(token)
    if PY_FILE.match(token):
        return None if any(p == token or p.endswith("/" + token) for p in paths) else f"`{token}`: no such file"
    if call:
        return None if call.group(1) in defined else f"`{token}`: no such function or class"
    if DOTTED.match(token) and token.rpartition(".")[2] not in FILE_SUFFIXES and token.split(".")[0] not in THIRD_PARTY:
        missing = [part for part in token.removesuffix("()").split(".") if part not in names]
        return f"`{token}`: the code has no {', '.join(missing)}" if missing else None
    return None


def private_reads(files: dict[str, str]) -> list[str]:
    """`obj._name` where obj is not `self`, `cls` or `super()` (dunder names aside)."""
    out = []
    for path, text in files.items():
        for node in ast.walk(ast.parse(text)):
            if (
                isinstance(node, ast.Attribute)
                and node.attr.startswith("_")
                and not node.attr.startswith("__")
                and not (isinstance(node.value, ast.Name) and node.value.id in ("self", "cls"))
                and not (isinstance(node.value, ast.Call) and getattr(node.value.func, "id", "") == "super")
            ):
                out.append(f"{path}:{node.lineno}: reads private attribute {node.attr}")
    return out


def _anchor(heading: str) -> str:
    """GitHub's anchor for a markdown heading: lower case, punctuation dropped, spaces to hyphens."""
    return re.sub(r"[^\w\- ]", "", heading.strip().lower()).replace(" ", "-")


def broken_links(docs: dict[str, str]) -> list[str]:
    """`path:line: link` for every relative link whose file or `#anchor` is not in `docs` (paths relative to the
    root; links to files other than markdown only need the file to be listed)."""
    anchors = {
        path: {_anchor(line.lstrip("#")) for line in text.splitlines() if line.startswith("#")}
        for path, text in docs.items()
        if path.endswith(".md")
    }
    out = []
    for path, text in docs.items():
        for number, line in enumerate(text.splitlines(), 1):
            for link in LINK.findall(line):
                if "://" in link or link.startswith("mailto:"):
                    continue
                target, _, anchor = link.partition("#")
                resolved = os.path.normpath(os.path.join(os.path.dirname(path), target)) if target else path
                if resolved not in docs or (anchor and anchor not in anchors.get(resolved, set())):
                    out.append(f"{path}:{number}: broken link {link}")
    return out


def broken_test_references(texts: dict[str, str], files: dict[str, str]) -> list[str]:
    """`path:line: reference` for every `tests/<file>.py::<test>` in `texts` whose file is not in `files` or does not
    define that function."""
    out = []
    for path, text in texts.items():
        for number, line in enumerate(text.splitlines(), 1):
            for file, name in TEST_REFERENCE.findall(line):
                if not re.search(rf"^\s*def {name}\(", files.get(file, ""), re.MULTILINE):
                    out.append(f"{path}:{number}: no test {file}::{name}")
    return out


def long_readme(text: str, limit: int = MAX_README_LINES) -> list[str]:
    lines = len(text.splitlines())
    return [f"README.md is {lines} lines (at most {limit}): move detail into docs/"] if lines > limit else []


def documents(root: Path) -> dict[str, str]:
    """README.md, docs/*.md and every other file they may link to (by path relative to the root)."""
    files = {"README.md": (root / "README.md").read_text(), "reports/README.md": (root / REPORTS).read_text()}
    files.update({str(p.relative_to(root)): p.read_text() for p in sorted((root / "docs").glob("*.md"))})
    for p in sorted(root.rglob("*")):
        rel = p.relative_to(root)
        if p.is_file() and rel.parts[0] not in (".git", "reports", ".nox") and str(rel) not in files:
            files[str(rel)] = ""
    return files


def foreign_imports(files: dict[str, str], allowed=CORE) -> list[str]:
    """`path:line: module` for every absolute import that is neither the standard library, `allowed`, nor the
    project's own packages."""
    out = []
    for path, text in files.items():
        tree = ast.parse(text)
        optional = {
            id(node)
            for guard in ast.walk(tree)
            if isinstance(guard, ast.Try) and _catches_import_error(guard)
            for statement in guard.body
            for node in ast.walk(statement)
        }  # used where installed
        for node in ast.walk(tree):
            names = (
                [a.name for a in node.names]
                if isinstance(node, ast.Import)
                else ([node.module] if isinstance(node, ast.ImportFrom) and node.level == 0 and node.module else [])
            )
            if id(node) in optional:
                continue
            for name in names:
                top = name.split(".")[0]
                if top not in sys.stdlib_module_names and top not in allowed and top not in PACKAGES:
                    out.append(f"{path}:{node.lineno}: imports {top}, which the loader's install does not have")
    return out


def _catches_import_error(guard: ast.Try) -> bool:
    return any(
        isinstance(h.type, ast.Name) and h.type.id in ("ImportError", "ModuleNotFoundError") for h in guard.handlers
    )


def sources(root: Path, packages=PACKAGES) -> dict[str, str]:
    return {
        str(p.relative_to(root)): p.read_text() for package in packages for p in sorted((root / package).rglob("*.py"))
    }


def findings(root: Path) -> list[str]:
    every = sources(root)
    tests = {str(p.relative_to(root)): p.read_text() for p in sorted((root / "tests").rglob("*.py"))}
    loader = {p: t for p, t in every.items() if p.startswith("loader")}
    docs = documents(root)
    noxfile = (root / "noxfile.py").read_text()
    return (
        docstring_numbers(loader)
        + import_cycles(every)
        + layering(loader)
        + private_reads(every)
        + foreign_imports({p: t for p, t in loader.items() if not p.startswith(MANISKILL[0])})
        + foreign_imports({p: t for p, t in loader.items() if p.startswith(MANISKILL[0])}, CORE + MANISKILL[1])
        + broken_links(docs)
        + long_readme(docs["README.md"])
        + unresolved_identifiers(docs, {**every, **tests, "noxfile.py": noxfile})
        + unpasteable_commands(
            docs, nox_sessions(noxfile), harness_commands(every["conformance/cli.py"]), nox_environments(noxfile)
        )
        + broken_test_references(
            {**{p: t for p, t in docs.items() if p.endswith(".md")}, **every},
            {str(p.relative_to(root)): p.read_text() for p in sorted((root / "tests").rglob("*.py"))},
        )
    )


if __name__ == "__main__":
    found = findings(Path.cwd())
    print("\n".join(found) or "house rules: clean")
    sys.exit(1 if found else 0)

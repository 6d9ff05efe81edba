"""The house rules `nox -s lint` and tests/test_house.py check on the source tree:

- no measured number (e-notation) in a docstring under `loader/`: it belongs in the test that measures it;
- no import cycle between the project's modules (function-local imports included);
- no class over `MAX_CLASS_LINES` lines in `loader/`;
- no module reading another object's private (`_name`) attribute;
- `loader/` imports nothing beyond the standard library and its core dependencies (`CORE`), but for
  `loader/maniskill/`, which may import what the `maniskill` extra installs (`MANISKILL`), and an optional import
  guarded by `except ImportError`;
- every relative link in README.md and docs/*.md resolves (file and `#anchor`), every `tests/<file>.py::<test>`
  they or the source name exists, and README.md stays under `MAX_README_LINES` lines.

Run as `python tests/support/house.py` from the project root; exits non-zero on a finding."""

from __future__ import annotations

import ast
import os
import re
import sys
from pathlib import Path

E_NOTATION = re.compile(r"(?<![\w.])\d+(?:\.\d+)?[eE][-+]?\d+\b")
MAX_CLASS_LINES = 120
MAX_README_LINES = 120
PACKAGES = ("loader", "conformance")
CORE = ("mujoco", "sapien", "numpy")  # the loader's install: everything else is an extra
MANISKILL = ("loader/maniskill/", ("mani_skill", "torch", "gymnasium"))  # the one module the `maniskill` extra adds
LINK = re.compile(r"\]\(([^)\s]+)\)")
TEST_REFERENCE = re.compile(r"(tests/[\w/]+\.py)::(\w+)")


def _docstring_nodes(tree: ast.AST):
    for node in ast.walk(tree):
        if isinstance(node, (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef)) and node.body:
            first = node.body[0]
            if isinstance(first, ast.Expr) and isinstance(first.value, ast.Constant) and isinstance(
                    first.value.value, str):
                yield first


def docstring_numbers(files: dict[str, str]) -> list[str]:
    """`path:line: <number>` for every e-notation number inside a docstring."""
    out = []
    for path, text in files.items():
        for node in _docstring_nodes(ast.parse(text)):
            for offset, line in enumerate(node.value.value.splitlines()):
                for number in E_NOTATION.findall(line):
                    out.append(f"{path}:{node.lineno + offset}: {number} in a docstring; name the test that "
                               "measures it instead")
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
                cycles.append(" -> ".join(stack[stack.index(nxt):] + [nxt]))
            elif nxt not in state:
                visit(nxt, stack)
        stack.pop()
        state[node] = "done"

    for name in sorted(graph):
        if name not in state:
            visit(name, [])
    return [f"import cycle: {cycle}" for cycle in cycles]


def long_classes(files: dict[str, str], limit: int = MAX_CLASS_LINES) -> list[str]:
    out = []
    for path, text in files.items():
        for node in ast.walk(ast.parse(text)):
            if isinstance(node, ast.ClassDef) and node.end_lineno - node.lineno + 1 > limit:
                out.append(f"{path}:{node.lineno}: class {node.name} is {node.end_lineno - node.lineno + 1} lines "
                           f"(at most {limit})")
    return out


def private_reads(files: dict[str, str]) -> list[str]:
    """`obj._name` where obj is not `self`, `cls` or `super()` (dunder names aside)."""
    out = []
    for path, text in files.items():
        for node in ast.walk(ast.parse(text)):
            if (isinstance(node, ast.Attribute) and node.attr.startswith("_") and not node.attr.startswith("__")
                    and not (isinstance(node.value, ast.Name) and node.value.id in ("self", "cls"))
                    and not (isinstance(node.value, ast.Call) and getattr(node.value.func, "id", "") == "super")):
                out.append(f"{path}:{node.lineno}: reads private attribute {node.attr}")
    return out


def _anchor(heading: str) -> str:
    """GitHub's anchor for a markdown heading: lower case, punctuation dropped, spaces to hyphens."""
    return re.sub(r"[^\w\- ]", "", heading.strip().lower()).replace(" ", "-")


def broken_links(docs: dict[str, str]) -> list[str]:
    """`path:line: link` for every relative link whose file or `#anchor` is not in `docs` (paths relative to the
    root; links to files other than markdown only need the file to be listed)."""
    anchors = {path: {_anchor(line.lstrip("#")) for line in text.splitlines() if line.startswith("#")}
               for path, text in docs.items() if path.endswith(".md")}
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
    files = {"README.md": (root / "README.md").read_text()}
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
        optional = {id(node) for guard in ast.walk(tree) if isinstance(guard, ast.Try) and _catches_import_error(guard)
                    for statement in guard.body for node in ast.walk(statement)}  # used where installed
        for node in ast.walk(tree):
            names = [a.name for a in node.names] if isinstance(node, ast.Import) else (
                [node.module] if isinstance(node, ast.ImportFrom) and node.level == 0 and node.module else [])
            if id(node) in optional:
                continue
            for name in names:
                top = name.split(".")[0]
                if top not in sys.stdlib_module_names and top not in allowed and top not in PACKAGES:
                    out.append(f"{path}:{node.lineno}: imports {top}, which the loader's install does not have")
    return out


def _catches_import_error(guard: ast.Try) -> bool:
    return any(isinstance(h.type, ast.Name) and h.type.id in ("ImportError", "ModuleNotFoundError")
               for h in guard.handlers)


def sources(root: Path, packages=PACKAGES) -> dict[str, str]:
    return {str(p.relative_to(root)): p.read_text() for package in packages
            for p in sorted((root / package).rglob("*.py"))}


def findings(root: Path) -> list[str]:
    every = sources(root)
    loader = {p: t for p, t in every.items() if p.startswith("loader")}
    docs = documents(root)
    return (docstring_numbers(loader) + import_cycles(every) + long_classes(loader) + private_reads(every)
            + foreign_imports({p: t for p, t in loader.items() if not p.startswith(MANISKILL[0])})
            + foreign_imports({p: t for p, t in loader.items() if p.startswith(MANISKILL[0])}, CORE + MANISKILL[1])
            + broken_links(docs) + long_readme(docs["README.md"])
            + broken_test_references({**{p: t for p, t in docs.items() if p.endswith(".md")}, **every},
                                     {str(p.relative_to(root)): p.read_text()
                                      for p in sorted((root / "tests").rglob("*.py"))}))


if __name__ == "__main__":
    found = findings(Path.cwd())
    print("\n".join(found) or "house rules: clean")
    sys.exit(1 if found else 0)

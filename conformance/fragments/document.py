"""MJCF fragments as data: a default-class tree, a body/frame tree, assets and actuators, rendered to XML.

Attribute values are kept as the exact strings written to the file, so a shrunk counterexample prints and saves
exactly as it was compiled. Meshes are small OBJ files written beside the document.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path
from xml.sax.saxutils import quoteattr

Attrs = dict[str, str]


@dataclass
class MeshAsset:
    """A small closed triangle mesh written as `<file stem>.obj` beside the document."""

    name: str
    vertices: list[tuple[float, float, float]]
    faces: list[tuple[int, int, int]]
    attrs: Attrs = field(default_factory=dict)  # class=, scale=

    def obj_text(self) -> str:
        lines = [f"v {x:.6g} {y:.6g} {z:.6g}" for x, y, z in self.vertices]
        lines += [f"f {a + 1} {b + 1} {c + 1}" for a, b, c in self.faces]
        return "\n".join(lines) + "\n"


@dataclass
class DefaultClass:
    """One `<default>` class: at most one element of each kind, and nested child classes.

    `name` is None for the top-level class (`main`). `actuator` is (shortcut tag, attributes)."""

    name: str | None
    geom: Attrs | None = None
    joint: Attrs | None = None
    site: Attrs | None = None
    mesh: Attrs | None = None
    material: Attrs | None = None
    actuator: tuple[str, Attrs] | None = None
    children: list[DefaultClass] = field(default_factory=list)
    children_first: bool = False  # nested classes written before the elements (document order must not matter)

    def names(self) -> list[str]:
        out = [self.name] if self.name else []
        for child in self.children:
            out += child.names()
        return out


@dataclass
class Element:
    """A leaf element inside a body, frame or the world body: geom, joint, freejoint or site."""

    tag: str
    attrs: Attrs = field(default_factory=dict)


@dataclass
class Body:
    """A `<body>` (tag "body") or a `<frame>` (tag "frame") with its elements and children."""

    tag: str
    attrs: Attrs = field(default_factory=dict)
    elements: list[Element] = field(default_factory=list)
    children: list[Body] = field(default_factory=list)


@dataclass
class Document:
    """One generated MJCF document."""

    compiler: Attrs = field(default_factory=dict)
    defaults: DefaultClass | None = None
    split_main: bool = False  # main's geom attributes written in two top-level <default> blocks (they merge)
    meshes: list[MeshAsset] = field(default_factory=list)
    materials: list[Attrs] = field(default_factory=list)
    world: list[Element] = field(default_factory=list)
    bodies: list[Body] = field(default_factory=list)
    actuators: list[tuple[str, Attrs]] = field(default_factory=list)
    option: Attrs = field(default_factory=dict)

    def render(self, mesh_prefix: str = "") -> tuple[str, dict[str, str]]:
        """(XML text, {file name: OBJ text}) with mesh files named `<mesh_prefix><mesh name>.obj`."""
        files = {f"{mesh_prefix}{m.name}.obj": m.obj_text() for m in self.meshes}
        lines = ['<mujoco model="fragment">']
        if self.compiler:
            lines.append(f"  <compiler{_attrs(self.compiler)}/>")
        if self.option:
            lines.append(f"  <option{_attrs(self.option)}/>")
        if self.defaults is not None:
            lines += _render_main(self.defaults, self.split_main)
        if self.meshes or self.materials:
            lines.append("  <asset>")
            for mesh in self.meshes:
                attrs = {"name": mesh.name, "file": f"{mesh_prefix}{mesh.name}.obj", **mesh.attrs}
                lines.append(f"    <mesh{_attrs(attrs)}/>")
            for material in self.materials:
                lines.append(f"    <material{_attrs(material)}/>")
            lines.append("  </asset>")
        lines.append("  <worldbody>")
        for element in self.world:
            lines.append(f"    <{element.tag}{_attrs(element.attrs)}/>")
        for body in self.bodies:
            lines += _render_body(body, 2)
        lines.append("  </worldbody>")
        if self.actuators:
            lines.append("  <actuator>")
            for tag, attrs in self.actuators:
                lines.append(f"    <{tag}{_attrs(attrs)}/>")
            lines.append("  </actuator>")
        lines.append("</mujoco>")
        return "\n".join(lines) + "\n", files


@dataclass
class RawDocument:
    """A hand-written fragment (corner cases, regressions): the XML and the files beside it."""

    xml: str
    files: dict[str, str] = field(default_factory=dict)
    label: str = ""

    def render(self, mesh_prefix: str = "") -> tuple[str, dict[str, str]]:
        if not mesh_prefix:
            return self.xml, dict(self.files)
        xml = self.xml
        for name in self.files:
            xml = xml.replace(f'"{name}"', f'"{mesh_prefix}{name}"')
        return xml, {f"{mesh_prefix}{name}": text for name, text in self.files.items()}


def write(document: Document | RawDocument, folder: str | os.PathLike, stem: str = "fragment") -> Path:
    """Write the document and its mesh files into `folder`; returns the path of the XML file."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    xml, files = document.render(mesh_prefix=f"{stem}." if stem != "fragment" else "")
    for name, text in files.items():
        (folder / name).write_text(text)
    path = folder / f"{stem}.xml"
    path.write_text(xml)
    return path


def _attrs(attrs: Attrs) -> str:
    return "".join(f" {key}={quoteattr(str(value))}" for key, value in attrs.items())


def _class_elements(cls: DefaultClass) -> list[str]:
    out = []
    for tag in ("geom", "joint", "site", "mesh", "material"):
        attrs = getattr(cls, tag)
        if attrs is not None:
            out.append(f"<{tag}{_attrs(attrs)}/>")
    if cls.actuator is not None:
        out.append(f"<{cls.actuator[0]}{_attrs(cls.actuator[1])}/>")
    return out


def _render_class(cls: DefaultClass, depth: int) -> list[str]:
    pad = "  " * depth
    head = f"{pad}<default class={quoteattr(cls.name)}>" if cls.name else f"{pad}<default>"
    elements = [f"{pad}  {e}" for e in _class_elements(cls)]
    children = [line for child in cls.children for line in _render_class(child, depth + 1)]
    body = children + elements if cls.children_first else elements + children
    return [head, *body, f"{pad}</default>"]


def _render_main(main: DefaultClass, split: bool) -> list[str]:
    if not split or not main.geom or len(main.geom) < 2:
        return _render_class(main, 1)
    keys = list(main.geom)
    half = len(keys) // 2
    first = DefaultClass(None, geom={k: main.geom[k] for k in keys[:half]})
    rest = DefaultClass(
        None,
        {k: main.geom[k] for k in keys[half:]},
        main.joint,
        main.site,
        main.mesh,
        main.material,
        main.actuator,
        main.children,
        main.children_first,
    )
    return _render_class(first, 1) + _render_class(rest, 1)


def _render_body(body: Body, depth: int) -> list[str]:
    pad = "  " * depth
    inner = [f"{pad}  <{e.tag}{_attrs(e.attrs)}/>" for e in body.elements]
    inner += [line for child in body.children for line in _render_body(child, depth + 1)]
    if not inner:
        return [f"{pad}<{body.tag}{_attrs(body.attrs)}/>"]
    return [f"{pad}<{body.tag}{_attrs(body.attrs)}>", *inner, f"{pad}</{body.tag}>"]

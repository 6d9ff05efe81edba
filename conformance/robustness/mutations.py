"""Mutations of a real MJCF document: the ways a file a user hands the loader can be wrong, too big or unusual.

Each kind is a function `(root, rng) -> description` that edits an ElementTree in place (or, for the byte-level
kinds, `(data, rng) -> (data, description)`); `mutate` picks one kind and returns the mutant's bytes. The same
(source, seed, index) always gives the same mutant, so a run's mutant can be rebuilt from its record."""

from __future__ import annotations

import random
import xml.etree.ElementTree as ET
from collections.abc import Callable
from dataclasses import dataclass

# values a number can be set to: non-finite, beyond float32, below float32's normal range, zero, negative
BAD_NUMBERS = ("nan", "inf", "-inf", "1e30", "-1e30", "1e39", "1e-30", "0", "-1")

# numeric attributes by element, so that every class gets mutated even where the document does not set it
NUMERIC = {
    "option": ("timestep", "gravity", "density", "viscosity", "wind", "impratio", "tolerance", "iterations"),
    "body": ("pos", "quat", "euler", "axisangle", "gravcomp"),
    "inertial": ("pos", "mass", "diaginertia", "fullinertia", "quat"),
    "joint": (
        "pos",
        "axis",
        "range",
        "damping",
        "stiffness",
        "armature",
        "frictionloss",
        "springref",
        "ref",
        "solreflimit",
        "solimplimit",
        "margin",
    ),
    "geom": (
        "pos",
        "quat",
        "size",
        "fromto",
        "mass",
        "density",
        "friction",
        "solref",
        "solimp",
        "margin",
        "gap",
        "priority",
        "condim",
    ),
    "site": ("pos", "size", "quat"),
    "motor": ("gear", "ctrlrange", "forcerange"),
    "position": ("kp", "kv", "ctrlrange", "gear", "timeconst"),
    "velocity": ("kv", "ctrlrange"),
    "general": ("gainprm", "biasprm", "dynprm", "ctrlrange", "gear", "actrange"),
    "fixed": ("stiffness", "damping", "range", "springlength"),
    "spatial": ("stiffness", "damping", "range", "width"),
    "weld": ("relpose", "solref", "torquescale"),
    "connect": ("anchor", "solref", "solimp"),
    "mesh": ("scale",),
    "camera": ("fovy", "pos"),
}
REFERENCES = (
    "joint",
    "body",
    "geom",
    "site",
    "mesh",
    "material",
    "texture",
    "class",
    "childclass",
    "tendon",
    "body1",
    "body2",
    "joint1",
    "joint2",
    "geom1",
    "geom2",
    "site1",
    "site2",
    "target",
    "hfield",
)
FILES = ("mesh", "texture", "hfield", "skin")
# elements the loader does not map (or maps only in part), to be mixed into a real document; {body} is a body name
UNSUPPORTED = {
    "worldbody": (
        (
            '<flexcomp name="mutant_flex" type="grid" count="3 3 1" spacing=".05 .05 .05" pos="0 0 2" '
            'dim="2" radius=".005"/>'
        ),
        ('<body name="mutant_mocap" mocap="true" pos="0 0 2"><geom size=".05" contype="0" conaffinity="0"/></body>'),
        (
            '<replicate count="3" offset=".2 0 0"><body name="mutant_rep" pos="0 0 3"><freejoint/>'
            '<geom size=".03"/></body></replicate>'
        ),
        '<light name="mutant_light" pos="0 0 3" mode="targetbody" target="{body}"/>',
        (
            '<body name="mutant_ball" pos="0 0 2"><joint type="ball" damping=".1" range="0 1"/>'
            '<geom size=".03" mass="1e-9"/></body>'
        ),
    ),
    "actuator": (
        '<adhesion body="{body}" ctrlrange="0 1" gain="5"/>',
        '<muscle name="mutant_muscle" tendon="mutant_tendon"/>',
        '<damper name="mutant_damper" joint="{joint}" kv="1" ctrlrange="0 1"/>',
        '<intvelocity joint="{joint}" kp="10" actrange="-1 1"/>',
    ),
    "tendon": ('<spatial name="mutant_tendon"><site site="{site}"/><site site="{site2}"/></spatial>',),
    "sensor": ('<jointpos joint="{joint}"/>', '<framepos objtype="body" objname="{body}"/>', '<touch site="{site}"/>'),
    "contact": ('<exclude body1="{body}" body2="{body2}"/>',),
    "equality": ('<weld body1="{body}"/>', '<joint joint1="{joint}" polycoef="0 2 0 0 0"/>'),
}


@dataclass(frozen=True)
class Mutant:
    """A mutated document: the kind of mutation, what it did, and the document's bytes."""

    kind: str
    description: str
    data: bytes


def _named(root: ET.Element, tag: str) -> list[str]:
    return [e.get("name") for e in root.iter(tag) if e.get("name")]


def _elements(root: ET.Element) -> list[ET.Element]:
    return [e for e in root.iter() if isinstance(e.tag, str)]


def _section(root: ET.Element, tag: str) -> ET.Element:
    found = root.find(tag)
    if found is None:
        found = ET.SubElement(root, tag)
    return found


def _bad_number(value: str, rng: random.Random) -> str:
    tokens = value.split() or ["0"]
    bad = rng.choice(BAD_NUMBERS)
    if rng.random() < 0.5:
        return " ".join(bad for _ in tokens)
    tokens[rng.randrange(len(tokens))] = bad
    return " ".join(tokens)


def numeric_value(root: ET.Element, rng: random.Random) -> str:
    """One numeric attribute (class chosen first, so that rare classes are hit as often as common ones) set to a
    non-finite, huge, tiny, zero or negative value, on an element that has it or one of the class's elements."""
    present = sorted({(e.tag, a) for e in _elements(root) for a in e.attrib if a in NUMERIC.get(e.tag, ())})
    classes = sorted({(t, a) for t, attrs in NUMERIC.items() for a in attrs if any(True for _ in root.iter(t))})
    tag, attr = rng.choice(
        present if present and rng.random() < 0.5 else (classes or present or [("option", "timestep")])
    )
    candidates = list(root.iter(tag)) or [_section(root, tag)]
    element = rng.choice(candidates)
    old = element.get(attr, "1")
    element.set(attr, _bad_number(old, rng))
    return f"{tag}.{attr}: {old!r} -> {element.get(attr)!r}"


def dropped_attribute(root: ET.Element, rng: random.Random) -> str:
    elements = [e for e in _elements(root) if e.attrib]
    element = rng.choice(elements)
    attr = rng.choice(sorted(element.attrib))
    del element.attrib[attr]
    return f"{element.tag}.{attr} dropped"


def duplicate_name(root: ET.Element, rng: random.Random) -> str:
    named = [e for e in _elements(root) if e.get("name")]
    if len(named) < 2:
        return empty_name(root, rng)
    first = rng.choice(named)
    same = [e for e in named if e.tag == first.tag and e is not first] or [e for e in named if e is not first]
    other = rng.choice(same)
    old = other.get("name")
    other.set("name", first.get("name"))
    return f"{other.tag} {old!r} renamed to {first.tag} {first.get('name')!r}"


def empty_name(root: ET.Element, rng: random.Random) -> str:
    named = [e for e in _elements(root) if e.get("name")] or _elements(root)
    element = rng.choice(named)
    old = element.get("name")
    element.set("name", "")
    return f"{element.tag} {old!r} named ''"


def dangling_reference(root: ET.Element, rng: random.Random) -> str:
    refs = [(e, a) for e in _elements(root) for a in e.attrib if a in REFERENCES]
    if not refs:
        return garbage_attribute(root, rng)
    element, attr = rng.choice(refs)
    old = element.get(attr)
    element.set(attr, "mutant_missing")
    return f"{element.tag}.{attr}: {old!r} -> 'mutant_missing'"


def missing_file(root: ET.Element, rng: random.Random) -> str:
    files = [e for e in _elements(root) if e.tag in FILES and e.get("file")]
    if files:
        element = rng.choice(files)
        old = element.get("file")
        element.set("file", "mutant_missing" + (old[old.rfind(".") :] if "." in old else ".stl"))
        return f"{element.tag}.file: {old!r} -> {element.get('file')!r}"
    asset = _section(root, "asset")
    ET.SubElement(asset, "mesh", name="mutant_mesh", file="mutant_missing.stl")
    body = ET.SubElement(_section(root, "worldbody"), "body", name="mutant_body", pos="0 0 1")
    ET.SubElement(body, "geom", type="mesh", mesh="mutant_mesh")
    return "a geom on a mesh whose file is missing"


def garbage_attribute(root: ET.Element, rng: random.Random) -> str:
    element = rng.choice(_elements(root))
    if element.attrib and rng.random() < 0.5:
        attr = rng.choice(sorted(element.attrib))
        element.set(attr, rng.choice(("garbage", "1 2 3 4 5 6 7 8 9 10 11 12 13", "", "0x1F", "true", "-")))
        return f"{element.tag}.{attr} set to {element.get(attr)!r}"
    element.set("mutant_garbage", "1")
    return f"{element.tag} gets an unknown attribute"


def unsupported_element(root: ET.Element, rng: random.Random) -> str:
    names = {k: _named(root, k) for k in ("body", "joint", "site")}
    section = rng.choice(sorted(UNSUPPORTED))
    snippet = rng.choice(UNSUPPORTED[section])
    bodies = names["body"] or ["world"]
    sites = names["site"] or ["mutant_site"]
    text = snippet.format(
        body=rng.choice(bodies),
        body2=rng.choice(bodies),
        joint=rng.choice(names["joint"] or ["mutant_joint"]),
        site=rng.choice(sites),
        site2=rng.choice(sites),
    )
    if "mutant_tendon" in text and section == "actuator":
        _section(root, "tendon").append(ET.fromstring(UNSUPPORTED["tendon"][0].format(site=sites[0], site2=sites[-1])))
    _section(root, section).append(ET.fromstring(text))
    return f"{section} gets {text}"


def _chain(count: int, prefix: str) -> ET.Element:
    """A hinged chain hanging from 20 m beside the origin, tilted so it swings, its geoms colliding with nothing (a
    chain started inside the robot or behind an arena's wall plane is a contact question, not a robustness one)."""
    top = ET.Element("body", name=f"{prefix}0", pos=f"20 20 {count * 0.02 + 1:g}", euler="0 0.3 0")
    body = top
    for i in range(count):
        ET.SubElement(body, "joint", name=f"{prefix}_j{i}", type="hinge", axis="0 1 0", damping="0.01")
        ET.SubElement(
            body, "geom", type="capsule", fromto="0 0 0 0 0 -.02", size=".005", mass=".01", contype="0", conaffinity="0"
        )
        if i + 1 < count:
            body = ET.SubElement(body, "body", name=f"{prefix}{i + 1}", pos="0 0 -.02")
    return top


def long_chain(root: ET.Element, rng: random.Random) -> str:
    count = rng.randint(40, 200)
    _section(root, "worldbody").append(_chain(count, "mutant_chain"))
    return f"a hinged chain of {count} bodies"


def deep_chain(root: ET.Element, rng: random.Random) -> str:
    _section(root, "worldbody").append(_chain(500, "mutant_deep"))
    return "a hinged chain of 500 bodies"


def huge_model(root: ET.Element, rng: random.Random) -> str:
    world = _section(root, "worldbody")
    free = rng.random() < 0.5
    count = 10_000 if not free else 2_000
    for i in range(count):
        body = ET.SubElement(world, "body", name=f"mutant_b{i}", pos=f"{i % 100 * 0.1} {i // 100 * 0.1} 3")
        if free:
            ET.SubElement(body, "freejoint")
        ET.SubElement(body, "geom", size=".02", contype="0", conaffinity="0")
    return f"{count} {'free' if free else 'static'} bodies"


def truncated(data: bytes, rng: random.Random) -> tuple[bytes, str]:
    cut = rng.randrange(len(data))
    return data[:cut], f"truncated at byte {cut} of {len(data)}"


def binary_garbage(data: bytes, rng: random.Random) -> tuple[bytes, str]:
    junk = bytes(rng.randrange(256) for _ in range(rng.randint(1, 64)))
    where = rng.random()
    if where < 0.2:
        return junk * rng.randint(1, 64), "the whole file is binary garbage"
    at = rng.randrange(len(data))
    return data[:at] + junk + data[at + len(junk) :], f"{len(junk)} bytes of garbage at byte {at}"


TREE_KINDS: dict[str, Callable[[ET.Element, random.Random], str]] = {
    "numeric_value": numeric_value,
    "dropped_attribute": dropped_attribute,
    "duplicate_name": duplicate_name,
    "empty_name": empty_name,
    "dangling_reference": dangling_reference,
    "missing_file": missing_file,
    "garbage_attribute": garbage_attribute,
    "unsupported_element": unsupported_element,
    "long_chain": long_chain,
    "deep_chain": deep_chain,
    "huge_model": huge_model,
}
BYTE_KINDS: dict[str, Callable[[bytes, random.Random], tuple[bytes, str]]] = {
    "truncated": truncated,
    "binary_garbage": binary_garbage,
}
# how often each kind is drawn: numbers most (many classes), the expensive huge models rarely
WEIGHTS = {
    "numeric_value": 30,
    "dropped_attribute": 8,
    "duplicate_name": 5,
    "empty_name": 3,
    "dangling_reference": 6,
    "missing_file": 4,
    "garbage_attribute": 6,
    "unsupported_element": 12,
    "long_chain": 3,
    "deep_chain": 1,
    "huge_model": 0.3,
    "truncated": 4,
    "binary_garbage": 4,
}


def mutate(data: bytes, seed: int, index: int, kind: str | None = None) -> Mutant:
    """Mutant `index` of a document under `seed` (`kind` forces one kind). A document ElementTree cannot parse
    gets a byte-level kind."""
    rng = random.Random(f"{seed}:{index}")
    kinds = sorted(WEIGHTS)
    kind = kind or rng.choices(kinds, weights=[WEIGHTS[k] for k in kinds])[0]
    if kind in BYTE_KINDS:
        mutated, description = BYTE_KINDS[kind](data, rng)
        return Mutant(kind, description, mutated)
    try:
        root = ET.fromstring(data)
    except ET.ParseError:
        mutated, description = truncated(data, rng)
        return Mutant("truncated", description, mutated)
    description = TREE_KINDS[kind](root, rng)
    return Mutant(kind, description, ET.tostring(root))

"""Hypothesis strategies for MJCF documents built around default classes.

`documents()` draws a compiler setting, a default-class tree (depth up to 3 below `main`, unique names, at most
one element of each kind per class), small meshes, and a body/frame tree whose elements pick classes through
`class=` (including `class="main"`) and `childclass` on bodies and frames. Most draws compile; the rest exercise
error parity. `broken_documents()` adds one deliberate mistake from a list MuJoCo is known to reject.
`kinematic_trees()` draws class-free chains with random orientations and joint axes.

Every number is drawn as a small integer and written as a short decimal, and every optional attribute is left
out when its draw shrinks to 0, so shrunk counterexamples are short, readable files.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from hypothesis import strategies as st

from .document import Attrs, Body, DefaultClass, Document, Element, MeshAsset, RawDocument

PRIMITIVES = ("sphere", "capsule", "ellipsoid", "cylinder", "box")
FROMTO_TYPES = ("capsule", "cylinder", "box", "ellipsoid")
SEGMENT_TYPES = ("capsule", "cylinder")  # size needs 1 number with fromto; box/ellipsoid need 3 (or 2)
SHORTCUTS = ("motor", "position", "velocity", "general")
EULERSEQS = ("xyz", "XYZ", "zyx", "ZYX", "xzy", "XZY", "zxz", "ZXZ", "yxz", "xYz")


def _dec(lo: int, hi: int, scale: float) -> st.SearchStrategy[str]:
    """A decimal `i * scale` for integer i in [lo, hi], written short."""
    return st.integers(lo, hi).map(lambda i: f"{i * scale:.6g}")


def _vec(n: int, lo: int, hi: int, scale: float) -> st.SearchStrategy[str]:
    return st.lists(_dec(lo, hi, scale), min_size=n, max_size=n).map(" ".join)


SIZE = _dec(2, 30, 0.01)  # 0.02 .. 0.3 m
POS = _vec(3, -30, 30, 0.01)
DIRECTION = st.tuples(*[st.integers(-2, 2)] * 3).filter(any).map(lambda v: " ".join(map(str, v)))
QUAT = st.tuples(*[st.integers(-3, 3)] * 4).filter(any).map(lambda v: " ".join(map(str, v)))


def angle(unit: str, lo_deg: int = -180, hi_deg: int = 180) -> st.SearchStrategy[str]:
    """An angle in the compiler's unit (degrees as integers, radians with two decimals)."""
    if unit == "radian":
        return _dec(round(lo_deg * 3.14159 / 180 * 100), round(hi_deg * 3.14159 / 180 * 100), 0.01)
    return st.integers(lo_deg, hi_deg).map(str)


def orientation(unit: str) -> st.SearchStrategy[Attrs]:
    """No rotation or one of the alternative orientation forms MJCF accepts on bodies and frames."""
    a = angle(unit)
    return st.one_of(
        st.just({}),
        st.tuples(a, a, a).map(lambda t: {"euler": " ".join(t)}),
        st.tuples(DIRECTION, a).map(lambda t: {"axisangle": f"{t[0]} {t[1]}"}),
        QUAT.map(lambda q: {"quat": q}),
        st.tuples(DIRECTION, DIRECTION).filter(lambda t: _independent(t[0], t[1]))
        .map(lambda t: {"xyaxes": f"{t[0]} {t[1]}"}),
        DIRECTION.map(lambda d: {"zaxis": d}),
    )


def _independent(a: str, b: str) -> bool:
    x = [int(v) for v in a.split()]
    y = [int(v) for v in b.split()]
    cross = (x[1] * y[2] - x[2] * y[1], x[2] * y[0] - x[0] * y[2], x[0] * y[1] - x[1] * y[0])
    return any(cross)


@dataclass
class _Context:
    """What later draws need to know: units, class names, meshes, materials, joint names."""

    unit: str = "degree"
    classes: list[str] = field(default_factory=list)
    meshes: list[str] = field(default_factory=list)
    materials: list[str] = field(default_factory=list)
    counters: dict[str, int] = field(default_factory=dict)
    joints: list[str] = field(default_factory=list)
    main_size: bool = False  # main sets a full size vector, so partial sizes on elements stay valid

    def name(self, kind: str) -> str:
        n = self.counters.get(kind, 0)
        self.counters[kind] = n + 1
        return f"{kind}{n}"


def _optional(draw, attrs: Attrs, key: str, strategy, p: bool | None = None) -> None:
    if p if p is not None else draw(st.booleans()):
        attrs[key] = draw(strategy)


@st.composite
def geom_attrs(draw, ctx: _Context, in_default: bool, world: bool = False) -> Attrs:
    """Geom attributes: type, full or partial size, pose (pos + orientation or fromto), contact bits,
    group, rgba, mass or density, friction, material, mesh."""
    attrs: Attrs = {}
    kinds = list(PRIMITIVES) + (["mesh"] if ctx.meshes else []) + (["plane"] if world else [])
    if draw(st.booleans()):
        attrs["type"] = draw(st.sampled_from(kinds))
    kind = attrs.get("type")
    if kind == "mesh" or (kind is None and ctx.meshes and draw(st.integers(0, 4)) == 4):
        attrs["mesh"] = draw(st.sampled_from(ctx.meshes))  # without type: a primitive fitted to the mesh
    if draw(st.booleans()) or not (in_default or ctx.main_size):
        full = not (in_default or ctx.main_size)
        attrs["size"] = " ".join(draw(st.lists(SIZE, min_size=3 if full else 1, max_size=3)))
    rare = 5 if in_default else 1  # a default pos clashes with every fromto of the class's geoms
    if draw(st.integers(0, rare)) == rare:
        attrs["pos"] = draw(POS)
    if kind in FROMTO_TYPES and draw(st.integers(0, 3)) == 3:
        attrs.pop("pos", None)
        attrs["fromto"] = draw(_vec(6, -20, 20, 0.01).filter(lambda v: v.split()[:3] != v.split()[3:]))
    elif draw(st.integers(0, 2)) == 2:
        a = angle(ctx.unit)
        attrs.update(draw(st.one_of(st.tuples(a, a, a).map(lambda t: {"euler": " ".join(t)}),
                                    st.tuples(DIRECTION, a).map(lambda t: {"axisangle": f"{t[0]} {t[1]}"}))))
    _optional(draw, attrs, "contype", st.integers(0, 3).map(str))
    _optional(draw, attrs, "conaffinity", st.integers(0, 3).map(str))
    _optional(draw, attrs, "group", st.integers(0, 5).map(str))
    _optional(draw, attrs, "rgba", _vec(4, 0, 10, 0.1))
    mass = draw(st.sampled_from(["", "mass", "density"]))
    if mass == "mass":
        attrs["mass"] = draw(_dec(1, 50, 0.1))
    elif mass == "density":
        attrs["density"] = draw(_dec(1, 20, 100.0))
    _optional(draw, attrs, "friction", st.lists(_dec(1, 20, 0.1), min_size=1, max_size=3).map(" ".join))
    if ctx.materials:
        _optional(draw, attrs, "material", st.sampled_from(ctx.materials))
    if not in_default:
        _optional(draw, attrs, "class", st.sampled_from(["main", *ctx.classes]), p=bool(ctx.classes)
                  and draw(st.booleans()))
    return attrs


@st.composite
def joint_attrs(draw, ctx: _Context, in_default: bool) -> Attrs:
    """Joint attributes: type, axis, range, limited, damping, armature, ref, stiffness, springref,
    frictionloss."""
    attrs: Attrs = {}
    _optional(draw, attrs, "type", st.sampled_from(["hinge", "hinge", "slide", "ball"]))
    _optional(draw, attrs, "axis", DIRECTION)
    if draw(st.booleans()):
        if attrs.get("type") == "ball":
            attrs["range"] = f"0 {draw(angle(ctx.unit, 10, 170))}"
        else:
            lo = draw(st.one_of(st.just(0), st.integers(-170, -10)))  # 0 also suits a ball from a class
            hi = draw(st.integers(10, 170))
            attrs["range"] = (f"{lo} {hi}" if ctx.unit == "degree"
                              else f"{lo * 0.0175:.3g} {hi * 0.0175:.3g}")
    limited = ["true", "false", "auto"] if "range" in attrs else ["false", "auto"]
    _optional(draw, attrs, "limited", st.sampled_from(limited), p=draw(st.integers(0, 3)) == 3)
    # elements write damping/armature less often than classes: most values then come from a default class
    sparse = None if in_default else draw(st.integers(0, 3)) == 3
    _optional(draw, attrs, "damping", _dec(0, 20, 0.05), p=sparse)
    _optional(draw, attrs, "armature", _dec(0, 20, 0.01), p=sparse)
    _optional(draw, attrs, "ref", angle(ctx.unit, -30, 30), p=draw(st.integers(0, 3)) == 3)
    _optional(draw, attrs, "stiffness", _dec(0, 20, 0.5), p=draw(st.integers(0, 3)) == 3)
    _optional(draw, attrs, "springref", angle(ctx.unit, -30, 30), p=draw(st.integers(0, 3)) == 3)
    _optional(draw, attrs, "frictionloss", _dec(0, 10, 0.01), p=draw(st.integers(0, 7)) == 7)
    _element_class(draw, attrs, ctx, in_default)
    return attrs


def _element_class(draw, attrs: Attrs, ctx: _Context, in_default: bool) -> None:
    """Half the elements outside defaults name a class (main or a declared one)."""
    if not in_default and ctx.classes and draw(st.booleans()):
        attrs["class"] = draw(st.sampled_from(["main", *ctx.classes]))


@st.composite
def site_attrs(draw, ctx: _Context, in_default: bool) -> Attrs:
    attrs: Attrs = {}
    _optional(draw, attrs, "type", st.sampled_from(PRIMITIVES))
    _optional(draw, attrs, "size", st.lists(SIZE, min_size=1, max_size=3).map(" ".join))
    _optional(draw, attrs, "pos", POS)
    _optional(draw, attrs, "rgba", _vec(4, 0, 10, 0.1))
    _optional(draw, attrs, "group", st.integers(0, 5).map(str))
    _element_class(draw, attrs, ctx, in_default)
    return attrs


@st.composite
def actuator_attrs(draw, ctx: _Context, tag: str) -> Attrs:
    """Attributes of one actuator shortcut (motor, position, velocity, general)."""
    attrs: Attrs = {}
    _optional(draw, attrs, "gear", _dec(1, 30, 0.5))
    if draw(st.booleans()):
        lo, hi = draw(st.integers(-30, -1)), draw(st.integers(1, 30))
        attrs["ctrlrange"] = f"{lo / 10:g} {hi / 10:g}"
    _optional(draw, attrs, "forcerange", st.integers(1, 50).map(lambda f: f"-{f} {f}"),
              p=draw(st.integers(0, 3)) == 3)
    if tag == "position":
        _optional(draw, attrs, "kp", _dec(1, 100, 1.0))
        _optional(draw, attrs, "kv", _dec(0, 20, 0.5))
    elif tag == "velocity":
        _optional(draw, attrs, "kv", _dec(1, 20, 0.5))
    elif tag == "general":
        if draw(st.booleans()):
            attrs["gainprm"] = draw(_dec(1, 100, 1.0))
        if draw(st.booleans()):
            kp, kv = draw(_dec(0, 100, 1.0)), draw(_dec(0, 20, 0.5))
            attrs["biasprm"] = f"0 -{kp} -{kv}"
            attrs["biastype"] = "affine"
        if draw(st.integers(0, 3)) == 3:  # activation dynamics: the gain multiplies the activation
            attrs["dyntype"] = draw(st.sampled_from(["filter", "filterexact", "integrator"]))
            if attrs["dyntype"] != "integrator":
                attrs["dynprm"] = draw(_dec(1, 20, 0.01))
            _optional(draw, attrs, "actearly", st.sampled_from(["true", "false"]))
    return attrs


@st.composite
def default_class(draw, ctx: _Context, name: str | None, depth: int) -> DefaultClass:
    cls = DefaultClass(name)
    if draw(st.booleans()) or name is None:
        cls.geom = draw(geom_attrs(ctx, in_default=True))
        if name is None:  # a full size in main keeps most documents valid (partial sizes come below)
            cls.geom["size"] = " ".join(draw(st.lists(SIZE, min_size=3, max_size=3)))
    if draw(st.booleans()):
        cls.joint = draw(joint_attrs(ctx, in_default=True))
    if draw(st.integers(0, 2)) == 2:
        cls.site = draw(site_attrs(ctx, in_default=True))
    if draw(st.integers(0, 2)) == 2:
        cls.mesh = {"scale": draw(_vec(3, 5, 30, 0.1))}
    if name is None and ctx.materials and draw(st.integers(0, 3)) == 3:
        cls.material = {"rgba": draw(_vec(4, 0, 10, 0.1)), "specular": draw(_dec(0, 10, 0.1))}
    if draw(st.booleans()):
        tag = draw(st.sampled_from(SHORTCUTS))
        cls.actuator = (tag, draw(actuator_attrs(ctx, tag)))
    if depth < 3:
        for _ in range(draw(st.integers(0, 2 if depth else 3))):
            child = ctx.name("c")
            ctx.classes.append(child)
            cls.children.append(draw(default_class(ctx, child, depth + 1)))
    cls.children_first = bool(cls.children) and draw(st.booleans())
    return cls


BOX_FACES = [(0, 2, 1), (1, 2, 3), (4, 5, 6), (5, 7, 6), (0, 1, 4), (1, 5, 4),
             (2, 6, 3), (3, 6, 7), (0, 4, 2), (2, 4, 6), (1, 3, 5), (3, 7, 5)]
TETRA_FACES = [(0, 2, 1), (0, 1, 3), (0, 3, 2), (1, 2, 3)]


@st.composite
def mesh_asset(draw, ctx: _Context, name: str) -> MeshAsset:
    """A small closed mesh: a jittered box or a tetrahedron, off-centre so MuJoCo re-centres it."""
    offset = [draw(st.integers(-10, 10)) * 0.01 for _ in range(3)]
    if draw(st.booleans()):
        half = [draw(st.integers(2, 15)) * 0.01 for _ in range(3)]
        vertices = []
        for i in range(8):
            corner = [(1 if i >> k & 1 else -1) * half[k] for k in range(3)]
            jitter = [draw(st.integers(-2, 2)) * 0.002 for _ in range(3)]
            vertices.append(tuple(c + j + o for c, j, o in zip(corner, jitter, offset)))
        faces = BOX_FACES
    else:
        s = draw(st.integers(3, 15)) * 0.01
        base = [(0, 0, 0), (s, 0, 0), (0, s * 1.2, 0), (0, 0, s * 0.8)]
        vertices = [tuple(c + o for c, o in zip(v, offset)) for v in base]
        faces = TETRA_FACES
    attrs: Attrs = {}
    if ctx.classes and draw(st.integers(0, 2)) == 2:
        attrs["class"] = draw(st.sampled_from(["main", *ctx.classes]))
    if draw(st.integers(0, 3)) == 3:
        attrs["scale"] = draw(_vec(3, 5, 20, 0.1))
    return MeshAsset(name, vertices, faces, attrs)


@st.composite
def body_tree(draw, ctx: _Context, depth: int, top: bool, max_depth: int = 3) -> Body:
    """A body (or a frame holding bodies) with joints, geoms and sites that pick classes."""
    if draw(st.integers(0, 4)) == 4 and depth < max_depth:
        frame = Body("frame", {})
        _optional(draw, frame.attrs, "pos", POS)
        frame.attrs.update(draw(orientation(ctx.unit)))
        if ctx.classes and draw(st.booleans()):
            frame.attrs["childclass"] = draw(st.sampled_from(ctx.classes))
        if draw(st.booleans()):
            frame.elements.append(Element("geom", {"name": ctx.name("g"), **draw(geom_attrs(ctx, False))}))
        frame.children = [draw(body_tree(ctx, depth + 1, top, max_depth))
                          for _ in range(draw(st.integers(1, 2)))]
        return frame
    body = Body("body", {"name": ctx.name("b")})
    _optional(draw, body.attrs, "pos", POS)
    body.attrs.update(draw(orientation(ctx.unit)))
    if ctx.classes and draw(st.integers(0, 2)) == 2:
        body.attrs["childclass"] = draw(st.sampled_from(["main", *ctx.classes]))
    if top and draw(st.integers(0, 3)) == 3:
        name = ctx.name("j")
        if draw(st.booleans()):
            body.elements.append(Element("freejoint", {"name": name}))
        else:
            body.elements.append(Element("joint", {"name": name, "type": "free",
                                                   **_drop(draw(joint_attrs(ctx, False)), "type", "range")}))
    else:
        for _ in range(draw(st.integers(0, 2))):  # two balls are MuJoCo's limit of 6 dofs per body
            name = ctx.name("j")
            ctx.joints.append(name)
            body.elements.append(Element("joint", {"name": name, **draw(joint_attrs(ctx, False))}))
    for _ in range(draw(st.integers(1, 2))):
        body.elements.append(Element("geom", {"name": ctx.name("g"), **draw(geom_attrs(ctx, False))}))
    if draw(st.integers(0, 3)) == 3:
        body.elements.append(Element("site", {"name": ctx.name("s"), **draw(site_attrs(ctx, False))}))
    if depth < max_depth:
        count = draw(st.integers(0, 2 if max_depth <= 3 else 1))
        body.children = [draw(body_tree(ctx, depth + 1, False, max_depth)) for _ in range(count)]
    return body


def _drop(attrs: Attrs, *keys: str) -> Attrs:
    return {k: v for k, v in attrs.items() if k not in keys}


@st.composite
def compiler_attrs(draw) -> Attrs:
    """`<compiler angle=... eulerseq=... autolimits=...>` variations (each may be absent)."""
    attrs: Attrs = {}
    _optional(draw, attrs, "angle", st.sampled_from(["degree", "radian"]))
    _optional(draw, attrs, "eulerseq", st.sampled_from(EULERSEQS))
    _optional(draw, attrs, "autolimits", st.sampled_from(["true", "false"]), p=draw(st.integers(0, 4)) == 4)
    return attrs


@st.composite
def documents(draw, max_bodies: int = 3) -> Document:
    """A document with a default-class tree, meshes, materials, world geoms, bodies/frames and actuators."""
    compiler = draw(compiler_attrs())
    ctx = _Context(unit=compiler.get("angle", "degree"))
    ctx.materials = [f"mat{i}" for i in range(draw(st.integers(0, 2)))]
    ctx.meshes = [f"mesh{i}" for i in range(draw(st.integers(0, 2)))]
    defaults = draw(default_class(ctx, None, 0)) if draw(st.integers(0, 5)) else None
    ctx.main_size = defaults is not None
    meshes = [draw(mesh_asset(ctx, name)) for name in ctx.meshes]
    materials = [{"name": name, **({"rgba": draw(_vec(4, 0, 10, 0.1))} if draw(st.booleans()) else {})}
                 for name in ctx.materials]
    world = [Element("geom", {"name": ctx.name("g"), **draw(geom_attrs(ctx, False, world=True))})
             for _ in range(draw(st.integers(0, 2)))]
    bodies = [draw(body_tree(ctx, 0, True)) for _ in range(draw(st.integers(1, max_bodies)))]
    actuators = []
    if ctx.joints:
        for _ in range(draw(st.integers(0, 3))):
            tag = draw(st.sampled_from(SHORTCUTS))
            attrs = {"name": ctx.name("a"), "joint": draw(st.sampled_from(ctx.joints))}
            if ctx.classes and draw(st.booleans()):
                attrs["class"] = draw(st.sampled_from(["main", *ctx.classes]))
            attrs.update(draw(actuator_attrs(ctx, tag)) if draw(st.booleans()) else {})
            actuators.append((tag, attrs))
    return Document(compiler, defaults, bool(defaults) and draw(st.integers(0, 4)) == 4, meshes, materials,
                    world, bodies, actuators)


# One mistake each, spliced into a rendered valid document: (where, text). MuJoCo rejects every one.
@st.composite
def kinematic_trees(draw, max_depth: int = 6) -> Document:
    """Class-free trees (chains up to `max_depth` bodies deep) with random body orientations in every MJCF
    form, random joint axes and types, frames, and compiler angle / eulerseq variations."""
    compiler = draw(compiler_attrs())
    ctx = _Context(unit=compiler.get("angle", "degree"))
    bodies = [draw(body_tree(ctx, 0, True, max_depth)) for _ in range(draw(st.integers(1, 2)))]
    return Document(compiler, bodies=bodies)


BREAKAGES = {
    "unknown_class": ("world", '<geom class="nope" size=".1"/>'),
    "duplicate_class": ("top", '<default><default class="dup"/><default class="dup"/></default>'),
    "short_rgba": ("world", '<geom size=".1" rgba="0 1"/>'),
    "two_geoms_in_class": ("top", ('<default><default class="two"><geom size=".1"/><geom size=".2"/></default>'
                                  '</default>')),
    "named_default_element": ("top", '<default><default class="named"><site name="s"/></default></default>'),
    "body_in_default": ("top", "<default><body/></default>"),
    "renamed_main": ("top", '<default class="x"><geom size=".1"/></default>'),
    "worldbody_childclass": ("worldbody_attr", ' childclass="main"'),
    "body_class": ("world", '<body class="main"><geom size=".1"/></body>'),
    "missing_mesh_file": ("top", ('<asset><mesh name="absent" file="absent.obj"/></asset>'
                                 '<worldbody><geom type="mesh" mesh="absent"/></worldbody>')),
    "reversed_range": ("world", '<body><joint range="1 -1" limited="true"/><geom size=".1"/></body>'),
    "fromto_sphere": ("world", '<geom type="sphere" size=".1" fromto="0 0 0 0 0 .2"/>'),
    "nested_freejoint": ("world", '<body><geom size=".1"/><body><freejoint/><geom size=".1"/></body></body>'),
}


def break_document(document, breakage: str) -> RawDocument:
    """The rendered `document` with the named mistake spliced in."""
    xml, files = document.render()
    where, text = BREAKAGES[breakage]
    if where == "world":
        xml = xml.replace("<worldbody>", f"<worldbody>\n    {text}", 1)
    elif where == "worldbody_attr":
        xml = xml.replace("<worldbody>", f"<worldbody{text}>", 1)
    else:
        head, rest = xml.split("\n", 1)
        xml = f"{head}\n  {text}\n{rest}"
    return RawDocument(xml, files, label=breakage)


@st.composite
def broken_documents(draw) -> RawDocument:
    """A generated document with one mistake MuJoCo is known to reject (`label` names it)."""
    return break_document(draw(documents(max_bodies=2)), draw(st.sampled_from(sorted(BREAKAGES))))

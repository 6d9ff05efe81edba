"""Hypothesis strategies for MJCF documents built around default classes.

`documents()` draws a compiler setting, a default-class tree (depth up to 3 below `main`, unique names, at most
one element of each kind per class), small meshes, and a body/frame tree whose elements pick classes through
`class=` (including `class="main"`) and `childclass` on bodies and frames. Most draws compile; the rest exercise
error parity. `broken_documents()` adds one deliberate mistake from a list MuJoCo is known to reject.
`kinematic_trees()` draws class-free chains with random orientations and joint axes.

Few, large draws: the tree's shape (how many classes, bodies, joints, geoms, children, and whether an element
holds another one) is drawn as small integers and booleans, which hypothesis shrinks by deleting what follows
them; everything else one element decides is read from one or two drawn byte strings (`_Reader`): first its
flags (which optional attributes it writes), each at a fixed place, then the values of those it writes.
Decisions are uniform as before (hypothesis draws small integer ranges uniformly, booleans and `one_of` branches
fairly): one of n outcomes reads one byte when n divides 256 and otherwise two or three (a bias below 0.4 %), and
outcome 0 is what the old draw shrank to: an attribute left out, a number closest to 0 (or to its range's nearest
end), the first of a list. So shrunk counterexamples stay short, readable files, and every number is still a
small integer written as a short decimal.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cache
from itertools import product

from hypothesis import strategies as st

from .document import Attrs, Body, DefaultClass, Document, Element, MeshAsset, RawDocument

PRIMITIVES = ("sphere", "capsule", "ellipsoid", "cylinder", "box")
FROMTO_TYPES = ("capsule", "cylinder", "box", "ellipsoid")
SEGMENT_TYPES = ("capsule", "cylinder")  # size needs 1 number with fromto; box/ellipsoid need 3 (or 2)
SHORTCUTS = ("motor", "position", "velocity", "general")
EULERSEQS = ("xyz", "XYZ", "zyx", "ZYX", "xzy", "XZY", "zxz", "ZXZ", "yxz", "xYz")

_MORE = 16  # bytes drawn when an element's first draw runs out
# Whether an element holds another drawn element is a draw of its own (not a flag), as before the byte strings:
# hypothesis shrinks it to "no" and deletes what followed it, here the inner element's draws.
_COIN = st.booleans()
_THIRD = st.integers(0, 2)


@cache
def _chunks(size: int) -> st.SearchStrategy[bytes]:
    return st.binary(min_size=size, max_size=size)


# Lengths 1, 2, 3 of `st.lists(min_size=1, max_size=3)` in thousandths: hypothesis continues such a list with
# p = 0.617 (an average length of 2)
_ONE_TO_THREE = (383, 236 + 383)


@cache
def _ordered(lo: int, hi: int) -> tuple[int, ...]:
    """The integers of [lo, hi] in hypothesis's shrink order: 0 (or the nearer end) first, then 1, -1, 2, ..."""
    target = min(max(0, lo), hi)
    return tuple(sorted(range(lo, hi + 1), key=lambda v: (abs(v - target), v < target)))


def _nonzero(values: tuple[int, ...], n: int) -> tuple[tuple[int, ...], ...]:
    """Integer n-vectors over `values` (in shrink order) with some component nonzero, simplest first."""
    rank = {v: i for i, v in enumerate(values)}
    vectors = [v for v in product(values, repeat=n) if any(v)]
    return tuple(sorted(vectors, key=lambda v: (sum(rank[c] for c in v), [rank[c] for c in v])))


DIRECTIONS = _nonzero(_ordered(-2, 2), 3)  # the 124 axes of components -2..2
QUATS = _nonzero(_ordered(-3, 3), 4)


def _independent(x: tuple[int, ...], y: tuple[int, ...]) -> bool:
    cross = (x[1] * y[2] - x[2] * y[1], x[2] * y[0] - x[0] * y[2], x[0] * y[1] - x[1] * y[0])
    return any(cross)


XYAXES = tuple((x, y) for x in DIRECTIONS for y in DIRECTIONS if _independent(x, y))


def _ints(v: tuple[int, ...]) -> str:
    return " ".join(map(str, v))


class _Decisions:
    """Decisions read one at a time from bytes (`_byte`). `below(n)` is uniform over range(n) and 0 when its bytes
    are 0, which is where hypothesis shrinks them."""

    def _byte(self) -> int:
        raise NotImplementedError

    def below(self, n: int) -> int:
        if n <= 1:
            return 0
        if 256 % n == 0:
            return self._byte() * n >> 8
        width = 2 if n <= 256 else 3
        word = 0
        for _ in range(width):
            word = word << 8 | self._byte()
        return word * n >> (8 * width)

    def coin(self) -> bool:
        """`st.booleans()`."""
        return self.below(2) == 1

    def one_in(self, n: int) -> bool:
        """`st.integers(0, n - 1) == n - 1`."""
        return self.below(n) == n - 1

    def pick(self, options):
        """`st.sampled_from(options)`."""
        return options[self.below(len(options))]


class _Flags(_Decisions):
    """The first bytes of an element's first draw, each decision at a fixed place: which optional attributes it
    writes (and in which form)."""

    def __init__(self, reader: _Reader, size: int):
        self._reader, self._size, self._at = reader, size, 0

    def _byte(self) -> int:
        if self._at == self._size:
            raise AssertionError(f"an element read more than the {self._size} flag bytes it reserved")
        self._at += 1
        return self._reader.head()[self._at - 1]


class _Reader(_Decisions):
    """One element's decisions, read from drawn byte strings. Its first draw holds `flags` bytes for `.flags`
    (which attributes it writes) and `first` bytes of values (what nine in ten elements of its kind need, so
    one draw); later values come `_MORE` bytes at a time. Shrinking a flag to 0 leaves an attribute out and
    moves only the values read after it, never another flag."""

    def __init__(self, draw, first: int, flags: int = 0):
        self._draw = draw
        self._size = flags + first
        self._first: bytes | None = None
        self._bytes = b""
        self._at = flags
        self.flags = _Flags(self, flags)

    def head(self) -> bytes:
        if self._first is None:
            self._first = self._bytes = self._draw(_chunks(self._size))
        return self._first

    def _byte(self) -> int:
        self.head()
        if self._at == len(self._bytes):
            self._bytes, self._at = self._draw(_chunks(_MORE)), 0
        self._at += 1
        return self._bytes[self._at - 1]

    def integer(self, lo: int, hi: int) -> int:
        """`st.integers(lo, hi)`."""
        return self.pick(_ordered(lo, hi))

    def dec(self, lo: int, hi: int, scale: float) -> str:
        """A decimal `i * scale` for integer i in [lo, hi], written short."""
        return f"{self.integer(lo, hi) * scale:.6g}"

    def vec(self, n: int, lo: int, hi: int, scale: float) -> str:
        return " ".join(self.dec(lo, hi, scale) for _ in range(n))

    def one_to_three(self) -> int:
        """The length of `st.lists(min_size=1, max_size=3)`."""
        u = self.below(1000)
        return 1 if u < _ONE_TO_THREE[0] else 2 if u < _ONE_TO_THREE[1] else 3

    def size(self) -> str:
        return self.dec(2, 30, 0.01)  # 0.02 .. 0.3 m

    def sizes(self, full: bool) -> str:
        return " ".join(self.size() for _ in range(3 if full else self.one_to_three()))

    def pos(self) -> str:
        return self.vec(3, -30, 30, 0.01)

    def rgba(self) -> str:
        return self.vec(4, 0, 10, 0.1)

    def direction(self) -> str:
        return _ints(self.pick(DIRECTIONS))

    def angle(self, unit: str, lo_deg: int = -180, hi_deg: int = 180) -> str:
        """An angle in the compiler's unit (degrees as integers, radians with two decimals)."""
        if unit == "radian":
            return self.dec(round(lo_deg * 3.14159 / 180 * 100), round(hi_deg * 3.14159 / 180 * 100), 0.01)
        return str(self.integer(lo_deg, hi_deg))

    def turn(self, unit: str, axisangle: bool) -> Attrs:
        """Euler angles, or an axis and an angle."""
        if axisangle:
            direction = self.direction()
            return {"axisangle": f"{direction} {self.angle(unit)}"}
        return {"euler": " ".join(self.angle(unit) for _ in range(3))}

    def orientation(self, unit: str, form: int) -> Attrs:
        """No rotation (form 0) or one of the alternative orientation forms MJCF accepts on bodies and frames."""
        if form == 0:
            return {}
        if form in (1, 2):
            return self.turn(unit, axisangle=form == 2)
        if form == 3:
            return {"quat": _ints(self.pick(QUATS))}
        if form == 4:
            x, y = self.pick(XYAXES)
            return {"xyaxes": f"{_ints(x)} {_ints(y)}"}
        return {"zaxis": self.direction()}

    def fromto(self) -> str:
        ends = [self.integer(-20, 20) for _ in range(6)]
        if ends[:3] == ends[3:]:  # a zero-length segment (1 in 68921): the old draw was filtered out and redrawn
            ends[5] = ends[5] + 1 if ends[5] < 20 else ends[5] - 1
        return " ".join(f"{i * 0.01:.6g}" for i in ends)


_FORMS = 6  # orientation forms: none, euler, axisangle, quat, xyaxes, zaxis


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
    made: dict = field(default_factory=dict)

    def name(self, kind: str) -> str:
        n = self.counters.get(kind, 0)
        self.counters[kind] = n + 1
        return f"{kind}{n}"

    def strategy(self, make, *args) -> st.SearchStrategy:
        """`make(self, *args)`, made once per document: hypothesis checks a new strategy on its first draw."""
        key = (make, *args)
        if key not in self.made:
            self.made[key] = make(self, *args)
        return self.made[key]


@dataclass(frozen=True)
class _GeomFlags:
    """Which optional attributes one geom writes (and in which form), read from its flag bytes in a fixed order."""

    typed: bool
    fitted: bool
    sized: bool
    placed: bool
    segment: bool
    turned: bool
    axisangle: bool
    contype: bool
    conaffinity: bool
    group: bool
    rgba: bool
    mass: str  # "", "mass" or "density"
    friction: bool
    material: bool
    named_class: bool

    @classmethod
    def read(cls, f: _Flags, in_default: bool) -> _GeomFlags:
        """The flags of a geom, one decision per flag byte."""
        typed, fitted, sized = f.coin(), f.one_in(5), f.coin()
        placed = f.one_in(6 if in_default else 2)  # a default pos clashes with every fromto of the class's geoms
        segment, turned, axisangle = f.one_in(4), f.one_in(3), f.coin()
        contype, conaffinity, group, rgba = f.coin(), f.coin(), f.coin(), f.coin()
        mass, friction, material, named_class = f.pick(("", "mass", "density")), f.coin(), f.coin(), f.coin()
        return cls(
            typed,
            fitted,
            sized,
            placed,
            segment,
            turned,
            axisangle,
            contype,
            conaffinity,
            group,
            rgba,
            mass,
            friction,
            material,
            named_class,
        )


def _geom_shape(r: _Reader, g: _GeomFlags, attrs: Attrs, ctx: _Context, in_default: bool, world: bool) -> None:
    """A geom's type, mesh and size: planes only in the world, sizes full wherever no class supplies one."""
    kinds = list(PRIMITIVES) + (["mesh"] if ctx.meshes else []) + (["plane"] if world else [])
    if g.typed:
        attrs["type"] = r.pick(kinds)
    kind = attrs.get("type")
    if kind == "mesh" or (kind is None and ctx.meshes and g.fitted):
        attrs["mesh"] = r.pick(ctx.meshes)  # without type: a primitive fitted to the mesh
    if g.sized or not (in_default or ctx.main_size):
        attrs["size"] = r.sizes(full=not (in_default or ctx.main_size))


def _geom_pose(r: _Reader, g: _GeomFlags, attrs: Attrs, ctx: _Context) -> None:
    """A geom's placement: a position and an orientation, or a fromto segment in place of both."""
    if g.placed:
        attrs["pos"] = r.pos()
    if attrs.get("type") in FROMTO_TYPES and g.segment:
        attrs.pop("pos", None)
        attrs["fromto"] = r.fromto()
    elif g.turned:
        attrs.update(r.turn(ctx.unit, g.axisangle))


def _geom_mass(r: _Reader, mass: str) -> Attrs:
    """A geom's mass or density, or neither (`mass` is "", "mass" or "density")."""
    if mass == "mass":
        return {"mass": r.dec(1, 50, 0.1)}
    if mass == "density":
        return {"density": r.dec(1, 20, 100.0)}
    return {}


@st.composite
def geom_attrs(draw, ctx: _Context, in_default: bool, world: bool = False) -> Attrs:
    """Geom attributes: type, full or partial size, pose (pos + orientation or fromto), contact bits,
    group, rgba, mass or density, friction, material, mesh."""
    r = _Reader(draw, 34, flags=19)
    g = _GeomFlags.read(r.flags, in_default)
    attrs: Attrs = {}
    _geom_shape(r, g, attrs, ctx, in_default, world)
    _geom_pose(r, g, attrs, ctx)
    if g.contype:
        attrs["contype"] = str(r.integer(0, 3))
    if g.conaffinity:
        attrs["conaffinity"] = str(r.integer(0, 3))
    if g.group:
        attrs["group"] = str(r.integer(0, 5))
    if g.rgba:
        attrs["rgba"] = r.rgba()
    attrs.update(_geom_mass(r, g.mass))
    if g.friction:
        attrs["friction"] = r.vec(r.one_to_three(), 1, 20, 0.1)
    if ctx.materials and g.material:
        attrs["material"] = r.pick(ctx.materials)
    _element_class(r, g.named_class, attrs, ctx, in_default)
    return attrs


@st.composite
def joint_attrs(draw, ctx: _Context, in_default: bool) -> Attrs:
    """Joint attributes: type, axis, range, limited, damping, armature, ref, stiffness, springref,
    frictionloss."""
    r = _Reader(draw, 12, flags=13)
    f = r.flags
    typed, axis, ranged, below_zero, limited = f.coin(), f.coin(), f.coin(), f.coin(), f.one_in(4)
    # elements write damping/armature less often than classes: most values then come from a default class
    sparse, damping, armature = f.one_in(4), f.coin(), f.coin()
    if not in_default:
        damping = armature = sparse
    ref, stiffness, springref, frictionloss = f.one_in(4), f.one_in(4), f.one_in(4), f.one_in(8)
    named_class = f.coin()
    attrs: Attrs = {}
    if typed:
        attrs["type"] = r.pick(("hinge", "hinge", "slide", "ball"))
    if axis:
        attrs["axis"] = r.direction()
    if ranged:
        attrs["range"] = _joint_range(r, ctx.unit, attrs.get("type"), below_zero)
    if limited:
        attrs["limited"] = r.pick(("true", "false", "auto") if "range" in attrs else ("false", "auto"))
    if damping:
        attrs["damping"] = r.dec(0, 20, 0.05)
    if armature:
        attrs["armature"] = r.dec(0, 20, 0.01)
    _joint_spring(r, ctx.unit, attrs, ref, stiffness, springref)
    if frictionloss:
        attrs["frictionloss"] = r.dec(0, 10, 0.01)
    _element_class(r, named_class, attrs, ctx, in_default)
    return attrs


def _joint_range(r: _Reader, unit: str, kind: str | None, below_zero: bool) -> str:
    """A joint's range: a ball's upper cone angle, otherwise a low end at or below 0 and a high end above it."""
    if kind == "ball":
        return f"0 {r.angle(unit, 10, 170)}"
    lo = r.integer(-170, -10) if below_zero else 0  # 0 also suits a ball from a class
    hi = r.integer(10, 170)
    return f"{lo} {hi}" if unit == "degree" else f"{lo * 0.0175:.3g} {hi * 0.0175:.3g}"


def _joint_spring(r: _Reader, unit: str, attrs: Attrs, ref: bool, stiffness: bool, springref: bool) -> None:
    """A joint's reference position and its spring: stiffness and the spring's rest position."""
    if ref:
        attrs["ref"] = r.angle(unit, -30, 30)
    if stiffness:
        attrs["stiffness"] = r.dec(0, 20, 0.5)
    if springref:
        attrs["springref"] = r.angle(unit, -30, 30)


def _element_class(r: _Reader, named: bool, attrs: Attrs, ctx: _Context, in_default: bool) -> None:
    """Half the elements outside defaults name a class (main or a declared one)."""
    if not in_default and ctx.classes and named:
        attrs["class"] = r.pick(["main", *ctx.classes])


@st.composite
def site_attrs(draw, ctx: _Context, in_default: bool) -> Attrs:
    r = _Reader(draw, 21, flags=6)
    f = r.flags
    typed, sized, placed, rgba, group, named_class = (f.coin() for _ in range(6))
    attrs: Attrs = {}
    if typed:
        attrs["type"] = r.pick(PRIMITIVES)
    if sized:
        attrs["size"] = r.sizes(full=False)
    if placed:
        attrs["pos"] = r.pos()
    if rgba:
        attrs["rgba"] = r.rgba()
    if group:
        attrs["group"] = str(r.integer(0, 5))
    _element_class(r, named_class, attrs, ctx, in_default)
    return attrs


_ACTUATOR_FLAGS = 7  # flag bytes `_actuator_attrs` reads: keep them the last an element reads


def _actuator_attrs(f: _Flags, r: _Reader, tag: str) -> Attrs:
    """Attributes of one actuator shortcut (motor, position, velocity, general): flags from `f`, values from `r`."""
    gear, ctrlrange, forcerange = f.coin(), f.coin(), f.one_in(4)
    attrs: Attrs = {}
    if gear:
        attrs["gear"] = r.dec(1, 30, 0.5)
    if ctrlrange:
        lo, hi = r.integer(-30, -1), r.integer(1, 30)
        attrs["ctrlrange"] = f"{lo / 10:g} {hi / 10:g}"
    if forcerange:
        force = r.integer(1, 50)
        attrs["forcerange"] = f"-{force} {force}"
    if tag == "position":
        attrs.update(_position_gains(f, r))
    elif tag == "velocity":
        attrs.update(_velocity_gain(f, r))
    elif tag == "general":
        attrs.update(_general_gains(f, r))
    return attrs


def _position_gains(f: _Flags, r: _Reader) -> Attrs:
    """A position actuator's proportional and derivative gains (kp, kv), each optional."""
    kp, kv = f.coin(), f.coin()
    attrs: Attrs = {}
    if kp:
        attrs["kp"] = r.dec(1, 100, 1.0)
    if kv:
        attrs["kv"] = r.dec(0, 20, 0.5)
    return attrs


def _velocity_gain(f: _Flags, r: _Reader) -> Attrs:
    """A velocity actuator's optional gain (kv)."""
    attrs: Attrs = {}
    if f.coin():
        attrs["kv"] = r.dec(1, 20, 0.5)
    return attrs


def _general_gains(f: _Flags, r: _Reader) -> Attrs:
    """A general actuator's gain, affine bias and activation dynamics, each optional."""
    gain, bias, dynamics, actearly = f.coin(), f.coin(), f.one_in(4), f.coin()
    attrs: Attrs = {}
    if gain:
        attrs["gainprm"] = r.dec(1, 100, 1.0)
    if bias:
        kp, kv = r.dec(0, 100, 1.0), r.dec(0, 20, 0.5)
        attrs["biasprm"] = f"0 -{kp} -{kv}"
        attrs["biastype"] = "affine"
    if dynamics:  # activation dynamics: the gain multiplies the activation
        attrs["dyntype"] = r.pick(("filter", "filterexact", "integrator"))
        if attrs["dyntype"] != "integrator":
            attrs["dynprm"] = r.dec(1, 20, 0.01)
        if actearly:
            attrs["actearly"] = r.pick(("true", "false"))
    return attrs


@st.composite
def actuator_attrs(draw, ctx: _Context, tag: str) -> Attrs:
    """Attributes of one actuator shortcut (motor, position, velocity, general)."""
    r = _Reader(draw, 10, flags=_ACTUATOR_FLAGS)
    return _actuator_attrs(r.flags, r, tag)


@st.composite
def default_class(draw, ctx: _Context, name: str | None, depth: int) -> DefaultClass:
    cls = DefaultClass(name)
    r = _Reader(draw, 15, flags=5 + _ACTUATOR_FLAGS)
    f = r.flags
    mesh, material, actuator, children_first = f.one_in(3), f.one_in(4), f.coin(), f.coin()
    if draw(_COIN) or name is None:
        cls.geom = draw(ctx.strategy(geom_attrs, True))
        if name is None:  # a full size in main keeps most documents valid (partial sizes come below)
            cls.geom["size"] = r.sizes(full=True)
    if draw(_COIN):
        cls.joint = draw(ctx.strategy(joint_attrs, True))
    if draw(_THIRD) == 2:
        cls.site = draw(ctx.strategy(site_attrs, True))
    if mesh:
        cls.mesh = {"scale": r.vec(3, 5, 30, 0.1)}
    if name is None and ctx.materials and material:
        cls.material = {"rgba": r.rgba(), "specular": r.dec(0, 10, 0.1)}
    if actuator:
        tag = r.pick(SHORTCUTS)
        cls.actuator = (tag, _actuator_attrs(f, r, tag))
    if depth < 3:
        for _ in range(draw(st.integers(0, 2 if depth else 3))):
            child = ctx.name("c")
            ctx.classes.append(child)
            cls.children.append(draw(default_class(ctx, child, depth + 1)))
    cls.children_first = bool(cls.children) and children_first
    return cls


BOX_FACES = [
    (0, 2, 1),
    (1, 2, 3),
    (4, 5, 6),
    (5, 7, 6),
    (0, 1, 4),
    (1, 5, 4),
    (2, 6, 3),
    (3, 6, 7),
    (0, 4, 2),
    (2, 4, 6),
    (1, 3, 5),
    (3, 7, 5),
]
TETRA_FACES = [(0, 2, 1), (0, 1, 3), (0, 3, 2), (1, 2, 3)]


@st.composite
def mesh_asset(draw, ctx: _Context, name: str) -> MeshAsset:
    """A small closed mesh: a jittered box or a tetrahedron, off-centre so MuJoCo re-centres it."""
    r = _Reader(draw, 64, flags=4)
    box, named_class, scaled = r.flags.coin(), r.flags.one_in(3), r.flags.one_in(4)
    offset = [r.integer(-10, 10) * 0.01 for _ in range(3)]
    if box:
        half = [r.integer(2, 15) * 0.01 for _ in range(3)]
        vertices = []
        for i in range(8):
            corner = [(1 if i >> k & 1 else -1) * half[k] for k in range(3)]
            jitter = [r.integer(-2, 2) * 0.002 for _ in range(3)]
            vertices.append(tuple(c + j + o for c, j, o in zip(corner, jitter, offset)))
        faces = BOX_FACES
    else:
        size = r.integer(3, 15) * 0.01
        base = [(0, 0, 0), (size, 0, 0), (0, size * 1.2, 0), (0, 0, size * 0.8)]
        vertices = [tuple(c + o for c, o in zip(v, offset)) for v in base]
        faces = TETRA_FACES
    attrs: Attrs = {}
    if ctx.classes and named_class:
        attrs["class"] = r.pick(["main", *ctx.classes])
    if scaled:
        attrs["scale"] = r.vec(3, 5, 20, 0.1)
    return MeshAsset(name, vertices, faces, attrs)


_FRAME = st.integers(0, 4)  # 4: a frame (below max_depth)
_SITE = st.integers(0, 3)  # 3: a site on a body
_FREE = st.integers(0, 3)  # 3: a free joint (on a top-level body)
_NOT_FREE = st.integers(0, 2)  # joints on a body: two balls are MuJoCo's limit of 6 dofs per body
_ONE_OR_TWO = st.integers(1, 2)
_CHILDREN = {True: st.integers(0, 2), False: st.integers(0, 1)}  # children per body in shallow / deep trees


def _frame(draw, ctx: _Context, depth: int, top: bool, max_depth: int) -> Body:
    """A frame: a pose and a childclass for the one or two bodies it holds, and maybe a geom of its own."""
    r = _Reader(draw, 12, flags=4)
    placed, form, childclass = r.flags.coin(), r.flags.below(_FORMS), r.flags.coin()
    frame = Body("frame", {})
    if placed:
        frame.attrs["pos"] = r.pos()
    frame.attrs.update(r.orientation(ctx.unit, form))
    if ctx.classes and childclass:
        frame.attrs["childclass"] = r.pick(ctx.classes)
    if draw(_COIN):
        frame.elements.append(Element("geom", {"name": ctx.name("g"), **draw(ctx.strategy(geom_attrs, False))}))
    frame.children = [draw(ctx.strategy(body_tree, depth + 1, top, max_depth)) for _ in range(draw(_ONE_OR_TWO))]
    return frame


def _body_joints(draw, ctx: _Context, body: Body, top: bool) -> None:
    """A body's joints: a free joint (as `freejoint` or a joint of type free) on some top-level bodies, otherwise
    up to two joints that actuators may drive."""
    if top and draw(_FREE) == 3:
        name = ctx.name("j")
        if draw(_COIN):
            body.elements.append(Element("freejoint", {"name": name}))
        else:
            body.elements.append(
                Element(
                    "joint",
                    {"name": name, "type": "free", **_drop(draw(ctx.strategy(joint_attrs, False)), "type", "range")},
                )
            )
    else:
        for _ in range(draw(_NOT_FREE)):
            name = ctx.name("j")
            ctx.joints.append(name)
            body.elements.append(Element("joint", {"name": name, **draw(ctx.strategy(joint_attrs, False))}))


@st.composite
def body_tree(draw, ctx: _Context, depth: int, top: bool, max_depth: int = 3) -> Body:
    """A body (or a frame holding bodies) with joints, geoms and sites that pick classes."""
    if draw(_FRAME) == 4 and depth < max_depth:
        return _frame(draw, ctx, depth, top, max_depth)
    r = _Reader(draw, 12, flags=5)
    placed, form, childclass = r.flags.coin(), r.flags.below(_FORMS), r.flags.one_in(3)
    body = Body("body", {"name": ctx.name("b")})
    if placed:
        body.attrs["pos"] = r.pos()
    body.attrs.update(r.orientation(ctx.unit, form))
    if ctx.classes and childclass:
        body.attrs["childclass"] = r.pick(["main", *ctx.classes])
    _body_joints(draw, ctx, body, top)
    for _ in range(draw(_ONE_OR_TWO)):
        body.elements.append(Element("geom", {"name": ctx.name("g"), **draw(ctx.strategy(geom_attrs, False))}))
    if draw(_SITE) == 3:
        body.elements.append(Element("site", {"name": ctx.name("s"), **draw(ctx.strategy(site_attrs, False))}))
    if depth < max_depth:
        body.children = [
            draw(ctx.strategy(body_tree, depth + 1, False, max_depth)) for _ in range(draw(_CHILDREN[max_depth <= 3]))
        ]
    return body


def _drop(attrs: Attrs, *keys: str) -> Attrs:
    return {k: v for k, v in attrs.items() if k not in keys}


@st.composite
def compiler_attrs(draw) -> Attrs:
    """`<compiler angle=... eulerseq=... autolimits=...>` variations (each may be absent)."""
    r = _Reader(draw, 4, flags=4)
    angle, eulerseq, autolimits = r.flags.coin(), r.flags.coin(), r.flags.one_in(5)
    attrs: Attrs = {}
    if angle:
        attrs["angle"] = r.pick(("degree", "radian"))
    if eulerseq:
        attrs["eulerseq"] = r.pick(EULERSEQS)
    if autolimits:
        attrs["autolimits"] = r.pick(("true", "false"))
    return attrs


_UP_TO_TWO = st.integers(0, 2)
_DEFAULTS = st.integers(0, 5)  # 0: no <default> at all
_ACTUATORS = st.integers(0, 3)


@st.composite
def _actuator(draw, ctx: _Context) -> tuple[str, Attrs]:
    r = _Reader(draw, 12, flags=2 + _ACTUATOR_FLAGS)
    named_class, written = r.flags.coin(), r.flags.coin()
    tag = r.pick(SHORTCUTS)
    attrs = {"name": ctx.name("a"), "joint": r.pick(ctx.joints)}
    if ctx.classes and named_class:
        attrs["class"] = r.pick(["main", *ctx.classes])
    if written:
        attrs.update(_actuator_attrs(r.flags, r, tag))
    return tag, attrs


@st.composite
def documents(draw, max_bodies: int = 3) -> Document:
    """A document with a default-class tree, meshes, materials, world geoms, bodies/frames and actuators."""
    compiler = draw(compiler_attrs())
    ctx = _Context(unit=compiler.get("angle", "degree"))
    ctx.materials = [f"mat{i}" for i in range(draw(_UP_TO_TWO))]
    ctx.meshes = [f"mesh{i}" for i in range(draw(_UP_TO_TWO))]
    defaults = draw(default_class(ctx, None, 0)) if draw(_DEFAULTS) else None
    ctx.main_size = defaults is not None
    meshes = [draw(mesh_asset(ctx, name)) for name in ctx.meshes]
    r = _Reader(draw, 8, flags=4)
    split_main, coloured = r.flags.one_in(5), [r.flags.coin() for _ in ctx.materials]
    materials = [{"name": name, **({"rgba": r.rgba()} if rgba else {})} for name, rgba in zip(ctx.materials, coloured)]
    world = [
        Element("geom", {"name": ctx.name("g"), **draw(ctx.strategy(geom_attrs, False, True))})
        for _ in range(draw(_UP_TO_TWO))
    ]
    bodies = [draw(ctx.strategy(body_tree, 0, True)) for _ in range(draw(st.integers(1, max_bodies)))]
    actuators = [draw(_actuator(ctx)) for _ in range(draw(_ACTUATORS))] if ctx.joints else []
    return Document(compiler, defaults, bool(defaults) and split_main, meshes, materials, world, bodies, actuators)


# One mistake each, spliced into a rendered valid document: (where, text). MuJoCo rejects every one.
@st.composite
def kinematic_trees(draw, max_depth: int = 6) -> Document:
    """Class-free trees (chains up to `max_depth` bodies deep) with random body orientations in every MJCF
    form, random joint axes and types, frames, and compiler angle / eulerseq variations."""
    compiler = draw(compiler_attrs())
    ctx = _Context(unit=compiler.get("angle", "degree"))
    bodies = [draw(ctx.strategy(body_tree, 0, True, max_depth)) for _ in range(draw(st.integers(1, 2)))]
    return Document(compiler, bodies=bodies)


BREAKAGES = {
    "unknown_class": ("world", '<geom class="nope" size=".1"/>'),
    "duplicate_class": ("top", '<default><default class="dup"/><default class="dup"/></default>'),
    "short_rgba": ("world", '<geom size=".1" rgba="0 1"/>'),
    "two_geoms_in_class": (
        "top",
        ('<default><default class="two"><geom size=".1"/><geom size=".2"/></default></default>'),
    ),
    "named_default_element": ("top", '<default><default class="named"><site name="s"/></default></default>'),
    "body_in_default": ("top", "<default><body/></default>"),
    "renamed_main": ("top", '<default class="x"><geom size=".1"/></default>'),
    "worldbody_childclass": ("worldbody_attr", ' childclass="main"'),
    "body_class": ("world", '<body class="main"><geom size=".1"/></body>'),
    "missing_mesh_file": (
        "top",
        (
            '<asset><mesh name="absent" file="absent.obj"/></asset>'
            '<worldbody><geom type="mesh" mesh="absent"/></worldbody>'
        ),
    ),
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

"""Which pairs of bodies may touch: MuJoCo's contype/conaffinity bits and its pair filters, as PhysX's four
collision-group words (g0 = contype, g1 = conaffinity; g2/g3 carry the body pairs MuJoCo filters and PhysX does
not). Derivation: docs/mapping.md#collision-filter.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import mujoco
import numpy as np

from ..errors import Notes
from ..model import mj
from .tree import TreePlan

GROUP_BITS = 32


@dataclass
class CollisionFilter:
    """Per MuJoCo body: the (g2, g3) words its shapes carry; per geom, the bits explicit `<pair>`s add to its g0
    and g1 (`plan_pairs`)."""

    body_words: dict[int, tuple[int, int]] = field(default_factory=dict)
    pair_bits: dict[int, list[int]] = field(default_factory=dict)  # geom -> [bits for g0, bits for g1]

    def groups(self, model: mujoco.MjModel, geom: int) -> list[int]:
        g2, g3 = self.body_words.get(int(model.geom_bodyid[geom]), (0, 0))
        extra0, extra1 = self.pair_bits.get(geom, (0, 0))
        return [int(model.geom_contype[geom]) | extra0, int(model.geom_conaffinity[geom]) | extra1, g2, g3]


def _physx_parent_body(tree: TreePlan, b: int) -> int | None:
    """The body carried by the direct PhysX parent of body b's link (PhysX never lets those two collide)."""
    if b not in tree.body_link:
        return None
    a, link = tree.body_link[b]
    parent = tree.articulations[a].links[link].parent
    return None if parent is None else tree.articulations[a].links[parent].body


def plan_collision_filter(
    model: mujoco.MjModel, tree: TreePlan, shape_bodies: set[int], static_bodies: set[int], notes: Notes
) -> CollisionFilter:
    """Assign g2/g3 words so that PhysX filters exactly the body pairs MuJoCo filters."""
    result = CollisionFilter()
    contype = np.zeros(model.nbody, dtype=np.int64)
    conaffinity = np.zeros(model.nbody, dtype=np.int64)
    shaped = mj.body_mask(model, shape_bodies)[model.geom_bodyid]
    np.bitwise_or.at(contype, model.geom_bodyid[shaped], model.geom_contype[shaped].astype(np.int64))
    np.bitwise_or.at(conaffinity, model.geom_bodyid[shaped], model.geom_conaffinity[shaped].astype(np.int64))
    excluded = mj.excluded_body_pairs(model)
    filter_parent = not mj.disabled(model, "filterparent")
    bodies = np.array(sorted(shape_bodies), dtype=np.int64)
    # The pairs to decide, in order: bits that meet, not both unable to move (PhysX makes no contact there).
    meet = ((contype[bodies][:, None] & conaffinity[bodies][None, :]) != 0) | (
        (contype[bodies][None, :] & conaffinity[bodies][:, None]) != 0
    )
    fixed = mj.body_mask(model, static_bodies)[bodies]
    first, second = np.nonzero(np.triu(meet & ~(fixed[:, None] & fixed[None, :]), 1))
    filtered = mj.filtered_pairs(model, bodies, excluded, filter_parent)[first, second]
    parents = (_physx_parent_body(tree, b) for b in bodies.tolist())
    physx_parent = np.array([-1 if p is None else p for p in parents], dtype=np.int64)
    b1, b2 = bodies[first], bodies[second]
    physx_skips = (physx_parent[second] == b1) | (physx_parent[first] == b2)
    pairs = list(zip(b1.tolist(), b2.tolist()))
    must_exclude = [pair for pair, yes in zip(pairs, (filtered & ~physx_skips).tolist()) if yes]
    must_collide = {pair for pair, yes in zip(pairs, (~filtered & ~physx_skips).tolist()) if yes}
    for (a, b), yes in zip(pairs, (~filtered & physx_skips).tolist()):
        if yes:
            notes.approximate(
                "contact",
                f"{mj.name(model, 'body', a)}/{mj.name(model, 'body', b)}",
                "PhysX never lets a link touch its direct parent; MuJoCo would let these bodies touch",
            )
    for g1, g2 in zip(model.pair_geom1, model.pair_geom2):  # an explicit pair's bodies must meet (`plan_pairs`)
        b1, b2 = sorted((int(model.geom_bodyid[g1]), int(model.geom_bodyid[g2])))
        if b1 != b2 and not mj.mujoco_filters(model, b1, b2, excluded, filter_parent):
            must_collide.add((b1, b2))
    _assign_bits(model, must_exclude, must_collide, result, notes)
    return result


def _clusters(must_exclude) -> list[list[tuple[int, int]]]:
    """The excluded body pairs grouped into connected clusters (union-find), each cluster's pairs in order."""
    parent = {}

    def find(x):
        while parent.setdefault(x, x) != x:
            x = parent[x]
        return x

    for a, b in must_exclude:
        parent[find(a)] = find(b)
    clusters: dict[int, list[tuple[int, int]]] = {}
    for a, b in must_exclude:
        clusters.setdefault(find(a), []).append((a, b))
    return list(clusters.values())


def _cluster_bits(model, edges, must_collide, notes: Notes) -> list[set[int]]:
    """One cluster's excluded pairs packed onto group bits: bodies sharing a bit do not collide, so a bit takes
    only bodies none of whose pairs must collide; a pair left over once the bits run out is noted."""

    def may_share(m: int, x: int) -> bool:
        return m == x or (min(m, x), max(m, x)) not in must_collide

    bit_members: list[set[int]] = []
    for a, b in edges:
        if any(a in s and b in s for s in bit_members):
            continue
        for members in bit_members:
            if all(may_share(m, a) and may_share(m, b) for m in members):
                members.update((a, b))
                break
        else:
            if len(bit_members) == GROUP_BITS:
                notes.drop(
                    "contact",
                    f"{mj.name(model, 'body', a)}/{mj.name(model, 'body', b)}",
                    "filtered by MuJoCo but not expressible in PhysX's 32 group bits: may collide",
                )
                continue
            bit_members.append({a, b})
    return bit_members


def _assign_bits(model, must_exclude, must_collide, result: CollisionFilter, notes: Notes) -> None:
    g2: dict[int, int] = {}
    g3: dict[int, int] = {}
    for cluster_index, edges in enumerate(_clusters(must_exclude), start=1):
        for a, b in edges:
            g3[a] = g3[b] = cluster_index
        for bit, members in enumerate(_cluster_bits(model, edges, must_collide, notes)):
            for m in members:
                g2[m] = g2.get(m, 0) | (1 << bit)
    result.body_words = {b: (g2.get(b, 0), g3.get(b, 0)) for b in set(g2) | set(g3)}


DISTANCE_RESOLUTION = 1e-7  # m: a contact distance PhysX's float32 already misses (its offsets are float32)
PAIR_FRICTION = 1e-9  # relative: a pair's sliding friction PhysX's average of its geoms' already gives


def plan_pairs(
    model: mujoco.MjModel, tree: TreePlan, result: CollisionFilter, shaped: set[int], static: set[int], notes: Notes
) -> None:
    """MuJoCo's explicit `<pair>`s: a contact between two geoms whatever their bits and their bodies' filters, with
    the pair's own parameters in place of the geoms'. Where the geoms' bits do not meet, a bit that no geom's
    contype or conaffinity uses joins one geom's g0 and the other's g1; one bit serves several pairs while every
    combination it enables is one MuJoCo makes (a floor and many feet share one). Noted per pair: a contact PhysX
    blocks (the bodies' filter, a pair bypasses it; PhysX's parent rule), no bit left, and a sliding friction other
    than PhysX's average of its two geoms'
    (tests/test_loader_contact.py::test_explicit_pairs_make_mujocos_contacts_and_note_what_physx_loses)."""
    used = 0
    for g in range(model.ngeom):
        used |= int(model.geom_contype[g]) | int(model.geom_conaffinity[g])
    spare = [k for k in range(GROUP_BITS) if not used >> k & 1]
    explicit = {frozenset((int(a), int(b))) for a, b in zip(model.pair_geom1, model.pair_geom2)}

    def wanted(x: int, y: int) -> bool:
        meet = (model.geom_contype[x] & model.geom_conaffinity[y]) or (
            model.geom_contype[y] & model.geom_conaffinity[x]
        )
        return x == y or bool(meet) or frozenset((x, y)) in explicit

    bits: list[tuple[int, set[int], set[int]]] = []  # (bit, geoms whose g0 has it, geoms whose g1 has it)
    for p in range(model.npair):
        a, b = int(model.pair_geom1[p]), int(model.pair_geom2[p])
        name = mj.name(model, "pair", p)
        lost = _pair_blocked(model, tree, result, a, b, shaped, static)
        if lost is None:
            continue  # two geoms that cannot move: nothing to simulate
        if lost:
            notes.drop("contact pair", name, f"its contact is lost: {lost}")
            continue
        ga, gb = result.groups(model, a), result.groups(model, b)
        if not ((ga[0] & gb[1]) or (ga[1] & gb[0])) and not _pair_bit(a, b, bits, spare, wanted):
            notes.drop("contact pair", name, "its contact is lost: no collision bit is left to enable it in PhysX")
            continue
        _pair_friction(model, p, a, b, name, notes)
    for bit, first, second in bits:
        for g in first:
            result.pair_bits.setdefault(g, [0, 0])[0] |= 1 << bit
        for g in second:
            result.pair_bits.setdefault(g, [0, 0])[1] |= 1 << bit


def _pair_blocked(model, tree: TreePlan, result: CollisionFilter, a: int, b: int, shaped, static) -> str | None:
    """Why PhysX cannot make the pair's contact ('' where it can; None for two geoms that cannot move)."""
    ba, bb = int(model.geom_bodyid[a]), int(model.geom_bodyid[b])
    if a not in shaped or b not in shaped:
        return f"geom {mj.name(model, 'geom', a if a not in shaped else b)!r} has no collision shape in SAPIEN"
    if ba in static and bb in static:
        return None
    if model.body_weldid[ba] == model.body_weldid[bb]:
        return "both geoms are on one rigid body in SAPIEN"
    if _physx_parent_body(tree, bb) == ba or _physx_parent_body(tree, ba) == bb:
        return "PhysX never lets a link touch its direct parent"
    ga, gb = result.groups(model, a), result.groups(model, b)
    if (ga[2] & gb[2]) and (ga[3] & 0xFFFF) == (gb[3] & 0xFFFF):
        return "PhysX filters these bodies (MuJoCo's weld, parent or exclude filter, which a pair bypasses)"
    return ""


def _pair_bit(a: int, b: int, bits: list, spare: list[int], wanted) -> bool:
    """Put a on an enabling bit's g0 side and b on its g1 side (or the other way round): a bit in use where every
    combination across its sides stays `wanted`, else a spare one; False when none is left."""
    for bit, first, second in bits:
        for x, y in ((a, b), (b, a)):
            if all(wanted(f, s) for f in first | {x} for s in second | {y}):
                first.add(x)
                second.add(y)
                return True
    if not spare:
        return False
    bits.append((spare.pop(0), {a}, {b}))
    return True


def _pair_friction(model: mujoco.MjModel, p: int, a: int, b: int, name: str, notes: Notes) -> None:
    """Note a pair whose sliding friction (none with condim 1) is not PhysX's average of its geoms' materials."""
    own = float(model.pair_friction[p][0]) if int(model.pair_dim[p]) > 1 else 0.0
    physx = 0.5 * float(model.geom_friction[a][0] + model.geom_friction[b][0])
    if abs(own - physx) > PAIR_FRICTION * max(abs(own), abs(physx), 1.0):
        notes.approximate(
            "contact pair", name, f"sliding friction {own:g} (the pair's); PhysX averages its geoms' to {physx:g}"
        )


def _meeting(model: mujoco.MjModel, geoms: np.ndarray, static: set[int]) -> np.ndarray:
    """Which of `geoms` (pairwise) PhysX lets touch by their bits: not on one welded body, not both static."""
    contype, conaffinity = model.geom_contype[geoms], model.geom_conaffinity[geoms]
    meet = ((contype[:, None] & conaffinity[None, :]) | (contype[None, :] & conaffinity[:, None])) != 0
    bodies = model.body_weldid[model.geom_bodyid[geoms]]
    fixed = mj.body_mask(model, static)[model.geom_bodyid[geoms]]
    return meet & (bodies[:, None] != bodies[None, :]) & ~(fixed[:, None] & fixed[None, :])


def note_contact_laws(model: mujoco.MjModel, plans: dict, static: set[int], notes: Notes) -> None:
    """The notes on the pairs of a load's geoms (`plans`: geom id -> its `ShapePlan`) whose bits meet, where PhysX's
    contact follows another law than MuJoCo's: the friction combine, the contact distances, the rebound. The pairs
    are found once for the three."""
    geoms = np.array(sorted(plans), dtype=int)
    if geoms.size < 2:
        return
    meeting = np.triu(_meeting(model, geoms, static), 1)  # each pair once, the lower-indexed geom first
    note_friction_combine(model, geoms, meeting, notes)
    note_contact_distances(model, geoms, meeting, [plans[int(g)] for g in geoms], notes)
    note_contact_rebound(model, geoms, meeting | meeting.T, notes)


def note_friction_combine(model: mujoco.MjModel, geoms: np.ndarray, meeting: np.ndarray, notes: Notes) -> None:
    """MuJoCo gives a contact the larger of its two geoms' sliding frictions; PhysX averages its two materials', and
    SAPIEN 3.0.3 exposes no combine mode. Where geoms whose bits meet differ in sliding friction, the contact between
    them slides on another coefficient: one note says how many such pairs and the largest difference (explicit
    pairs carry their own note, `plan_pairs`)
    (tests/test_contact_classes.py::test_unequal_frictions_combine_by_average_in_physx_and_by_max_in_mujoco)."""
    friction = model.geom_friction[geoms, 0]
    if np.all(friction == friction[0]):
        return
    gap = np.abs(friction[:, None] - friction[None, :]) / 2  # max(a, b) - (a + b) / 2
    differs = meeting & (gap > 0)
    if not differs.any():
        return
    i, j = np.unravel_index(np.argmax(np.where(differs, gap, -1.0)), gap.shape)
    names = f"{mj.name(model, 'geom', int(geoms[i]))}/{mj.name(model, 'geom', int(geoms[j]))}"
    notes.approximate(
        "contact friction",
        f"{int(differs.sum())} geom pairs",
        f"MuJoCo takes the larger of two geoms' sliding frictions, PhysX their average; largest gap "
        f"{gap[i, j]:g} ({names}: {friction[i]:g} and {friction[j]:g})",
    )


def note_contact_distances(
    model: mujoco.MjModel, geoms: np.ndarray, meeting: np.ndarray, plans: list, notes: Notes
) -> None:
    """Where PhysX's rest offset and torsional patch radius (the `plans`' own, `geom.contact_distances`) miss
    MuJoCo's law for a pair of geoms whose bits meet (`meeting`, each pair once), one note per quantity says how
    many pairs and the largest difference: a pair where both geoms carry `margin - gap` (PhysX adds them, MuJoCo
    takes the larger margin less the larger gap), a torsional friction that is not PhysX's average sliding friction
    times the larger radius (frictions that differ, a geom of condim 3 with the larger torsion, a geom's priority),
    and rolling friction (condim 6), which PhysX has not
    (tests/test_contact_classes.py::test_a_margin_is_each_pairs_rest_offset_where_one_geom_carries_it,
    tests/test_contact_classes.py::test_pairs_whose_torsion_or_rolling_physx_misses_are_noted)."""
    a, b = np.nonzero(meeting)  # the pairs, as indices into `geoms`
    pairs = (geoms[a], geoms[b])
    rest, torsion = np.array([(plan.rest_offset, plan.torsion) for plan in plans]).T
    margin, gap = model.geom_margin[geoms], model.geom_gap[geoms]
    theirs = np.maximum(margin[a], margin[b]) - np.maximum(gap[a], gap[b])
    _note_pairs(
        notes,
        model,
        pairs,
        np.abs(rest[a] + rest[b] - theirs),
        "contact margin",
        "PhysX rests a pair at the sum of its geoms' margin - gap, MuJoCo at the larger margin less the larger gap",
    )
    condim, friction = _pair_friction_law(model, *pairs)
    sliding = model.geom_friction[geoms, 0]
    physx = (sliding[a] + sliding[b]) / 2 * np.maximum(torsion[a], torsion[b])
    _note_pairs(
        notes,
        model,
        pairs,
        np.abs(physx - np.where(condim >= 4, friction[:, 1], 0.0)),
        "contact torsion",
        "PhysX's torsional friction is the average sliding friction times the larger patch radius, MuJoCo's the "
        "pair's own",
    )
    rolling = np.where(condim == 6, np.maximum(friction[:, 2], 0.0), 0.0)
    _note_pairs(notes, model, pairs, rolling, "contact rolling", "PhysX has no rolling friction")


def note_contact_rebound(model: mujoco.MjModel, geoms: np.ndarray, meeting: np.ndarray, notes: Notes) -> None:
    """MuJoCo's contact at a damping ratio of 1 or more (its default) does not rebound, nor does PhysX's at
    restitution 0, the loader's. Below 1 MuJoCo's rebounds by an amount its impedance shapes, which no PhysX
    restitution reproduces at every speed: one note names the geoms that can touch another with such a `solref`
    (tests/test_contact_classes.py::test_a_dropped_ball_does_not_rebound_as_in_mujoco)."""
    timeconst, damping = model.geom_solref[geoms].T
    stiffness = np.maximum(-timeconst, np.finfo(float).tiny)
    ratio = np.where(timeconst > 0, damping, -damping / (2 * np.sqrt(stiffness)))  # solref's direct form: -k, -b
    rebounds = (ratio < 1) & meeting.any(axis=1)
    if not rebounds.any():
        return
    i = int(np.argmin(np.where(rebounds, ratio, np.inf)))
    notes.approximate(
        "contact rebound",
        f"{int(rebounds.sum())} geoms",
        f"MuJoCo's contact rebounds under a damping ratio below 1 (lowest {ratio[i]:g}, geom "
        f"{mj.name(model, 'geom', int(geoms[i]))}); PhysX's restitution stays 0",
    )


def _pair_friction_law(model: mujoco.MjModel, first: np.ndarray, second: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """MuJoCo's condim and friction (3 coefficients) per pair of geoms (`first[k]`, `second[k]`): the higher
    priority geom's, else the larger of the two."""
    priority = model.geom_priority
    leads, trails = priority[first] > priority[second], priority[first] < priority[second]
    condim = np.maximum(model.geom_condim[first], model.geom_condim[second])
    condim = np.where(leads, model.geom_condim[first], np.where(trails, model.geom_condim[second], condim))
    friction = np.maximum(model.geom_friction[first], model.geom_friction[second])
    friction = np.where(
        leads[:, None], model.geom_friction[first], np.where(trails[:, None], model.geom_friction[second], friction)
    )
    return condim, friction


def _note_pairs(notes: Notes, model: mujoco.MjModel, pairs: tuple, difference: np.ndarray, kind: str, why: str) -> None:
    """One note of `kind` for the pairs of geoms (`pairs`: first and second geom ids) whose `difference` (m) exceeds
    float32's resolution: how many, the largest, `why`."""
    differs = difference > DISTANCE_RESOLUTION
    if not differs.any():
        return
    k = int(np.argmax(np.where(differs, difference, -1.0)))
    names = f"{mj.name(model, 'geom', int(pairs[0][k]))}/{mj.name(model, 'geom', int(pairs[1][k]))}"
    notes.approximate(
        kind, f"{int(differs.sum())} geom pairs", f"{why}; largest difference {difference[k]:g} m ({names})"
    )

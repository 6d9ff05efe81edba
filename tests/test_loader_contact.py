"""Collision filtering and static world geoms, on small fixtures, with MuJoCo and PhysX as oracles."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest
from support.corpus import FIXTURES
from support.oracle import collision_filter_mismatches, component_of

from loader import MJCFLoader
from loader.model.options import MAX_DEPENETRATION_VELOCITY


def _physx_loader() -> MJCFLoader:
    """A loader whose models' own contacts are PhysX's (`MJCFLoader.contacts`), for the tests of that mapping."""
    loader = MJCFLoader()
    loader.contacts = "physx"
    return loader


def _separation_after(result, steps: int) -> tuple[float, float]:
    """Distances within the excluded pair (left, right) and the plain pair (third, fourth), both overlapping
    by 5 cm at the start, after PhysX has stepped them."""
    for _ in range(steps):
        result.scene.step()
    poses = {art.name: art.root_pose.p for art in result.articulations}
    return (
        float(np.linalg.norm(poses["right"] - poses["left"])),
        float(np.linalg.norm(poses["fourth"] - poses["third"])),
    )


def test_excluded_pair_never_touches_in_physx_while_others_do(load):
    result = load(FIXTURES / "excluded_pair.xml")
    assert not collision_filter_mismatches(result)
    excluded, plain = _separation_after(result, 50)
    assert abs(excluded - 0.15) < 1e-4  # excluded: the overlapping boxes stay where they are
    assert plain > 0.15 + 0.01  # not excluded: PhysX pushes the overlapping boxes apart


def test_exclusion_is_load_bearing(tmp_path):
    """The same scene without <exclude>: the pair is pushed apart (so the test above can fail)."""
    text = (FIXTURES / "excluded_pair.xml").read_text()
    start, end = text.index("<contact>"), text.index("</contact>") + len("</contact>")
    (tmp_path / "no_exclude.xml").write_text(text[:start] + text[end:])
    result = MJCFLoader().load(tmp_path / "no_exclude.xml")
    excluded, _ = _separation_after(result, 50)
    assert excluded > 0.15 + 0.01


def test_a_chain_of_40_bodies_collides_like_mujoco(load):
    result = load(FIXTURES / "chain_40_bodies.xml")
    model = result.model
    assert model.nbody == 41 and model.njnt == 48
    assert not [e for e in result.unsupported if e.kind == "contact"]
    assert not collision_filter_mismatches(result)
    words = {
        tuple(result.collision_groups(component_of(result, result.mapping.geoms[g]).collision_shapes[0])[2:])
        for g in range(model.ngeom)
    }
    assert len(words) > 1  # bits are really spent on the chain's weld-parent pairs


def test_world_geoms_are_one_static_actor(load):
    result = load(FIXTURES / "world_geoms.xml")
    model = result.model
    assert len(result.actors) == 1 and len(result.articulations) == 1
    floor, wall, ghost = (model.geom(n).id for n in ("floor", "wall", "ghost"))
    assert result.mapping.geoms[floor].actor == 0 and result.mapping.geoms[wall].actor == 0
    assert result.mapping.geoms[ghost] is None  # contype = conaffinity = 0: no shape at all
    actor = component_of(result, result.mapping.geoms[floor])
    assert len(actor.collision_shapes) == 2
    # the ball falls onto the static floor and rests on it
    for _ in range(500):
        result.scene.step()
    height = result.articulations[0].root_pose.p[2]
    assert 0.09 < height < 0.11


def test_filter_bits_running_out_is_reported_not_silent(tmp_path):
    """40 bodies of two joints each need 39 weld-parent filters in one cluster: more than 32 bits."""
    lines = []
    for line in (FIXTURES / "chain_40_bodies.xml").read_text().splitlines():
        if 'b" type="hinge"' not in line:
            lines.append(line)
        if 'a" type="hinge"' in line:
            lines.append(line.replace('a" type', 'b" type').replace('axis="0 1 0"', 'axis="0 0 1"'))
    (tmp_path / "chain.xml").write_text("\n".join(lines))
    result = MJCFLoader().load(tmp_path / "chain.xml")
    assert result.model.njnt == 80
    overflow = [e for e in result.unsupported if e.kind == "contact"]
    assert len(overflow) == 39 - 32
    # everything else still agrees with MuJoCo
    assert not collision_filter_mismatches(result)


SWITCH_CONTACTS = """
import sys, warnings
import numpy as np
warnings.simplefilter("ignore")
import loader.runtime.contacts
from loader import MJCFLoader
result = MJCFLoader(ignore_classes=[]).load(sys.argv[1])
before = (result.articulations[0].get_qpos().copy(), result.articulations[0].get_qvel().copy())
if sys.argv[2] == "no-warm-up":  # the deliberate mistake: the groups zeroed with no step before
    loader.runtime.contacts.warm_up = lambda scene: None
result.set_contacts(False)
after = (result.articulations[0].get_qpos(), result.articulations[0].get_qvel())
assert all(np.array_equal(a, b) for a, b in zip(before, after)), "switching contacts off moved the state"
for _ in range(5):
    result.scene.step()
result.set_contacts(True)
for _ in range(20):
    result.scene.step()
print("survived", flush=True)
"""


def _switch_contacts(mistake: str) -> int:
    """In a fresh process (a PhysX crash is a segfault): contacts off before the scene's first step, five steps,
    contacts back on, twenty steps. The process's exit code."""
    import subprocess
    import sys

    from support.corpus import suite_path

    proc = subprocess.run(
        [sys.executable, "-c", SWITCH_CONTACTS, str(suite_path("manipulator")), mistake],
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
    )
    assert proc.returncode != 0 or "survived" in proc.stdout, proc.stderr
    return proc.returncode


def test_contacts_switched_off_before_the_first_step_come_back_without_a_crash():
    assert _switch_contacts("none") == 0


def test_a_plain_restore_of_zeroed_collision_groups_crashes_physx():
    """The deliberate mistake: the groups zeroed without `disable_contacts`' warm-up step (SAPIEN 3.0.3)."""
    assert _switch_contacts("no-warm-up") == -11


JAMMED_SPEED = {10: 2.0, 255: 15.0}  # x MuJoCo's fastest DoF over 0.2 s. Measured (mujoco 3.17.0, sapien 3.0.3):
# SAPIEN 0.86 and 10.5 rad/s against MuJoCo's 1.39; with a 1 m/s cap (the mistake) 12.2 and 95


@pytest.mark.parametrize("iterations", sorted(JAMMED_SPEED))
@pytest.mark.parametrize("cap", [MAX_DEPENETRATION_VELOCITY, 1.0], ids=["loader", "mistake_1_m_s"])
def test_arms_started_inside_each_other_come_apart_as_slowly_as_in_mujoco(iterations, cap):
    """Menagerie's aloha at qpos0: its two arms overlap by up to 3.5 cm over 91 contacts. MuJoCo's soft contacts
    ease them apart; PhysX's rigid ones, solved with a depenetration speed cap, fling the jammed links, and the
    harder the more position iterations it runs (an articulation runs with another's count when the scene holds
    one that needs more, `plan/solver_iterations.py`). The loader's cap keeps the arms near MuJoCo's speeds where
    PhysX makes the contacts (`contacts="physx"`)."""
    from support.corpus import menagerie_root
    from support.lockstep import paired_rollout

    root = menagerie_root()
    if root is None or not (root / "aloha" / "scene.xml").is_file():
        pytest.skip("the Menagerie slice is not installed (the `menagerie` extra)")
    result = _physx_loader().load(root / "aloha" / "scene.xml")
    for articulation in result.articulations:
        articulation.solver_position_iterations = iterations
        for link in articulation.links:
            link.max_depenetration_velocity = cap
    model = result.model
    paired = paired_rollout(result, model, mujoco.MjData(model), 100)
    within = paired.sapien_speed.max() <= JAMMED_SPEED[iterations] * paired.mujoco_speed.max()
    assert within == (cap == MAX_DEPENETRATION_VELOCITY), (paired.sapien_speed.max(), paired.mujoco_speed.max())


PAIRS = """<mujoco><option timestep="0.002"/><worldbody>
  <geom name="floor" type="plane" size="2 2 .1" contype="0" conaffinity="0"/>
  <geom name="wall" type="box" size=".05 2 1" pos="-1 0 1" contype="0" conaffinity="0"/>
  <body name="a" pos="0 0 .3"><freejoint/><geom name="ball" size=".1" contype="0" conaffinity="0"/></body>
  <body name="b" pos=".5 0 .3"><freejoint/><geom name="box" type="box" size=".1 .1 .1" contype="0" conaffinity="0"/>
    <body name="lid" pos="0 0 .2"><joint type="hinge" axis="1 0 0"/>
      <geom name="lid" type="box" size=".1 .1 .02" contype="0" conaffinity="0"/></body></body>
  <body name="c" pos="-.5 0 .3"><freejoint/><geom name="cube" type="box" size=".1 .1 .1" contype="0" conaffinity="0"/>
  </body></worldbody>
  <contact><pair name="ball_floor" geom1="floor" geom2="ball"/>
    <pair name="box_floor" geom1="floor" geom2="box" friction="0.3 0.3 0.005 0.0001 0.0001"/>
    <pair name="cube_floor" geom1="cube" geom2="floor"/><pair name="cube_wall" geom1="wall" geom2="cube"/>
    <pair name="lid_box" geom1="lid" geom2="box"/></contact></mujoco>"""
REST = 1e-3  # m: MuJoCo's soft contacts rest the bodies 0.4 mm into the floor, PhysX's on it (mujoco 3.17.0)


def test_explicit_pairs_make_mujocos_contacts_and_note_what_physx_loses(tmp_path, monkeypatch):
    """Every geom here has contype = conaffinity = 0: only the pairs make contacts. The floor, the wall and the
    bodies meet exactly where MuJoCo's pairs say (one bit serves the floor's pairs, another the wall's, which
    sharing would let the ball touch the wall); bodies resting on the floor stay there. A lid on its parent box is
    a pair PhysX's parent rule blocks, and the box's pair has its own friction: both noted. The words serve where
    PhysX makes the model's contacts (`contacts="physx"`, after `release()`). Mutation: the pairs left unplanned, so
    that every body falls through the floor."""
    from loader import mjcf_loader

    path = tmp_path / "pairs.xml"
    path.write_text(PAIRS)
    result = _physx_loader().load(str(path))
    assert collision_filter_mismatches(result) == [("box", "lid", False)]  # the one the parent rule blocks
    assert sorted((n.name, n.reason) for n in result.unsupported + result.approximations if "pair" in n.kind) == [
        ("box_floor", "sliding friction 0.3 (the pair's); PhysX averages its geoms' to 1"),
        ("lid_box", "its contact is lost: PhysX never lets a link touch its direct parent"),
    ]
    model, data = result.model, mujoco.MjData(result.model)
    for _ in range(500):
        result.set_ctrl(None)
        result.scene.step()
        mujoco.mj_step(model, data)
    heights = result.get_state()[0][[2, 9, 17]], data.qpos[[2, 9, 17]]
    assert np.abs(heights[0] - heights[1]).max() < REST, heights
    monkeypatch.setattr(mjcf_loader, "plan_pairs", lambda *args: None)
    fallen = _physx_loader().load(str(path))
    for _ in range(500):
        fallen.set_ctrl(None)
        fallen.scene.step()
    assert fallen.get_state()[0][[2, 9, 17]].max() < -0.5


CREEP = """<mujoco><option timestep="0.002" gravity="4 0 -9.81"/><worldbody><geom type="plane" size="2 2 .1"/>
  <body pos="0 0 .05"><freejoint/><geom type="box" size=".05 .05 .05" mass="1"/></body></worldbody></mujoco>"""
CREEP_TOLERANCE = 1e-5  # m: the box's path against MuJoCo's over 1 s. Measured 2.5e-8; with PhysX's contacts (it
# sticks) 2.5e-3 (mujoco 3.17.0, sapien 3.0.3)


def _creep(contacts: str) -> float:
    """The largest distance of the box from MuJoCo's over 1 s, pulled sideways at 4 m/s^2 (below its sliding
    friction), through `set_ctrl`."""
    model = mujoco.MjModel.from_xml_string(CREEP)
    data = mujoco.MjData(model)
    loader = MJCFLoader()
    loader.contacts = contacts
    result = loader.load(mujoco.MjSpec.from_string(CREEP))
    worst = 0.0
    for _ in range(round(1.0 / model.opt.timestep)):
        result.set_ctrl(None)
        result.scene.step()
        mujoco.mj_step(model, data)
        worst = max(worst, float(np.linalg.norm(result.get_state()[0][:3] - data.qpos[:3])))
    return worst


def test_a_box_under_a_push_creeps_over_the_floor_as_in_mujoco():
    """MuJoCo's friction is soft: under a pull below its limit the box creeps, at the rate its impedance gives. The
    model's own contacts are MuJoCo's (`runtime/rows.py`, `runtime/contacts.py`: OwnContacts), so SAPIEN's box
    follows. Mutation: PhysX's contacts, whose friction holds the box still."""
    assert _creep("mujoco") < CREEP_TOLERANCE
    assert _creep("physx") > 100 * CREEP_TOLERANCE


BESIDE = """<mujoco><option timestep="0.002"/><worldbody><geom name="floor" type="plane" size="2 2 .1"/>
  <body pos="0 0 .2"><freejoint/><geom type="box" size=".05 .05 .05" mass="1"/></body></worldbody></mujoco>"""
OTHER = """<mujoco><option timestep="0.002"/><worldbody>
  <body pos=".3 0 .2"><freejoint/><geom type="sphere" size=".05" mass="1"/></body></worldbody></mujoco>"""


def _heights_beside() -> tuple[float, float, float]:
    """A model with a floor and a box, a second model (a ball, no floor) loaded into the same scene, and a box the
    caller builds there: their heights after 0.5 s, each load stepped through `set_ctrl`."""
    import sapien

    first = MJCFLoader().load(mujoco.MjSpec.from_string(BESIDE))
    second = MJCFLoader().set_scene(first.scene).load(mujoco.MjSpec.from_string(OTHER))
    builder = first.scene.create_actor_builder()
    builder.add_box_collision(half_size=[0.05, 0.05, 0.05])
    box = builder.build(name="caller's box")
    box.set_pose(sapien.Pose([-0.3, 0.0, 0.2]))
    for _ in range(250):
        first.set_ctrl(None)
        second.set_ctrl(None)
        first.scene.step()
    return float(first.get_state()[0][2]), float(second.get_state()[0][2]), float(box.pose.p[2])


def test_objects_outside_the_model_still_touch_it_through_physx(monkeypatch):
    """The model's own contacts are MuJoCo's, PhysX's between its shapes off; a box the caller builds and a second
    load in the same scene still land on the first load's floor through PhysX (each load takes its own g1 bit).
    Mutation: both loads with one bit, so the second falls through the first's floor."""
    from loader.runtime import contacts

    own, other, callers = _heights_beside()
    assert abs(own - 0.05) < 1e-3 and abs(other - 0.05) < 1e-2 and abs(callers - 0.05) < 1e-2, (own, other, callers)
    monkeypatch.setattr(contacts, "load_bits", lambda scene, shapes: 1 << contacts.LOAD_BITS[0])
    own, other, callers = _heights_beside()
    assert other < 0.0, other


CRATE = """<mujoco><option timestep="0.002"/><worldbody>
  <body pos="{x} 0 {z}"><freejoint/><geom type="box" size=".05 .05 .05" mass="1"/></body></worldbody></mujoco>"""


def _stacked_last(loads: int) -> float:
    """`BESIDE` (a floor and a box), then `loads` crates in the same scene, each its own load, in a row on the floor
    but the last, dropped onto the one before it: the last crate's height after 0.5 s, every load stepped through
    `set_ctrl`."""
    first = MJCFLoader().load(mujoco.MjSpec.from_string(BESIDE))
    crates = [
        MJCFLoader()
        .set_scene(first.scene)
        .load(
            mujoco.MjSpec.from_string(CRATE.format(x=0.2 * min(k, loads - 2) + 0.2, z=0.06 if k < loads - 1 else 0.17))
        )
        for k in range(loads)
    ]
    for _ in range(250):
        for result in (first, *crates):
            result.set_ctrl(None)
        first.scene.step()
    return float(crates[-1].get_state()[0][2])


def test_loads_beyond_the_free_bits_still_touch_each_other(monkeypatch):
    """Sixteen crates loaded beside a floor's load: seventeen loads, more than the fifteen free g1 bits, so the
    last loads take sets of two bits; the last crate still lands on the one before it (0.15 m up). Mutation: the
    last bit shared once the single bits run out, so the last crate falls through its neighbour to the floor."""
    from itertools import count

    from loader.runtime import contacts

    assert abs(_stacked_last(16) - 0.15) < 1e-2
    taken = count()
    monkeypatch.setattr(contacts, "load_bits", lambda scene, shapes: 1 << contacts.LOAD_BITS[min(next(taken), 14)])
    assert _stacked_last(16) < 0.1


def _after_release() -> float:
    """The box of `BESIDE` stepped once through `set_ctrl`, then released and stepped 0.5 s by PhysX alone: its
    height."""
    result = MJCFLoader().load(mujoco.MjSpec.from_string(BESIDE))
    result.set_ctrl(None)
    result.scene.step()
    result.release()
    for _ in range(250):
        result.scene.step()
    return float(result.get_state()[0][2])


def test_release_gives_the_model_its_own_contacts_back(monkeypatch):
    """After `release()` nothing applies MuJoCo's contacts: PhysX's are back between the model's shapes, and the box
    stepped without `set_ctrl` rests on its floor. Mutation: the groups not given back, so it falls through."""
    from loader.runtime.contacts import OwnContacts

    assert abs(_after_release() - 0.05) < 1e-2
    monkeypatch.setattr(OwnContacts, "give_back", lambda self: None)
    assert _after_release() < 0.0

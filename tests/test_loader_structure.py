"""Articulations, names, builders and the ManiSkill-compatible surface."""

from __future__ import annotations

import warnings

import mujoco
import numpy as np
import pytest
from support.corpus import FIXTURES, suite_path
from support.oracle import POSE_TOLERANCE, link_pose_errors

from loader import Approximation, MJCFLoader, Unsupported, UnsupportedFeatureWarning
from loader.plan.geom import hfield_triangles


def test_unnamed_bodies_load_with_unique_link_names(load, rng):
    result = load(FIXTURES / "unnamed_bodies.xml")
    names = [link.name for art in result.articulations for link in art.links]
    assert len(names) == len(set(names))
    assert len(result.articulations) == 2
    assert max(link_pose_errors(result, rng, random_configurations=10)) < POSE_TOLERANCE


def test_parse_returns_builders_that_build_on_their_own():
    loader = MJCFLoader(ignore_classes=["motor"], visual_groups=[0, 2])
    articulation_builders, actor_builders, cameras = loader.parse(suite_path("cartpole"))
    assert loader.scene is not None
    articulations = [builder.build() for builder in articulation_builders]
    actors = [builder.build_static("world") for builder in actor_builders]
    assert [art.dof for art in articulations] == [2]
    assert len(actors) == 1
    assert {camera.name for camera in cameras} == {"fixed", "lookatcart"}
    # the PhysX overrides are applied by build() itself
    art = articulations[0]
    assert all(link.linear_damping == 0 and link.angular_damping == 0 for link in art.links)
    assert all(float(joint.friction) == 0 for joint in art.active_joints)


def test_fix_root_link_false_lets_a_jointless_root_float(tmp_path):
    (tmp_path / "box.xml").write_text(
        '<mujoco><worldbody><body name="crate" pos="0 0 1"><geom type="box" size=".1 .1 .1"/></body>'
        "</worldbody></mujoco>"
    )
    loader = MJCFLoader()
    loader.fix_root_link = False
    result = loader.load(tmp_path / "box.xml")
    for _ in range(100):
        result.scene.step()
    assert result.articulations[0].root_pose.p[2] < 0.95  # fell under gravity
    fixed = MJCFLoader().load(tmp_path / "box.xml")
    for _ in range(100):
        fixed.scene.step()
    assert fixed.articulations[0].root_pose.p[2] == pytest.approx(1.0)


SPATIAL_SPRING = """<mujoco><worldbody><site name="top" pos="0 0 1"/><body><joint name="a" axis="0 1 0"/>
  <geom size=".1" pos=".2 0 0"/><site name="tip" pos=".4 0 0"/></body></worldbody>
  <tendon><spatial name="rope" stiffness="5" armature="0.1"><site site="top"/><site site="tip"/></spatial>
  </tendon></mujoco>"""


CYLINDERS = SPATIAL_SPRING.replace(
    '<geom size=".1" pos=".2 0 0"/>',
    "".join(f'<geom type="cylinder" size=".05 .1" pos=".{k} 0 0"/>' for k in (2, 3, 4)),
)  # each a convex approximation


def test_unsupported_features_are_listed_and_warned_once_per_kind(tmp_path):
    """What a load drops is warned, one warning per kind; approximations are listed and warned only on request
    (`warn_approximations`), each note of its own class."""
    (tmp_path / "rope.xml").write_text(CYLINDERS)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        quiet = MJCFLoader().load(tmp_path / "rope.xml")
    assert ("tendon", "rope") in {(entry.kind, entry.name) for entry in quiet.unsupported}  # its armature
    assert {type(n) for n in quiet.unsupported} == {Unsupported} and quiet.approximations
    assert {type(n) for n in quiet.approximations} == {Approximation}
    dropped = [w for w in caught if issubclass(w.category, UnsupportedFeatureWarning)]
    assert {str(w.message).split(" x")[0] for w in dropped} == {
        f"rope.xml: unsupported {e.kind}" for e in quiet.unsupported
    }
    loader = MJCFLoader()
    loader.warn_approximations = True
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        result = loader.load(tmp_path / "rope.xml")
    ours = [w for w in caught if issubclass(w.category, UnsupportedFeatureWarning)]
    kinds = {("unsupported", e.kind) for e in result.unsupported} | {
        ("approximated", e.kind) for e in result.approximations
    }
    assert len(ours) == len(kinds) < len(result.unsupported) + len(result.approximations)
    geoms = [str(w.message) for w in ours if str(w.message).startswith("rope.xml: approximated geom x3: ")]
    assert len(geoms) == 1 and "2 more in result.approximations" in geoms[0]
    assert all(w.filename == __file__ for w in ours), "the warning points at the caller's line, not the loader's"
    assert not any(str(tmp_path) in str(w.message) for w in ours), "the file's name, not its whole path"
    loader.warn_each_note = True
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        loader.load(tmp_path / "rope.xml")
    each = [w for w in caught if issubclass(w.category, UnsupportedFeatureWarning)]
    assert len(each) == len(result.unsupported) + len(result.approximations)


def test_nonlinear_damping_and_actuator_passive_terms_are_listed_not_dropped_silently():
    import mujoco

    spec = mujoco.MjSpec.from_string(
        '<mujoco><worldbody><body><joint name="poly" damping="1 2" stiffness="3 4"/><geom size=".1"/></body>'
        '<body pos="1 0 0"><joint name="plain" damping="1"/><geom size=".1"/></body></worldbody>'
        '<actuator><position name="damped" joint="plain" kp="5" damping="0.3"/>'
        '<position name="bare" joint="plain" kp="5"/></actuator></mujoco>'
    )
    result = MJCFLoader().load(spec)
    listed = {(entry.kind, entry.name) for entry in result.unsupported}
    assert {("joint", "poly"), ("actuator", "damped")} <= listed
    assert not {("joint", "plain"), ("actuator", "bare")} & listed


def test_tendon_armature_is_listed_not_dropped_silently():
    import mujoco

    spec = mujoco.MjSpec.from_string(
        '<mujoco><worldbody><body><joint name="a"/><geom size=".1"/></body><body pos="1 0 0"><joint name="b"/>'
        '<geom size=".1"/></body></worldbody><tendon>'
        '<fixed name="rough" frictionloss="0.5" damping="0.2"><joint joint="a" coef="1"/><joint joint="b" coef="-1"/>'
        '</fixed><fixed name="heavy" armature="0.1" damping="0.2"><joint joint="a" coef="1"/></fixed>'
        '<fixed name="plain" damping="0.2"><joint joint="b" coef="1"/></fixed></tendon></mujoco>'
    )
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        result = MJCFLoader().load(spec)
    reasons = {entry.name: entry.reason for entry in result.unsupported if entry.kind == "tendon"}
    assert "armature" in reasons["heavy"] and "rough" not in reasons and "plain" not in reasons  # friction: a row


def test_keyframe_is_usable_as_the_initial_state(load):
    result = load(suite_path("dog"))
    qpos, _ = result.keyframe_state(0)
    np.testing.assert_allclose(qpos, result.model.key_qpos[0])
    result.reset(0)
    back, _ = result.mapping.get_state(result.articulations)
    np.testing.assert_allclose(back[7:], qpos[7:], atol=1e-5)
    result.reset()


def test_the_state_api_round_trips(load, rng):
    from support.oracle import body_poses, link_of, random_qpos

    from loader import ControlError

    result = load(suite_path("dog"))  # a free root, hinges, several joints per body, keyframes
    model = result.model
    qpos, qvel = random_qpos(model, rng), rng.uniform(-1.0, 1.0, model.nv)
    result.set_state(qpos, qvel)
    got_qpos, got_qvel = result.get_state()
    np.testing.assert_allclose(got_qpos, qpos, atol=1e-5)  # SAPIEN holds float32
    np.testing.assert_allclose(got_qvel, qvel, atol=1e-5)
    xpos, _ = body_poses(model, qpos)  # MuJoCo's kinematics of the same qpos: the links are where MuJoCo puts them
    assert max(float(np.abs(link_of(result, b).entity_pose.p - xpos[b]).max()) for b in range(1, model.nbody)) < 1e-5
    with pytest.raises(ControlError, match="qpos has shape"):
        result.set_state(qpos[:-1])
    np.testing.assert_allclose(result.get_state()[0], qpos, atol=1e-5)  # a rejected state changes nothing
    result.set_state(qpos)
    assert not result.get_state()[1].any(), "qvel None: at rest"
    np.testing.assert_array_equal(result.keyframe_state(0)[0], model.key_qpos[0])
    with pytest.warns(DeprecationWarning, match="keyframe_state"):
        np.testing.assert_array_equal(result.state(0)[0], model.key_qpos[0])
    result.reset()


TREES = """<mujoco{named}><worldbody>
  <body name="arm"><joint axis="0 1 0"/><geom size="0.1" contype="0"/></body>
  {second}</worldbody></mujoco>"""


@pytest.mark.parametrize(
    "named,second,names",
    [
        (' model="picker"', "", ["picker"]),
        ("", "", ["arm"]),  # a document without a model name: the root body's
        (' model="picker"', '<body name="cube"><freejoint/><geom size="0.1" contype="0"/></body>', ["arm", "cube"]),
    ],
)
def test_articulations_are_named_after_the_model_or_their_root(tmp_path, named, second, names):
    (tmp_path / "scene.xml").write_text(TREES.format(named=named, second=second))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        result = MJCFLoader().load(tmp_path / "scene.xml")
    assert [art.name for art in result.articulations] == names


def test_no_render_device_skips_visuals_but_keeps_physics():
    from loader import has_render_device

    if has_render_device():
        pytest.skip("a render device exists here: visuals are built")
    result = MJCFLoader(visual_groups=[0, 1, 2]).load(suite_path("pendulum"))
    assert result.articulations and not any(
        type(c).__name__ == "RenderBodyComponent"
        for art in result.articulations
        for link in art.links
        for c in link.entity.components
    )


def test_cameras_and_sites_carry_their_body_and_pose(load):
    result = load(suite_path("cartpole"))
    camera = next(c for c in result.cameras if c.name == "fixed")
    assert camera.body == "world" and 0 < camera.fovy < np.pi
    assert result.sites == {} or all(site.body for site in result.sites.values())


def test_textures_come_from_the_compiled_model(load):
    result = load(suite_path("cartpole"))
    grid = next(t for t in result.textures if t.name == "grid")
    assert grid.type == "2d" and grid.data.ndim == 3 and grid.data.size > 0
    # MuJoCo's own pixels (the compiled model's the load keeps), not a copy per load, and read-only so that the
    # model's stay as compiled
    assert np.shares_memory(grid.data, result.controller.model.tex_data) and not grid.data.flags.writeable


def test_ignore_classes_skips_a_class_entirely_and_defaults_like_maniskill(tmp_path):
    (tmp_path / "classes.xml").write_text(
        '<mujoco><default><default class="motor"><geom rgba="1 0 0 1"/></default></default><worldbody>'
        '<body name="b"><freejoint/><geom type="sphere" size=".1"/><geom class="motor" type="box" size=".1 .1 .1"/>'
        "</body></worldbody></mujoco>"
    )
    default = MJCFLoader()
    assert default.ignore_classes == ["motor"] and default.visual_groups == [0, 2]
    skipped = default.load(tmp_path / "classes.xml")
    assert [g is None for g in skipped.mapping.geoms] == [False, True]
    kept = MJCFLoader(ignore_classes=[]).load(tmp_path / "classes.xml")
    assert all(g is not None for g in kept.mapping.geoms)


def test_included_robot_with_frame_and_replicate_arrives_whole(load, rng):
    """ManiSkill's loader lost robots from included files; MuJoCo's compiler resolves include, frame, replicate."""
    result = load(FIXTURES / "include_scene.xml")
    model = result.model
    assert model.nbody == 5 and model.njnt == 4  # world, base, three replicated segments
    assert [art.dof for art in result.articulations] == [4]
    assert max(link_pose_errors(result, rng, random_configurations=10)) < POSE_TOLERANCE


def test_solver_iterations_reach_every_articulation():
    loader = MJCFLoader()
    loader.solver_iterations = (50, 4)
    result = loader.load(suite_path("finger"))
    assert [(a.solver_position_iterations, a.solver_velocity_iterations) for a in result.articulations] == [
        (50, 4)
    ] * len(result.articulations)


def test_an_mjspec_edited_in_python_loads_as_compiled():
    import mujoco

    spec = mujoco.MjSpec.from_file(str(suite_path("cartpole")))
    for joint in spec.joints:
        joint.damping = [0.75, 0.0, 0.0]  # MjsJoint keeps a polynomial: the linear term first
    result = MJCFLoader().load(spec)
    assert np.allclose(result.model.dof_damping, 0.75)
    joints = [j for art in result.articulations for j in art.active_joints]
    assert len(joints) == 2 and all(np.isclose(j.damping, 0.75) for j in joints)


def test_an_mjspec_built_from_scratch_loads():
    import mujoco

    spec = mujoco.MjSpec()
    body = spec.worldbody.add_body(name="pole", pos=[0, 0, 1])
    body.add_joint(name="hinge", type=mujoco.mjtJoint.mjJNT_HINGE, axis=[0, 1, 0])
    body.add_geom(type=mujoco.mjtGeom.mjGEOM_CAPSULE, size=[0.05, 0.3, 0], mass=1.0)
    result = MJCFLoader().load(spec)
    assert [art.dof for art in result.articulations] == [1]
    assert np.isclose(sum(link.mass for link in result.articulations[0].links if link.mass > 1e-6), 1.0)


@pytest.mark.parametrize(
    "integrator, listed", [("RK4", True), ("implicit", True), ("Euler", False), ("implicitfast", False)]
)
def test_an_integrator_physx_cannot_follow_is_listed(tmp_path, integrator, listed):
    path = tmp_path / "integrator.xml"
    path.write_text(
        f'<mujoco><option integrator="{integrator}"/><worldbody><body><joint/><geom size=".1"/>'
        "</body></worldbody></mujoco>"
    )
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        result = MJCFLoader().load(path)
    assert (("option", "integrator") in {(e.kind, e.name) for e in result.approximations}) is listed


COAXIAL = """<mujoco><worldbody><body pos="0 0 1"><joint name="a" axis="1 0 0"/>
  <inertial pos="0 0 0" mass="1e-9" diaginertia="3e-13 3e-13 6e-13"/>
  <body pos=".25 0 0"><joint name="b" axis="1 0 0"/><geom type="box" size=".05 .05 .05" mass=".1"/></body>
</body></worldbody></mujoco>"""


def test_a_joint_space_inertia_float32_cannot_resolve_is_listed(monkeypatch):
    """Two coaxial hinges with a weightless link between them: MuJoCo's joint-space inertia is conditioned beyond
    float32 (about 1e11), so PhysX's articulation cannot follow MuJoCo; the loader says so. A well-conditioned
    arm gets no such note. Mutation: the check skipped."""
    import mujoco

    from loader.plan import features

    def listed(xml: str) -> list:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            result = MJCFLoader().load(mujoco.MjSpec.from_string(xml))
        return [e for e in result.approximations if e.name == "joint-space inertia"]

    (note,) = listed(COAXIAL)
    assert float(note.reason.split("condition number ")[1].split()[0]) > features.FLOAT32_CONDITION
    assert not listed(
        COAXIAL.replace(
            'mass="1e-9" diaginertia="3e-13 3e-13 6e-13"', 'mass=".5" diaginertia="1e-3 1e-3 1e-3"'
        ).replace('axis="1 0 0"/>\n  <inertial', 'axis="0 1 0"/>\n  <inertial')
    )
    monkeypatch.setattr(features, "note_ill_conditioned", lambda model, notes: None)
    assert not listed(COAXIAL)


@pytest.mark.parametrize("name", ["humanoid", "manipulator", "swimmer"])
def test_inertia_blocks_are_mujocos_full_matrix(name):
    """The tree blocks read from MuJoCo's sparse inertia rebuild mj_fullM's dense matrix entry for entry, and the
    per-tree pseudo-inverse is the dense one's (M is block-diagonal over trees). Mutation: a block transposed
    against the tree's DoF order, or one entry dropped, is caught by the same comparison."""
    from loader.model import mj

    model = mujoco.MjModel.from_xml_path(str(suite_path(name)))
    data = mj.forward_at(model, model.qpos0 + 0.1 * np.arange(model.nq) % 0.3)
    dense = np.zeros((model.nv, model.nv))
    mujoco.mj_fullM(model, data, dense)
    rebuilt = np.zeros_like(dense)
    for dofs, block in mj.inertia_blocks(model, data):
        rebuilt[np.ix_(dofs, dofs)] = block
    assert np.array_equal(rebuilt, dense)
    dofs, inverse = mj.inverse_inertia(model, data)
    np.testing.assert_allclose(inverse, np.linalg.pinv(dense, hermitian=True)[np.ix_(dofs, dofs)], atol=1e-9)
    broken = rebuilt.copy()
    broken[0, model.nv - 1] = broken[model.nv - 1, 0] = 1.0 + abs(dense[0, model.nv - 1])
    assert not np.array_equal(broken, dense)


def test_a_load_reads_one_forward_pass_at_qpos0(monkeypatch):
    """Every stage that reads MuJoCo's forward pass at qpos0 (body poses, the ill-conditioning note, the drives'
    inertia diagonal, the solver iterations) reads the one the compile made; outside a load a call makes its own.
    Mutation: a stage that makes its own pass is caught by the count of distinct passes."""
    from loader.model import mj

    made, original = [], mj.forward_at

    def spy(model, *args, **kwargs):
        made.append(original(model, *args, **kwargs))
        return made[-1]

    monkeypatch.setattr(mj, "forward_at", spy)
    result = MJCFLoader().load(suite_path("cartpole"))  # no keyframe, no equality: every pass is at qpos0
    assert len(made) >= 5 and all(data is made[0] for data in made)
    assert original(result.model) is not made[0]


def test_a_load_makes_one_mujoco_data_where_its_rows_need_one(monkeypatch):
    """A limited hinge (constraint rows) and a ball-jointed body pinned to it by a connect (a D6 joint, which the
    rows' copy must not solve again): the load makes one MuJoCo data, the rows keeping the load's forward pass at
    qpos0 once the build has read it (`Controller.spare`), with only the copy's couplings active, and the pair
    steps bit for bit as with a data of the rows' own. Mutation: no hand-over makes two."""
    from loader.runtime.controller import Controller

    xml = (
        '<mujoco><worldbody><body name="a" pos="0 0 1"><joint type="hinge" axis="0 1 0" range="-1 1"/>'
        '<geom type="capsule" fromto="0 0 0 .2 0 0" size=".02"/></body><body name="b" pos=".4 0 1">'
        '<joint type="ball"/><geom type="capsule" fromto="0 0 0 -.2 0 0" size=".02"/></body></worldbody>'
        '<equality><connect body1="a" body2="b" anchor=".2 0 0"/></equality></mujoco>'
    )
    made, original = [], mujoco.MjData

    def counted(model):
        made.append(model)
        return original(model)

    monkeypatch.setattr(mujoco, "MjData", counted)
    handed = MJCFLoader().load(mujoco.MjSpec.from_string(xml))
    assert len(made) == 1
    monkeypatch.setattr(mujoco, "MjData", original)
    assert [link.kind for link in handed.equalities] == ["D6 joint"]
    assert handed.controller.term("rows").data.eq_active.tolist() == [False]
    monkeypatch.setattr(Controller, "spare", lambda self, model, data: False)
    own = MJCFLoader().load(mujoco.MjSpec.from_string(xml))
    for result in (handed, own):
        for _ in range(100):
            result.step(np.zeros(result.model.nu))
    assert np.abs(handed.get_state()[0] - handed.model.qpos0).max() > 0.01  # it sags on its pin
    np.testing.assert_array_equal(np.concatenate(handed.get_state()), np.concatenate(own.get_state()))


@pytest.mark.parametrize(
    "element, where",
    [
        ('<body name="b" pos=".2 0 0" quat="1e-30 0 1e-30 0"><joint/><geom size=".1"/></body>', "body 'b'"),
        ('<inertial pos="0 0 0" mass="1" diaginertia="1 2 3" quat="1e-30 1e-30 1e-30 1e-30"/>', "body 'a' <inertial>"),
        ('<geom size=".1" quat="1e-8 0 0 0"/>', "geom 'g'"),
        ('<site name="s" quat="1e-10 0 1e-10 0"/>', "site 's'"),
    ],
)
def test_a_frame_quaternion_the_compiler_left_unnormalized_is_a_typed_error(element, where, monkeypatch):
    """MuJoCo's compiler leaves a quaternion shorter than about 1e-6 as written, and its kinematics rotate a geom,
    site, camera or inertia frame by it unnormalized (a scaled, degenerate rotation: the inertia tensor of a
    robustness-session mutant vanished) and give a body with one the world's orientation, whatever its parent's
    (a mutant's joint axes 1.5 rad off). The loader names the element. Mutation: the check skipped loads it."""
    import mujoco

    import loader.mjcf_loader
    from loader import MJCFError, MJCFLoader

    element = element.replace("<geom size", '<geom name="g" size')
    xml = (
        f'<mujoco><worldbody><body name="a" euler="0 90 0"><joint/><geom size=".1" mass="1"/>{element}</body>'
        "</worldbody></mujoco>"
    )
    with pytest.raises(MJCFError, match="is not a unit quaternion") as caught:
        MJCFLoader().load(mujoco.MjSpec.from_string(xml))
    assert where in str(caught.value)
    monkeypatch.setattr(loader.mjcf_loader, "check_numbers", lambda model, path: None)
    MJCFLoader().load(mujoco.MjSpec.from_string(xml))


def test_a_shared_mesh_is_cooked_once(tmp_path, monkeypatch):
    """Three geoms of one mesh get their hull from one file of `loader/plan/hulls.py` (cooked once), a mesh of one
    geom and a height field are cooked from memory, a second load cooks none of them from memory again, and every
    hull and triangle mesh is the one PhysX cooks from the same vertices (101 and 50 of them: the STL pads the last
    triangle)."""
    import sapien

    rng = np.random.default_rng(20261125)

    def numbers(n: int, low: float = -0.05) -> str:
        return " ".join(f"{x:.5f}" for x in rng.uniform(low, 0.05, n))

    path = tmp_path / "meshes.xml"
    path.write_text(f"""<mujoco><asset><mesh name="shared" vertex="{numbers(303)}"/>
      <mesh name="single" vertex="{numbers(150)}"/>
      <hfield name="ground" nrow="5" ncol="7" size="1 1 .2 .1" elevation="{numbers(35, 0.0)}"/></asset>
      <worldbody><geom type="hfield" hfield="ground"/>
        <body pos="0 0 1"><freejoint/><geom type="mesh" mesh="shared"/>
        <geom type="mesh" mesh="shared" pos=".2 0 0"/><geom type="mesh" mesh="shared" pos=".4 0 0"/>
        <geom type="mesh" mesh="single" pos=".6 0 0"/></body></worldbody></mujoco>""")
    convex, triangles = sapien.physx.PhysxCollisionShapeConvexMesh, sapien.physx.PhysxCollisionShapeTriangleMesh
    sources = []

    def recorded(kind):
        def make(*args, **kwargs):
            sources.append(args[0] if isinstance(args[0], str) else "memory")
            return kind(*args, **kwargs)

        return make

    monkeypatch.setattr(sapien.physx, "PhysxCollisionShapeConvexMesh", recorded(convex))
    monkeypatch.setattr(sapien.physx, "PhysxCollisionShapeTriangleMesh", recorded(triangles))
    result = MJCFLoader().load(path)
    hulls = sources[:4]  # the body's, then the world's height field
    assert hulls[3] == "memory" and hulls[0] != "memory" and hulls[:3] == [hulls[0]] * 3, sources
    assert sources[4:] == ["memory"], sources
    sources.clear()
    MJCFLoader().load(path)
    assert "memory" not in sources and len(set(sources)) == 3, sources
    model = result.model
    shapes = result.articulations[0].links[0].collision_shapes
    assert len(shapes) == 4
    for g, shape in enumerate(shapes, start=1):
        mesh = int(model.geom_dataid[g])
        start, count = model.mesh_vertadr[mesh], model.mesh_vertnum[mesh]
        cooked = convex(
            np.ascontiguousarray(model.mesh_vert[start : start + count], np.float32),
            np.ones(3, np.float32),
            shape.physical_material,
        )
        assert np.array_equal(shape.get_vertices(), cooked.get_vertices())
        assert np.array_equal(shape.get_triangles(), cooked.get_triangles())
    ground = result.actors[0].components[-1].collision_shapes[0]
    cooked = triangles(*hfield_triangles(model, 0), np.ones(3, np.float32), ground.physical_material)
    assert np.array_equal(ground.get_vertices(), cooked.get_vertices())
    assert np.array_equal(ground.get_triangles(), cooked.get_triangles())


DAMPED_SLIDER = """<mujoco><option timestep="0.002" gravity="0 0 -9.81"/>
  <worldbody><body name="arm" pos="0 0 1"><joint name="hinge" axis="0 1 0" damping="0.05"/>
    <geom type="capsule" fromto="0 0 0 .3 0 0" size=".02" mass=".4"/>
    <body name="slider" pos=".3 0 0"><joint name="slide" type="slide" axis="1 0 0" damping="0.2"/>
      <geom type="box" size=".03 .03 .03" mass=".2"/></body></body></worldbody>
  <actuator><position name="servo" joint="hinge" kp="4" kv="0.3"/></actuator>
</mujoco>"""
TERM_TOLERANCE = (
    1e-5  # rad over 0.5 s; measured 1.7e-7 to 2.6e-7, mutations 0.18 and 0.23 (mujoco 3.17.0, sapien 3.0.3)
)
PUSH = np.array([0.3, -0.5])  # N m on the hinge, N on the slide


def _lockstep(result, model, push: np.ndarray, steps: int = 250) -> float:
    """SAPIEN from `result`'s state and MuJoCo from the same, MuJoCo with `push` as qfrc_applied; the worst qpos
    difference over `steps` steps of a fixed ctrl."""
    data = mujoco.MjData(model)
    data.qfrc_applied[:] = push
    data.ctrl[:] = 0.4
    result.reset()
    worst = 0.0
    for _ in range(steps):
        result.set_ctrl(data.ctrl.copy())
        mujoco.mj_step(model, data)
        result.scene.step()
        worst = max(worst, float(np.abs(result.get_state()[0] - data.qpos).max()))
    return worst


def test_a_toy_term_joins_the_controller_through_the_public_contract(tmp_path):
    """A term of the caller's own, written against `loader.runtime.term.Term` and added with `Controller.add`:
    a constant generalized force, as MuJoCo's qfrc_applied. The controller compiles it and runs it after the
    actuators; `without` switches it off like any other. Mutation: the term left out (the push goes missing)."""
    from loader.runtime.term import Term

    class Push(Term):
        name = "push"

        def compile(self, compilation) -> None:
            self.flat = compilation.layout.flat_of([(0, 0), (0, 1)])

        def contribute(self, step) -> None:
            step.force[self.flat] += PUSH

    path = tmp_path / "slider.xml"
    path.write_text(DAMPED_SLIDER)
    result = MJCFLoader().load(path)
    model = mujoco.MjModel.from_xml_path(str(path))
    result.controller.add(Push(), after="actuators")
    assert result.controller.names.index("push") == result.controller.names.index("actuators") + 1
    assert _lockstep(result, model, PUSH) < TERM_TOLERANCE
    with result.controller.without("push"):
        assert _lockstep(result, model, PUSH) > 100 * TERM_TOLERANCE
    with pytest.raises(ValueError, match="already a stage"):
        result.controller.add(Push(), after="rows")


def test_model_edits_reach_the_steps_only_through_replan(tmp_path):
    """`result.model` is the caller's copy: doubling the servo's kp and the slide's damping in it changes nothing
    SAPIEN does until `replan()`, which then follows MuJoCo's run of the edited model. Mutation: the edit read
    without `replan` (the loaded model's run then misses it)."""
    path = tmp_path / "slider.xml"
    path.write_text(DAMPED_SLIDER)
    result = MJCFLoader().load(path)
    loaded = mujoco.MjModel.from_xml_path(str(path))
    edited = result.model
    edited.actuator_gainprm[0, 0] *= 2.0
    edited.actuator_biasprm[0, 1] *= 2.0
    edited.dof_damping[1] *= 3.0
    assert _lockstep(result, loaded, np.zeros(2)) < TERM_TOLERANCE  # the edit has not reached the steps
    assert _lockstep(result, edited, np.zeros(2)) > 100 * TERM_TOLERANCE
    result.replan()
    assert _lockstep(result, edited, np.zeros(2)) < TERM_TOLERANCE
    assert result.actuators[0].stiffness == pytest.approx(8.0)


LIMITED_ON_A_FLOOR = """<mujoco><option timestep="0.002"/><worldbody><geom type="plane" size="1 1 .1"/>
  <body pos="0 0 1"><joint axis="0 1 0" range="-20 20"/><geom type="capsule" fromto="0 0 0 .3 0 0" size=".02"/></body>
</worldbody></mujoco>"""


def test_replan_keeps_contacts_off_where_they_were_turned_off():
    """MuJoCo's limit rows are solved with MuJoCo's contacts only while SAPIEN has contacts; the terms `replan()`
    makes start with them on, so a result whose contacts were turned off hands that on to them. Mutation: the new
    rows told contacts are on (they would solve the limit rows against contacts PhysX no longer has)."""
    result = MJCFLoader().load(mujoco.MjSpec.from_string(LIMITED_ON_A_FLOOR))
    assert result.controller.term("rows").with_contacts
    result.set_contacts(False)
    result.replan()
    assert not result.controller.term("rows").with_contacts
    result.set_contacts(True)
    assert result.controller.term("rows").with_contacts


@pytest.mark.usefixtures("terms")
def test_a_timed_controller_sums_each_stages_seconds_and_stops_when_asked():
    result = MJCFLoader().load(str(FIXTURES.parent.parent / "corpus" / "fixtures" / "pendulum.xml"))
    controller = result.controller
    timings = controller.timed()
    for _ in range(3):
        result.set_ctrl(None)
        result.scene.step()
    running = {term.name for term in controller.running}  # the pendulum's idle actuators neither run nor settle
    assert set(timings) == running and all(t > 0 for t in timings.values())
    seen = dict(timings)
    controller.timed(False)
    result.set_ctrl(None)
    assert timings == seen and controller.timings is None  # no longer timed


# the mistake: the ellipsoid's sphere points made unique with np.unique(axis=0), whose first call imports numpy.ma
UNIQUE_BY_NUMPY = (
    "import numpy as np, loader.plan.geom as geom; points = geom.unit_sphere_points; "
    "geom.unit_sphere_points = lambda n=7: np.unique(points(n), axis=0); "
)


@pytest.mark.parametrize("mistake", [None, "unique_by_numpy"])
def test_a_cold_load_imports_no_module_beyond_its_own(mistake):
    """A fresh process that loads the corpus models with an ellipsoid (fish, swimmer, quadruped) imports nothing
    numpy keeps lazy: numpy.ma's import alone would be most of such a cold load's time beyond MuJoCo's compile.
    Mutation: the ellipsoid's sphere points made unique with np.unique(axis=0), which imports it."""
    import subprocess
    import sys

    paths = [str(suite_path(name)) for name in ("fish", "swimmer", "quadruped")]
    code = (
        "import sys, warnings; warnings.simplefilter('ignore'); import loader; "
        + (UNIQUE_BY_NUMPY if mistake else "")
        + "[loader.MJCFLoader().load(p) for p in sys.argv[1:]]; "
        "print(sorted(m for m in ('numpy.ma', 'scipy', 'trimesh') if m in sys.modules))"
    )
    done = subprocess.run([sys.executable, "-c", code, *paths], capture_output=True, text=True, check=True)
    assert (done.stdout.strip().splitlines()[-1] == "[]") == (mistake is None), done.stdout

"""Documents render to MJCF MuJoCo reads as intended, and saved counterexamples replay from their own folder."""

from __future__ import annotations

import tempfile
from pathlib import Path

import mujoco
import numpy as np
from hypothesis import given, settings

from conformance.fragments import DefaultClass, Document, Element, MeshAsset, write
from conformance.fragments.document import Body
from conformance.fragments.regressions import save_regression
from conformance.fragments.strategies import BOX_FACES, BREAKAGES, break_document, documents


def _box_mesh() -> MeshAsset:
    corners = [tuple((1 if i >> k & 1 else -1) * 0.1 + 0.05 for k in range(3)) for i in range(8)]
    return MeshAsset("m", corners, BOX_FACES, {"scale": "2 1 1"})


def _doc(split: bool) -> Document:
    main = DefaultClass(
        None,
        geom={"rgba": "0 1 0 1", "size": ".1 .2 .3", "type": "box"},
        children=[DefaultClass("a", joint={"damping": "3"})],
    )
    body = Body(
        "body",
        {"name": "b"},
        [
            Element("joint", {"name": "j", "class": "a"}),
            Element("geom", {"name": "g"}),
            Element("geom", {"name": "h", "type": "mesh", "mesh": "m"}),
        ],
    )
    return Document(defaults=main, split_main=split, meshes=[_box_mesh()], bodies=[body])


def test_main_split_over_two_default_blocks_compiles_like_one(tmp_path):
    one = mujoco.MjModel.from_xml_path(str(write(_doc(False), tmp_path / "one")))
    two = mujoco.MjModel.from_xml_path(str(write(_doc(True), tmp_path / "two")))
    assert _doc(True).render()[0].count("<default>") == 2
    for field in ("geom_size", "geom_rgba", "dof_damping", "mesh_vert"):
        np.testing.assert_array_equal(getattr(one, field), getattr(two, field))
    np.testing.assert_allclose(two.geom_size[0], (0.1, 0.2, 0.3))
    assert two.dof_damping[0] == 3


def test_mesh_scale_and_vertices_reach_mujoco(tmp_path):
    model = mujoco.MjModel.from_xml_path(str(write(_doc(False), tmp_path)))
    verts = model.mesh_vert[: model.mesh_vertnum[0]]
    # MuJoCo turns the mesh to its principal axes: compare the sorted extents of the 0.2 box scaled 2 along x
    np.testing.assert_allclose(np.sort(np.ptp(verts, axis=0)), (0.2, 0.2, 0.4), atol=1e-6)


def test_saved_counterexample_replays_beside_its_meshes(tmp_path):
    path = save_regression(_doc(False), "example", tmp_path)
    assert path.parent == tmp_path and path.name.startswith("example-")
    meshes = sorted(p.name for p in tmp_path.glob("*.obj"))
    assert meshes == [f"{path.stem}.m.obj"]
    model = mujoco.MjModel.from_xml_path(str(path))
    assert model.nmesh == 1 and model.ngeom == 2


@settings(max_examples=30, derandomize=True, deadline=None, database=None)
@given(documents())
def test_breakages_are_rejected_by_mujoco(document):
    with tempfile.TemporaryDirectory() as folder:
        try:
            mujoco.MjModel.from_xml_path(str(write(document, Path(folder) / "valid")))
        except ValueError:
            return  # the breakage must be what MuJoCo rejects, so start from a document it accepts
        for breakage in BREAKAGES:
            path = write(break_document(document, breakage), Path(folder) / breakage)
            try:
                mujoco.MjModel.from_xml_path(str(path))
            except ValueError:
                continue
            raise AssertionError(f"MuJoCo accepted the {breakage} breakage:\n{path.read_text()}")

"""The harness's reads of the SAPIEN scene (`conformance/sapien_side.py`)."""

from __future__ import annotations

import numpy as np
import pytest
from support.corpus import FIXTURES, suite_path

from conformance import sapien_side
from conformance.session import quiet_load

# several articulations and static actors (excluded_pair, world_geoms), one arm of many links (manipulator)
MODELS = [FIXTURES / "excluded_pair.xml", FIXTURES / "world_geoms.xml", suite_path("manipulator")]


def _stepped(path):
    """The model loaded, moved off its start and stepped, so that every link has a pose of its own."""
    result = quiet_load(str(path))
    rng = np.random.default_rng(0)
    q, v = result.get_state()
    result.set_state(q + 0.1 * rng.standard_normal(q.size) * (q.size > 0), v + rng.standard_normal(v.size))
    for _ in range(5):
        result.set_ctrl(None)
        result.scene.step()
    return result


@pytest.mark.parametrize("path", MODELS, ids=lambda p: p.stem)
def test_packed_link_poses_are_the_links_own_poses(path):
    """One packed read gives every link's `entity_pose`, bit for bit, in the order of `links`; the same read with
    the rows one entity off (a link read as its neighbour's entity) does not."""
    result = _stepped(path)
    read = sapien_side.LinkPoses(result)
    assert read.rows is not None  # the packed layout was recognised
    assert np.array_equal(read(), sapien_side.link_poses(result))
    read.rows = (read.rows + 1) % len(result.scene.entities)
    assert not np.array_equal(read(), sapien_side.link_poses(result))


def test_a_packing_of_another_layout_falls_back_to_each_links_pose(monkeypatch):
    """A packing whose size is not seven float32 per entity is not read: every read is then the per-link one."""
    result = _stepped(MODELS[0])
    monkeypatch.setattr(sapien_side.LinkPoses, "WIDTH", 8)
    read = sapien_side.LinkPoses(result)
    assert read.rows is None
    assert np.array_equal(read(), sapien_side.link_poses(result))

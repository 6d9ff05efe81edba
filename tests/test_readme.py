"""README's library example runs as written and does what it says: the panda, stepped from its "home" keyframe
under the keyframe's ctrl, where MuJoCo's own step of the same file puts it."""

from __future__ import annotations

import re
import runpy
from pathlib import Path

import mujoco
import numpy as np
import pytest
from support.corpus import menagerie_root

ROOT = Path(__file__).resolve().parents[1]
EXAMPLE_TOLERANCE = 1e-5  # rad; measured 1.1e-7 (mujoco 3.17.0, sapien 3.0.3)


def readme_example() -> str:
    """The first python block after README's "Library example" heading."""
    text = (ROOT / "README.md").read_text()
    section = text[text.index("## Library example") :]
    return re.search(r"```python\n(.*?)```", section, re.DOTALL).group(1)


@pytest.mark.skipif(menagerie_root() is None, reason="the Menagerie slice is not installed (the menagerie extra)")
def test_the_readme_library_example_runs_and_matches_mujoco(tmp_path):
    example = tmp_path / "example.py"
    example.write_text(readme_example())
    namespace = runpy.run_path(str(example))  # as a user pastes it into a file and runs it
    from conformance.corpus import where

    model = mujoco.MjModel.from_xml_path(str(where("panda")))
    data = mujoco.MjData(model)
    home = model.keyframe("home")
    mujoco.mj_resetDataKeyframe(model, data, home.id)
    for _ in range(10):
        mujoco.mj_step(model, data)
    error = np.abs(namespace["qpos"] - data.qpos).max()
    assert error < EXAMPLE_TOLERANCE, error
    assert np.abs(data.qpos - home.qpos).max() > 10 * EXAMPLE_TOLERANCE  # the example moved: not a test of rest

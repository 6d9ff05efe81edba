"""The harness's pool of MuJoCo data (conformance/data_pool.py): a lent data is the one `mujoco.MjData` would make,
two blocks never hold the same one, and the pool keeps the data of a bounded number of models."""

from __future__ import annotations

import mujoco
import numpy as np

from conformance import data_pool
from conformance.corpus import where


def _fields(data: mujoco.MjData) -> dict:
    out = {}
    for name in dir(data):
        if name.startswith("_"):
            continue
        value = getattr(data, name)
        if isinstance(value, np.ndarray):
            out[name] = value.copy()
    out["warnings"] = np.array([w.number for w in data.warning])
    return out


def test_a_borrowed_data_is_a_new_one_after_another_block_stepped_it():
    model = mujoco.MjModel.from_xml_path(str(where("humanoid")))
    with data_pool.borrowed(model) as used:
        used.qvel[:] = np.random.default_rng(0).standard_normal(model.nv)
        used.ctrl[:] = 0.3
        for _ in range(400):  # down onto the floor: contacts and their rows
            mujoco.mj_step(model, used)
        assert used.time > 0.0 and np.any(used.qpos != model.qpos0) and used.ncon > 0
    with data_pool.borrowed(model) as again:
        assert again is used  # reused, not made again
        lent = _fields(again)
    fresh = _fields(mujoco.MjData(model))
    assert lent.keys() == fresh.keys()
    differing = [name for name in fresh if not np.array_equal(lent[name], fresh[name], equal_nan=True)]
    assert not differing


def test_blocks_on_one_model_hold_different_data():
    model = mujoco.MjModel.from_xml_path(str(where("pendulum")))
    with data_pool.borrowed(model) as outer, data_pool.borrowed(model) as inner:
        assert inner is not outer
    with data_pool.borrowed(model) as first, data_pool.borrowed(model) as second:
        assert {id(first), id(second)} == {id(outer), id(inner)}  # both went back to the pool


def test_the_pool_keeps_the_data_of_a_bounded_number_of_models():
    models = [mujoco.MjModel.from_xml_path(str(where("pendulum"))) for _ in range(data_pool.MODELS + 1)]
    for model in models:
        with data_pool.borrowed(model):
            pass
    kept = [model for model in models if id(model) in data_pool._free]
    assert kept == models[1:]  # the least recently used model's data went first

"""MuJoCo data for the harness's short computations, reused instead of made again.

Making an `MjData` allocates MuJoCo's arena and costs a good fraction of a millisecond even for a two-body model;
resetting one (`mj_resetData`) costs microseconds and leaves every field as a new one has it. The harness makes a
data for every rollout, one-step comparison and static tier, thousands in a fuzz run, so `borrowed(model)` lends
one from a small per-process pool, reset, and takes it back when the block ends. A data is lent to one block at a
time; a block nested in another one on the same model gets a second data
(tests/test_conformance_data_pool.py).
"""

from __future__ import annotations

import threading
from collections import OrderedDict
from collections.abc import Iterator
from contextlib import contextmanager

import mujoco

MODELS = 8  # models whose free data the pool keeps (the least recently used model's go first)

_free: OrderedDict[int, tuple[mujoco.MjModel, list[mujoco.MjData]]] = OrderedDict()
_lock = threading.Lock()


@contextmanager
def borrowed(model: mujoco.MjModel) -> Iterator[mujoco.MjData]:
    """A data of `model` in the state `mujoco.MjData(model)` makes, for the block only."""
    with _lock:
        entry = _free.get(id(model))
        data = entry[1].pop() if entry is not None and entry[0] is model and entry[1] else None
    if data is None:
        data = mujoco.MjData(model)
    else:
        mujoco.mj_resetData(model, data)
    try:
        yield data
    finally:
        _give_back(model, data)


def _give_back(model: mujoco.MjModel, data: mujoco.MjData) -> None:
    with _lock:
        entry = _free.get(id(model))
        if entry is None or entry[0] is not model:  # a model gone and its id reused: its entry goes too
            entry = _free[id(model)] = (model, [])
        _free.move_to_end(id(model))
        entry[1].append(data)
        while len(_free) > MODELS:
            _free.popitem(last=False)

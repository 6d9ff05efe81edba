"""`nox -s bench` output: loader time against MuJoCo's compile time, and steps per second."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from conformance.bench import bench
from conformance.manifest import ModelEntry

ROOT = Path(__file__).resolve().parents[1]


def test_bench_writes_timings_per_model(tmp_path):
    entries = [ModelEntry(id="pendulum", source="fixture:fixtures/pendulum.xml", base_dir=str(ROOT / "corpus")),
               ModelEntry(id="missing", source="fixture:fixtures/nope.xml", base_dir=str(ROOT / "corpus"))]
    out = tmp_path / "bench.json"
    bench(entries, out, steps=50)
    doc = json.loads(out.read_text())
    row = doc["models"]["pendulum"]
    assert row["mujoco_compile_s"] > 0 and row["loader_load_s"] > 0
    assert row["load_over_compile"] == row["loader_load_s"] / row["mujoco_compile_s"]
    assert row["steps"] == 50 and row["harness_sapien_steps_per_s"] > 0 and row["harness_mujoco_steps_per_s"] > 0
    assert row["set_ctrl_over_step"] == pytest.approx(row["set_ctrl_us"] / row["physx_step_us"])
    assert "nope.xml" in doc["models"]["missing"]["skipped"]
    assert doc["versions"]["sapien"]

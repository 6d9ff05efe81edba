"""`nox -s bench` output: loader time against MuJoCo's compile time, cold and warm, and steps per second."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from conformance.bench import (
    COPIES,
    TARGET,
    TINY_BEYOND_S,
    TINY_COMPILE_S,
    batch_costs,
    bench,
    cold_seconds,
    over_target,
)
from conformance.manifest import ModelEntry

ROOT = Path(__file__).resolve().parents[1]


def test_bench_writes_timings_per_model(tmp_path):
    entries = [
        ModelEntry(id="pendulum", source="fixture:fixtures/pendulum.xml", base_dir=str(ROOT / "corpus")),
        ModelEntry(id="missing", source="fixture:fixtures/nope.xml", base_dir=str(ROOT / "corpus")),
    ]
    out = tmp_path / "bench.json"
    bench(entries, out, steps=50, repeats=2)
    doc = json.loads(out.read_text())
    assert doc["repeats"] == 2 and doc["target_load_over_compile"] == TARGET
    row = doc["models"]["pendulum"]
    for when in ("", "cold_"):  # warm (the plain names) and cold, each a median of positive times
        assert row[f"{when}mujoco_compile_s"] > 0 and row[f"{when}loader_load_s"] > 0
        assert row[f"{when}load_over_compile"] == row[f"{when}loader_load_s"] / row[f"{when}mujoco_compile_s"]
        assert row[f"{when}beyond_compile_s"] == row[f"{when}loader_load_s"] - row[f"{when}mujoco_compile_s"]
    assert row["steps"] == 50 and row["harness_sapien_steps_per_s"] > 0 and row["harness_mujoco_steps_per_s"] > 0
    assert row["set_ctrl_over_step"] == pytest.approx(row["set_ctrl_us"] / row["physx_step_us"])
    # the pendulum's hinges are MuJoCo's coordinates: its step drives them by default, the terms beside it
    assert row["law"] == "mujoco_step" and set(row["set_ctrl_stages_us"]) == {"mujoco_step", "controller"}
    # MuJoCo's own calls in that law, alone: the floor of set_ctrl on the CPU
    assert row["mujoco_pass_us"] > 0
    assert row["mujoco_pass_over_step"] == pytest.approx(row["mujoco_pass_us"] / row["physx_step_us"])
    terms = row["terms"]
    assert terms["set_ctrl_over_step"] == pytest.approx(terms["set_ctrl_us"] / terms["physx_step_us"])
    stages = terms["set_ctrl_stages_us"]  # the pendulum's limits are MuJoCo's rows; its drives always run
    assert {"rows", "drives", "controller"} <= set(stages) and all(stages[s] > 0 for s in ("rows", "drives"))
    assert list(stages)[:-1] == sorted(list(stages)[:-1], key=lambda s: -stages[s])  # costliest first
    batch = row["batch"]  # per copy at each batch size, MuJoCo's step per copy
    assert list(batch) == [str(n) for n in COPIES]
    for size in batch.values():
        assert size["set_ctrl_us_per_copy"] > 0 and size["physx_step_us_per_copy"] > 0
        assert size["set_ctrl_over_step"] == pytest.approx(
            size["set_ctrl_us_per_copy"] / size["physx_step_us_per_copy"]
        )
    # under the terms, the pendulum's stiffness and drives run once for all copies
    for size in batch_costs(str(ROOT / "corpus/fixtures/pendulum.xml"), 5, (1, 2), terms=True).values():
        assert {"stiffness", "drives"} <= set(size["batched_stages"])
    assert "nope.xml" in doc["models"]["missing"]["skipped"]
    assert doc["versions"]["sapien"]
    totals = doc["totals"]
    assert totals["models"] == 1  # the skipped model is not summed
    for key in ("mujoco_compile_s", "loader_load_s", "cold_mujoco_compile_s", "cold_loader_load_s"):
        assert totals[key] == pytest.approx(row[key])
    assert totals["harness_sapien_steps_per_s"] == pytest.approx(row["harness_sapien_steps_per_s"])
    assert totals["set_ctrl_over_step"] == pytest.approx(row["set_ctrl_over_step"])
    assert totals["mujoco_step"] == pytest.approx(
        {
            "models": 1,
            "set_ctrl_over_step": row["set_ctrl_over_step"],
            "terms_set_ctrl_over_step": terms["set_ctrl_over_step"],
            "mujoco_pass_over_step": row["mujoco_pass_over_step"],
        }
    )
    assert totals["batch_set_ctrl_over_step"] == pytest.approx({n: b["set_ctrl_over_step"] for n, b in batch.items()})
    for when, prefix in (("warm", ""), ("cold", "cold_")):
        assert totals["over_target"][when] == (["pendulum"] if over_target(row, prefix) else [])


def test_a_tiny_model_is_judged_by_its_time_beyond_the_compile():
    """A compile under `TINY_COMPILE_S` is judged by the milliseconds beyond it, any other by the ratio: a tiny model
    at five times its compile but within `TINY_BEYOND_S` meets its target; one past it, or a large model past the
    ratio, misses."""
    tiny = 0.2 * TINY_COMPILE_S
    row = {"mujoco_compile_s": tiny, "loader_load_s": 5 * tiny}
    row.update(load_over_compile=5.0, beyond_compile_s=4 * tiny)
    assert 4 * tiny < TINY_BEYOND_S and not over_target(row, "")
    row.update(loader_load_s=tiny + 1.01 * TINY_BEYOND_S, beyond_compile_s=1.01 * TINY_BEYOND_S)
    assert over_target(row, "")
    large = {"mujoco_compile_s": 0.1, "loader_load_s": 0.1 * 1.01 * TARGET, "load_over_compile": 1.01 * TARGET}
    large["beyond_compile_s"] = large["loader_load_s"] - 0.1
    assert over_target(large, "") and not over_target({**large, "load_over_compile": 0.99 * TARGET}, "")


def test_a_cold_measurement_that_fails_names_why():
    with pytest.raises(RuntimeError, match="cold load failed"):
        cold_seconds(str(ROOT / "corpus" / "fixtures" / "nope.xml"), "load")

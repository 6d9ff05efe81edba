"""The fuzz command's split of its examples over properties and worker processes."""

from __future__ import annotations

import re

import pytest

from conformance.fragments import Body, Document, Element, MeshAsset
from conformance.fragments.fuzz import divide, run, split
from conformance.fragments.regressions import save_regression
from conformance.fragments.strategies import TETRA_FACES


@pytest.mark.parametrize("workers", [1, 2, 3])
def test_workers_share_every_propertys_examples(workers):
    shares = split(2000, ["conformance", "error_parity", "kinematics", "robot_classes"])
    plans = divide(shares, workers)
    assert len(plans) == workers
    for name, share in shares.items():
        counts = [plan.get(name, 0) for plan in plans]
        assert sum(counts) == share and max(counts) - min(counts) <= 1, (name, counts)


def test_a_worker_without_examples_is_not_started():
    assert divide({"error_parity": 1}, 2) == [{"error_parity": 1}]


def test_two_workers_run_their_shares_and_the_tallies_add_up(tmp_path, monkeypatch, capsys):
    monkeypatch.setenv("FRAGMENTS_SAVE_REGRESSIONS", "0")  # inherited by the workers
    run(8, ["error_parity"], tmp_path / "db", workers=2)
    out = capsys.readouterr().out
    counted = int(re.search(r"fuzz: (\d+) examples in .* 2 worker\(s\)", out).group(1))
    rejected = int(re.search(r"rejected by MuJoCo: (\d+)", out).group(1))
    assert counted >= 8 and rejected == counted, out  # each worker also replays the corner cases MuJoCo rejects


def test_regressions_that_differ_only_in_a_mesh_get_different_files(tmp_path):
    def tetra(size: float) -> Document:
        mesh = MeshAsset("m", [(0, 0, 0), (size, 0, 0), (0, size, 0), (0, 0, size)], TETRA_FACES)
        body = Body(
            "body",
            {"name": "b"},
            [Element("joint", {"name": "j"}), Element("geom", {"name": "g", "type": "mesh", "mesh": "m"})],
        )
        return Document(meshes=[mesh], bodies=[body])

    small, large = save_regression(tetra(0.1), "p", tmp_path), save_regression(tetra(0.3), "p", tmp_path)
    assert small != large and save_regression(tetra(0.1), "p", tmp_path) == small

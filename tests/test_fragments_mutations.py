"""The properties catch a loader that ignores a class-resolved attribute.

Each mutation makes the loader read one attribute only where the element itself writes it, as a parser without
default classes would (falling back to MuJoCo's built-in default): geom `conaffinity` (1) or joint `armature`
(0). The generated documents put those attributes in default classes; the properties must fail."""

from __future__ import annotations

import dataclasses
import xml.etree.ElementTree as ET

import pytest

import loader.mjcf_loader
import loader.plan.contact
import loader.plan.tree
from conformance.fragments.fuzz import hypothesis_test, mutation_settings

EXAMPLES = 1000  # an upper bound: the run stops at the first failing document (about 1 in 60 draws catches
# the armature mutation: a hinge whose armature comes from a class, in a document the dynamic tiers judge)


class ClassBlind:
    """Remembers the document being loaded and answers what an element writes itself (no default classes)."""

    def __init__(self, monkeypatch):
        self.root = None
        compile_mjcf = loader.mjcf_loader.compile_mjcf

        def remembering(path, package_dir=None, dialect=False):
            self.root = ET.parse(path).getroot()
            return compile_mjcf(path, package_dir, dialect)

        monkeypatch.setattr(loader.mjcf_loader, "compile_mjcf", remembering)

    def written(self, tag: str, name: str, attribute: str) -> str | None:
        for element in self.root.iter(tag):
            if element.get("name") == name:
                return element.get(attribute)
        return None


@pytest.fixture
def blind(monkeypatch):
    monkeypatch.setenv("FRAGMENTS_SAVE_REGRESSIONS", "0")
    return ClassBlind(monkeypatch)


def _fails(name: str) -> str:
    with pytest.raises(AssertionError) as failure:
        hypothesis_test(name, mutation_settings(EXAMPLES), with_examples=False)()
    return str(failure.value)


def test_conaffinity_from_a_default_class_dropped_is_caught(blind, monkeypatch):
    groups = loader.plan.contact.CollisionFilter.groups

    def class_blind_groups(self, model, geom):
        out = groups(self, model, geom)
        written = blind.written("geom", model.geom(geom).name, "conaffinity")
        out[1] = int(written) if written is not None else 1
        return out

    monkeypatch.setattr(loader.plan.contact.CollisionFilter, "groups", class_blind_groups)
    message = _fails("conformance")
    assert "collision tier fails" in message and "groups" in message, message[:2000]


def test_armature_from_a_default_class_dropped_is_caught(blind, monkeypatch):
    plan_joint = loader.plan.tree.plan_joint

    def class_blind_plan(model, j, notes):
        written = blind.written("joint", model.joint(j).name, "armature")
        armature = float(written) if written is not None else 0.0
        return [dataclasses.replace(plan, armature=armature) for plan in plan_joint(model, j, notes)]

    monkeypatch.setattr(loader.plan.tree, "plan_joint", class_blind_plan)
    message = _fails("conformance")
    assert "dynamics tier fails" in message or "dynamics tier diverged" in message, message[:2000]

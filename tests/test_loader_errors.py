"""Bad input becomes one typed error that names the file, the line and what to do."""

from __future__ import annotations

import pytest
from models import FIXTURES

from loader import MissingAssetError, MJCFError, MJCFLoader


def test_missing_mesh_is_a_missing_asset_error_naming_the_file():
    with pytest.raises(MissingAssetError) as error:
        MJCFLoader().load(FIXTURES / "missing_mesh.xml")
    assert "no_such_mesh.stl" in str(error.value)
    assert error.value.file.endswith("missing_mesh.xml")


def test_malformed_xml_names_the_line():
    with pytest.raises(MJCFError) as error:
        MJCFLoader().load(FIXTURES / "malformed.xml")
    assert error.value.line is not None
    assert "malformed.xml" in str(error.value) and "fix:" in str(error.value)


def test_unknown_default_class_is_rejected_with_mujocos_message():
    with pytest.raises(MJCFError) as error:
        MJCFLoader().parse(FIXTURES / "unknown_class.xml")
    assert "nope" in error.value.mujoco_message
    assert error.value.line == 5 and error.value.element == "geom"


def test_a_path_that_is_not_a_file():
    with pytest.raises(MJCFError):
        MJCFLoader().load(FIXTURES / "does_not_exist.xml")

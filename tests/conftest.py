import numpy as np
import pytest

from conformance.session import quiet_load


@pytest.fixture(scope="module")
def load():
    """Load an MJCF file as the harness does (`conformance.session.quiet_load`), once per module."""
    cache = {}

    def _load(path, fix_root_link=True):
        key = (str(path), fix_root_link)
        if key not in cache:
            cache[key] = quiet_load(path, fix_root_link)
        return cache[key]

    return _load


@pytest.fixture
def rng():
    return np.random.default_rng(20261122)


@pytest.fixture
def terms(monkeypatch):
    """Every load in the test gives `set_ctrl`'s joint forces by the per-step terms (`MJCFLoader.set_ctrl_law =
    "terms"`): a test that judges a term's law, or breaks a term to show the test bites, on a model whose joint
    forces MuJoCo's own step gives by default."""
    from loader import MJCFLoader

    init = MJCFLoader.__init__

    def with_terms(self, *args, **kwargs):
        init(self, *args, **kwargs)
        self.set_ctrl_law = "terms"

    monkeypatch.setattr(MJCFLoader, "__init__", with_terms)

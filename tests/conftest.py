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

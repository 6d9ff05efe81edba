import sys
import warnings
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).parent))

from loader import MJCFLoader


@pytest.fixture(scope="module")
def load():
    """Load an MJCF file or string into a fresh CPU scene (warnings about approximations silenced)."""
    cache = {}

    def _load(path, fix_root_link=True):
        key = (str(path), fix_root_link)
        if key not in cache:
            loader = MJCFLoader(ignore_classes=[])
            loader.fix_root_link = fix_root_link
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                cache[key] = loader.load(path)
        return cache[key]

    return _load


@pytest.fixture
def rng():
    return np.random.default_rng(20261122)

import os

import pytest
from hypothesis import settings

from wbcbench.robots import load_robot

# the property tests draw the same examples on every run and machine (a result that changes between two runs of the
# same code is noise to whoever reads it); WBCBENCH_EXPLORE=1 draws new ones (and keeps the failures found)
settings.register_profile("reproducible", derandomize=True, database=None)
settings.register_profile("explore")
settings.load_profile("explore" if os.environ.get("WBCBENCH_EXPLORE") else "reproducible")


@pytest.fixture(scope="session")
def talos():
    return load_robot("talos")


@pytest.fixture(scope="session")
def g1():
    return load_robot("g1")


@pytest.fixture(scope="session", autouse=True)
def _render_model_cache(tmp_path_factory):
    """Rendering keeps its visual models in a cache directory: the session's own, not the user's."""
    import os

    old = os.environ.get("WBCBENCH_CACHE_DIR")
    os.environ["WBCBENCH_CACHE_DIR"] = str(tmp_path_factory.mktemp("cache"))
    yield
    if old is None:
        os.environ.pop("WBCBENCH_CACHE_DIR", None)
    else:
        os.environ["WBCBENCH_CACHE_DIR"] = old

import pytest

from wbcbench.robots import load_robot


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

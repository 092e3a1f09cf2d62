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
def one_line_exit_2():
    """The check of a command-line process that must fail as bad input does: exit 2, one line on stderr (no
    traceback), and that line naming each of `needles`. Usage: `one_line_exit_2(proc, *needles)`."""
    def check(proc, *needles):
        assert proc.returncode == 2, proc.stderr
        lines = proc.stderr.strip().splitlines()
        assert len(lines) == 1 and "Traceback" not in proc.stderr, proc.stderr
        for n in needles:
            assert n in lines[0], lines[0]
    return check


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

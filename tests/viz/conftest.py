import pytest

from wbcbench.runner import run


@pytest.fixture(scope="session")
def walk_run(tmp_path_factory):
    """3 s of the quick 20 cm walk with TSID torque: the CoM shifts, then the right foot lifts and moves (2.6 s)."""
    return run("walk-20cm-quick", "tsid-torque", duration=3.0, out=tmp_path_factory.mktemp("walk") / "run").run_dir

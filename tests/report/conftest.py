import pytest


@pytest.fixture(scope="package")
def two_runs(tmp_path_factory):
    """Two short run directories of the baseline controller: standing and swaying."""
    from wbcbench.runner import run

    root = tmp_path_factory.mktemp("runs")
    a, b = root / "stand-joint-pd", root / "sway-joint-pd"
    run("stand", "joint-pd", duration=0.3, out=a)
    run("sway", "joint-pd", duration=0.3, out=b)
    return a, b

import pytest

from wbcbench.runner import run


@pytest.fixture(scope="session")
def walk_run(tmp_path_factory):
    """3 s of the quick 20 cm walk with TSID torque: the CoM shifts, then the right foot lifts and moves (2.6 s)."""
    return run("walk-20cm-quick", "tsid-torque", duration=3.0, out=tmp_path_factory.mktemp("walk") / "run").run_dir


def bad_run_dirs(root, run_dir):
    """Two run directories the viewers must refuse: `root`/empty (no log) and `root`/corrupt (the config of
    `run_dir` beside a log that is not Parquet)."""
    empty = root / "empty"
    empty.mkdir()
    corrupt = root / "corrupt"
    corrupt.mkdir()
    (corrupt / "config.json").write_text((run_dir / "config.json").read_text())
    (corrupt / "log.parquet").write_bytes(b"PAR1 this is not parquet")
    return empty, corrupt

"""Command line: help lists what exists; bad input is one line on stderr with exit code 2."""

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from wbcbench.cli import main
from wbcbench.jit import JIT_ENABLED


def run_cli(*args):
    return subprocess.run([sys.executable, "-m", "wbcbench.cli", *args], capture_output=True, text=True)


def test_help_lists_scenarios_controllers_robots(capsys):
    with pytest.raises(SystemExit):
        main(["run", "--help"])
    out = capsys.readouterr().out
    for name in ("stand", "joint-pd", "talos", "g1", "spd"):
        assert name in out


def test_unknown_robot_lists_known_ones(one_line_exit_2):
    one_line_exit_2(run_cli("run", "stand", "-c", "joint-pd", "--robot", "atlas"), "atlas", "talos", "g1")


def test_unknown_controller_and_scenario(one_line_exit_2):
    one_line_exit_2(run_cli("run", "stand", "-c", "nope"), "nope", "joint-pd")
    one_line_exit_2(run_cli("run", "standing", "-c", "joint-pd"), "standing", "stand")


def test_malformed_profile_names_file_and_key(tmp_path: Path, one_line_exit_2):
    bad = tmp_path / "bad_robot.yaml"
    text = (Path(__file__).parents[1] / "wbcbench/robots/profiles/talos.yaml").read_text()
    bad.write_text(text.replace("length: 0.20", "length: -0.2"))
    one_line_exit_2(run_cli("run", "stand", "-c", "joint-pd", "--robot", str(bad)), str(bad), "sole.length", "> 0")
    bad.write_text(text.replace("torso_frame: torso_2_link", "torso_frame: torso_9_link"))
    one_line_exit_2(run_cli("run", "stand", "-c", "joint-pd", "--robot", str(bad)), "torso_9_link",
                    "torso_frame")
    bad.write_text(text + "\nunexpected_key: 1\n")
    one_line_exit_2(run_cli("run", "stand", "-c", "joint-pd", "--robot", str(bad)), "unexpected_key", "unknown key")
    bad.write_text("name: [unclosed\n")
    one_line_exit_2(run_cli("run", "stand", "-c", "joint-pd", "--robot", str(bad)), "invalid YAML")


def test_malformed_terrain_names_file_and_key(tmp_path: Path, one_line_exit_2):
    bad = tmp_path / "scene.yaml"
    bad.write_text("name: s\nkind: stand\nduration: 1\nterrain: {type: lava}\n")
    one_line_exit_2(run_cli("run", str(bad), "-c", "joint-pd"), str(bad), "terrain.type", "flat")
    bad.write_text("name: s\nkind: stand\nduration: 1\nterrain: {type: boxes, boxes: [{center: [0, 0], "
                   "size: [1, 1, 1]}]}\n")
    one_line_exit_2(run_cli("run", str(bad), "-c", "joint-pd"), "terrain.boxes[0].center", "3 values")
    bad.write_text("name: s\nkind: stand\nduration: 1\nterrain: {type: stairs, count: 3, height: -0.1, depth: 0.3}\n")
    one_line_exit_2(run_cli("run", str(bad), "-c", "joint-pd"), "terrain.height", "> 0")


def test_unsupported_mode(one_line_exit_2):
    one_line_exit_2(run_cli("run", "stand", "-c", "joint-pd", "--mode", "velocity"), "velocity", "torque")


def test_run_writes_a_run_directory(tmp_path: Path):
    out = tmp_path / "r"
    proc = run_cli("run", "stand", "-c", "joint-pd", "-d", "0.5", "-o", str(out), "-q")
    assert proc.returncode == 0, proc.stderr
    assert (out / "summary.json").exists() and (out / "log.parquet").exists() and (out / "config.json").exists()
    assert "completed" in proc.stdout


def test_unwritable_run_directory(tmp_path: Path, one_line_exit_2):
    blocker = tmp_path / "file"
    blocker.write_text("not a directory")
    proc = run_cli("run", "stand", "-c", "joint-pd", "--duration", "0.01", "--out", str(blocker / "run"))
    one_line_exit_2(proc, "--out", "cannot write the run directory", str(blocker / "run"))


def test_missing_taskset_file(tmp_path: Path, one_line_exit_2):
    proc = run_cli("run", "stand", "-c", "tsid-torque", "--duration", "0.01", "--taskset", str(tmp_path / "no.yaml"),
                   "--out", str(tmp_path / "r"))
    one_line_exit_2(proc, "--taskset", "no such file")


def test_existing_run_directory_is_not_overwritten_silently(tmp_path: Path, one_line_exit_2):
    out = tmp_path / "r"
    assert run_cli("run", "stand", "-c", "joint-pd", "--duration", "0.01", "--quiet", "--out", str(out)).returncode == 0
    one_line_exit_2(run_cli("run", "stand", "-c", "joint-pd", "--duration", "0.01", "--out", str(out)),
                    "already holds a run", "--overwrite")
    assert run_cli("run", "stand", "-c", "joint-pd", "--duration", "0.01", "--quiet", "--overwrite", "--out",
                   str(out)).returncode == 0


def test_ctrl_c_keeps_the_log_and_says_so(tmp_path: Path):
    import signal
    import time

    from wbcbench.recorder import read_log

    out = tmp_path / "r"
    proc = subprocess.Popen([sys.executable, "-m", "wbcbench.cli", "run", "walk-20cm", "-c", "tsid-torque", "--quiet",
                             "--out", str(out)], stderr=subprocess.PIPE, stdout=subprocess.PIPE, text=True,
                            # a shell that started the tests in the background leaves SIGINT ignored; a terminal's
                            # Ctrl-C reaches a process with the default disposition
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    deadline = time.time() + 300  # a loaded machine (the suite runs on every core) starts slowly
    while not (out / "log.parquet").exists() and time.time() < deadline:  # the first 1000 ticks are flushed
        time.sleep(0.2)
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 130, err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and "interrupted at t =" in lines[0] and "Traceback" not in err
    log = read_log(out / "log.parquet")
    import json
    summary = json.loads((out / "summary.json").read_text())
    assert summary["interrupted"] and len(log["t"]) >= 1000
    assert summary["sim_time_s"] == pytest.approx(log["t"][-1], abs=0.002) or summary["sim_time_s"] >= log["t"][-1]


def test_ctrl_c_inside_a_compiled_call_is_an_interruption_not_a_crash(talos, tmp_path: Path):
    """A Ctrl-C that lands while a compiled kernel calls back into the interpreter comes out of the kernel as a
    SystemError caused by the KeyboardInterrupt (seen under load in the test above): the run is interrupted, with
    its log and summary, not a controller crash."""
    import json

    from wbcbench.controllers.joint_pd import JointPD
    from wbcbench.runner import RunInterrupted, run
    from wbcbench.types import ActuationMode

    class Interrupted(JointPD):
        def step(self, meas, refs):
            if meas.t >= 0.05:
                try:
                    raise KeyboardInterrupt
                except KeyboardInterrupt as exc:
                    raise SystemError("a kernel returned a result with an exception set") from exc
            return super().step(meas, refs)

    out = tmp_path / "r"
    with pytest.raises(RunInterrupted, match="interrupted at t ="):
        run("stand", Interrupted(talos, ActuationMode.TORQUE, 0.001), talos, out=out, duration=0.2)
    summary = json.loads((out / "summary.json").read_text())
    assert summary["interrupted"] and not summary["fell"] and summary["fall_reason"] is None
    assert not (out / "error.txt").exists()
    assert 0.04 <= summary["sim_time_s"] <= 0.06


def test_full_disk_during_logging_is_one_line_and_keeps_the_log(tmp_path: Path, monkeypatch):
    """The disk fills after 2000 ticks: one WbcError naming the log and the time, the flushed ticks readable."""
    import errno

    from wbcbench.errors import WbcError
    from wbcbench.recorder import Recorder, read_log
    from wbcbench.runner import run

    real_flush = Recorder.flush
    calls = {"n": 0}

    def flaky_flush(self, *args, **kwargs):
        calls["n"] += 1
        if calls["n"] > 2:
            raise OSError(errno.ENOSPC, "No space left on device")
        return real_flush(self, *args, **kwargs)

    monkeypatch.setattr(Recorder, "flush", flaky_flush)
    real_init = Recorder.__init__  # row groups of 1000 ticks, whatever the default: the third group fails
    monkeypatch.setattr(Recorder, "__init__", lambda self, path, chunk=1000: real_init(self, path, 1000))
    with pytest.raises(WbcError, match="cannot write the log .*No space left on device.*kept") as err:
        run("stand", "joint-pd", duration=5.0, out=tmp_path / "r")
    assert "\n" not in str(err.value)
    log = read_log(tmp_path / "r" / "log.parquet")
    assert len(log["t"]) == 2000


def test_a_failed_background_write_is_raised_and_the_earlier_groups_kept(tmp_path: Path, monkeypatch):
    """Row groups are written in a thread: a write that fails there is raised by the next flush, in the run's
    thread, and the file keeps the groups written before it."""
    import errno

    import pyarrow.parquet as pq

    from wbcbench.recorder import Recorder, read_log

    rec = Recorder(tmp_path / "log.parquet", chunk=10)
    s = rec.add_channel("x")
    real_write = pq.ParquetWriter.write_table
    calls = {"n": 0}

    def flaky_write(self, table, *args, **kwargs):
        if self.where != rec.path:  # not the log (the recorder's warm-up writes a table in memory once)
            return real_write(self, table, *args, **kwargs)
        calls["n"] += 1
        if calls["n"] > 2:
            raise OSError(errno.ENOSPC, "No space left on device")
        return real_write(self, table, *args, **kwargs)

    monkeypatch.setattr(pq.ParquetWriter, "write_table", flaky_write)
    with pytest.raises(OSError, match="No space left"):
        for k in range(100):
            rec.row[s] = k
            rec.commit()
    assert calls["n"] == 3 and k == 39  # the third group failed in the thread; the fourth flush raised it
    with pytest.raises(OSError, match="No space left"):  # the disk is still full: the last rows cannot go
        rec.close()
    assert read_log(tmp_path / "log.parquet")["x"].tolist() == list(range(20))


def test_derived_columns_are_filled_per_row_group(tmp_path: Path):
    """`Recorder.derive`: a column computed from the others once per row group (in the writer thread) holds, in
    the file, the value of every row, the last partial group included; rows a tick left unwritten stay NaN; each
    group knows where it starts."""
    from wbcbench.recorder import Recorder, read_log

    rec = Recorder(tmp_path / "log.parquet", chunk=7)
    x, y, z = rec.add_channel("x"), rec.add_channel("y", ["a", "b"]), rec.add_channel("z")

    firsts = []

    def fill(block, first):
        firsts.append(first)
        block[:, y.start] = 2.0 * block[:, x.start]
        block[:, y.start + 1] = block[:, x.start] ** 2

    rec.derive(fill)
    for k in range(23):
        rec.row[x] = k
        if k % 2:
            rec.row[z] = -k
        rec.commit()
    rec.close()
    log = read_log(tmp_path / "log.parquet")
    k = np.arange(23.0)
    np.testing.assert_array_equal(log["y.a"], 2 * k)
    np.testing.assert_array_equal(log["y.b"], k ** 2)
    np.testing.assert_array_equal(np.isnan(log["z"]), k % 2 == 0)
    assert firsts == [0, 7, 14, 21]  # each group's first row in the log


@pytest.mark.skipif(not JIT_ENABLED, reason="the kernels run as plain Python (WBCBENCH_JIT=0)")
def test_the_first_row_readies_the_writers_compiled_pass(tmp_path: Path):
    """The log's first row runs the write path once (in memory): the compiled pass the writer thread uses is
    loaded then, for the argument types the writes have, so no row group loads or compiles one while a paced
    loop waits for the interpreter (that load held it for 12-30 ms at the first group)."""
    from wbcbench import recorder
    from wbcbench.recorder import Recorder, read_log

    rec = Recorder(tmp_path / "log.parquet", chunk=5)
    x = rec.add_channel("x", ["a", "b", "c"])
    rec.row[x] = 0.0
    loaded = set(recorder._columns_and_reset.signatures)
    assert recorder._warmed_up and loaded
    for k in range(12):
        rec.row[x] = k
        rec.commit()
    rec.close()
    assert set(recorder._columns_and_reset.signatures) == loaded  # the writes took the specialisation loaded
    np.testing.assert_array_equal(read_log(tmp_path / "log.parquet")["x.b"], np.arange(12.0))

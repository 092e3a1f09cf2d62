"""The teleop modules' former flat paths (wbcbench.teleop.<old>) give the modules at their new places."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def test_an_old_path_is_the_same_module_with_its_own_spec():
    # a fresh interpreter (in this one the modules may be imported already); warnings as errors: Python 3.12+ warns
    # at a relative import when the module's __spec__ and __package__ disagree
    code = ("import warnings; warnings.simplefilter('error')\n"
            "import wbcbench.teleop.commands as old, wbcbench.teleop.session.commands as new\n"
            "assert old is new, (old, new)\n"
            "assert new.__spec__.name == new.__name__ == 'wbcbench.teleop.session.commands', new.__spec__\n"
            "assert new.__spec__.parent == new.__package__, (new.__spec__.parent, new.__package__)\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT)
    assert out.returncode == 0, out.stderr

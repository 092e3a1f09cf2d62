"""`wbcbench sweep SWEEP.yaml`: run every cell of a design (wbcbench.study.design) into its own run directory and
collect one results table.

Layout of the output directory:
  manifest.json      the design (base, grid, random, every cell's id and parameters) and the code version
  cells/<id>/        the cell: scenario.yaml / taskset.yaml when overridden, run/ (a normal run directory),
                     cell.json (its results row; the cell's done marker), error.txt when it crashed
  results.parquet    one row per cell: param.* columns, every summary metric (flattened, `metrics.a.b`),
                     status (ok / fell / error), error, code_version
A killed sweep restarted with --resume runs only the cells without cell.json.
"""

from __future__ import annotations

import hashlib
import json
import shutil
import subprocess
from collections.abc import Callable
from pathlib import Path

import pyarrow as pa
import pyarrow.parquet as pq

from ..errors import ConfigError
from .cell import DONE_FILE, prepare, run_cell
from .design import Design, load_design
from .execute import Executor

RESULTS = "results.parquet"


def code_version() -> str:
    """`git describe --always --dirty` of the checkout holding wbcbench (else the package version), plus a hash
    of the package's .py and .yaml files."""
    import wbcbench

    root = Path(wbcbench.__file__).parent
    h = hashlib.sha1()
    for p in sorted(root.rglob("*")):
        if p.suffix in (".py", ".yaml") and "__pycache__" not in p.parts:
            h.update(str(p.relative_to(root)).encode())
            h.update(p.read_bytes())
    try:
        desc = subprocess.run(["git", "describe", "--always", "--dirty", "--tags"], cwd=root, capture_output=True,
                              text=True, timeout=10).stdout.strip()
    except (OSError, subprocess.SubprocessError):
        desc = ""
    if not desc:
        from importlib.metadata import PackageNotFoundError, version
        try:
            desc = version("wbcbench")
        except PackageNotFoundError:
            desc = "unknown"
    return f"{desc}+src.{h.hexdigest()[:10]}"


def validate_design(design: Design, scratch: Path) -> None:
    """Prepare one cell per (robot, scenario, controller, set of overridden keys) without running it, so an unknown
    key path or a bad value fails before any cell runs."""
    seen = set()
    for c in design.cells:
        sig = (c.get("robot"), c.get("scenario"), c.get("controller"), c.get("taskset"), str(c.get("realism")),
               c.get("engine"), c.get("mode"), tuple(sorted(c.params)))
        if sig in seen:
            continue
        seen.add(sig)
        try:
            prepare(c.params, scratch / c.id)
        except ConfigError as exc:
            raise ConfigError(f"cell {c.id}: {exc}", file=design.file) from None


def _table(rows: list[dict]) -> pa.Table:
    keys: list[str] = []
    for r in rows:
        keys += [k for k in r if k not in keys]
    cols = {}
    for k in keys:
        vals = [r.get(k) for r in rows]
        try:
            cols[k] = pa.array(vals)
        except (pa.ArrowInvalid, pa.ArrowTypeError, TypeError):
            cols[k] = pa.array([None if v is None else str(v) for v in vals])
    return pa.table(cols)


def write_results(out: Path, design: Design) -> pa.Table:
    rows = []
    for c in design.cells:
        f = out / "cells" / c.id / DONE_FILE
        if f.exists():
            rows.append(json.loads(f.read_text()))
    table = _table(rows)
    pq.write_table(table, out / RESULTS)
    return table


def run_sweep(sweep_file: str | Path, out: str | Path | None = None, executor: Executor | None = None,
              resume: bool = False, allow_large: bool = False,
              on_cell: Callable[[int, int, dict], None] | None = None) -> tuple[Path, pa.Table, int]:
    """Run the design into `out` (default sweeps/<file stem>); returns (out, results table, cells computed now).
    `on_cell(done, total, row)` is called after every finished cell."""
    design = load_design(sweep_file, allow_large=allow_large)
    out = Path(out) if out is not None else Path("sweeps") / Path(sweep_file).stem
    manifest_file = out / "manifest.json"
    version = code_version()
    manifest = {**design.manifest(), "code_version": version}
    if manifest_file.exists():
        old = json.loads(manifest_file.read_text())
        if not resume:
            raise ConfigError(f"{out} already holds a sweep; pass --resume to finish it or choose another --out",
                              key="--out")
        if [c["id"] for c in old["cells"]] != [c.id for c in design.cells]:
            raise ConfigError(f"{out} holds another design; --resume needs the same sweep file", key="--resume")
    validate_design(design, out / ".validate")
    shutil.rmtree(out / ".validate", ignore_errors=True)
    out.mkdir(parents=True, exist_ok=True)
    manifest_file.write_text(json.dumps(manifest, indent=1, default=str))
    todo = [c for c in design.cells if not (out / "cells" / c.id / DONE_FILE).exists()]
    done = len(design.cells) - len(todo)
    if on_cell is not None:
        on_cell(done, len(design.cells), {})
    executor = executor or Executor()
    kwargs = [{"params": c.params, "cell_dir": str((out / "cells" / c.id).resolve()), "code_version": version,
               "cell_id": c.id} for c in todo]
    for _, row in executor.map_unordered(run_cell, kwargs):
        done += 1
        if on_cell is not None:
            on_cell(done, len(design.cells), row)
    return out, write_results(out, design), len(todo)

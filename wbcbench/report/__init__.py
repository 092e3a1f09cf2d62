"""Reports: the paper's tables and figures with our numbers beside the published ones.

- `reproduce(out_dir, quick=False, jobs=None, progress=True)`: run the paper's matrix in parallel, write
  report.md / report.html / results.json / figures.
- `report(run_dirs, out_dir)`: the same from existing run directories, no simulation.
- `compare(run_a, run_b)`: two runs side by side.
- `paper`: the published numbers of paper 000, Tables 2-8 (`PAPER_TABLES`).
"""

from .compare import CompareRow, compare, compare_rows
from .paper import PAPER_CITATION, PAPER_TABLES, MetricSpec, PaperTable, paper_value
from .reproduce import ReportResult, report, reproduce, write_report
from .runs import ERROR, FELL, MISSING, OK, ReportError, RunOutcome, load_run

__all__ = [
    "ERROR",
    "FELL",
    "MISSING",
    "OK",
    "PAPER_CITATION",
    "PAPER_TABLES",
    "CompareRow",
    "MetricSpec",
    "PaperTable",
    "ReportError",
    "ReportResult",
    "RunOutcome",
    "compare",
    "compare_rows",
    "load_run",
    "paper_value",
    "report",
    "reproduce",
    "write_report",
]

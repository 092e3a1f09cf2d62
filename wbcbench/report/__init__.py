"""Reports: the paper's tables and figures with our numbers beside the published ones.

- `reproduce(out_dir, quick=False, jobs=None, progress=True)`: run the paper's matrix in parallel, write
  report.md / report.html / results.json / figures.
- `report(run_dirs, out_dir)`: the same from existing run directories, no simulation.
- `compare(run_a, run_b)`: two runs side by side.
- `paper`: the published numbers of paper 000, Tables 2-8 (`PAPER_TABLES`).
"""

from .._lazy import lazy_exports

# imported when first used, so that importing the package (or its `commands` module, for the command
# line's parser) stays light
__getattr__, __dir__ = lazy_exports(__name__, {
    **dict.fromkeys(("CompareRow", "compare", "compare_rows"), "compare"),
    **dict.fromkeys(("PAPER_CITATION", "PAPER_TABLES", "MetricSpec", "PaperTable", "paper_value"), "paper"),
    **dict.fromkeys(("ReportResult", "report", "reproduce", "write_report"), "reproduce"),
    **dict.fromkeys(("ERROR", "FELL", "MISSING", "OK", "ReportError", "RunOutcome", "load_run"), "runs"),
})

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

"""Studies: parameter sweeps over runs (design, execution on a process pool or Ray, results table, report)."""

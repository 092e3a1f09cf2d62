# Two commands on a fresh machine: `make run` (flagship comparison) and `make test`.
PY ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed

.PHONY: run test bench reproduce docs clean

$(STAMP): pyproject.toml
	test -x $(BIN)/python || $(PY) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e '.[test,docs,dart,c3d]'
	touch $(STAMP)

# The flagship comparison: the paper's controller x scenario matrix, shortened walks, with the report
# (reports/quick/report.md, report.html, results.json, figures/). `make reproduce` runs the full-length one.
run: $(STAMP)
	$(BIN)/wbcbench reproduce --quick --out reports/quick

reproduce: $(STAMP)
	$(BIN)/wbcbench reproduce --out reports/full

# the suite on every core (pytest-xdist); the tests of one file run in the same worker
test: $(STAMP)
	$(BIN)/python -m pytest -n auto --dist loadfile

# the documentation site into site/ (mkdocs.yml); --strict: a broken link or a missing reference fails the build
docs: $(STAMP)
	NO_MKDOCS_2_WARNING=1 $(BIN)/python -m mkdocs build --strict

bench: $(STAMP)
	$(BIN)/python benchmarks/bench_sim.py
	$(BIN)/python benchmarks/bench_controllers.py

clean:
	rm -rf $(VENV) runs reports site

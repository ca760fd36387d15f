# Shortcuts for developers; the README's two commands need nothing but Python and pip.
VENV := .venv
PY := $(VENV)/bin/python

.PHONY: paper test lint format diagrams results bench

$(PY):
	python3 -m venv $(VENV) && $(VENV)/bin/pip install -q -e '.[test]'

paper: $(PY)  ## the paper scenario: out/paper/{log.npz,metrics.json,error_summary.png,figures/}
	$(VENV)/bin/drake-uuv run

test: $(PY)
	$(PY) -m pytest

lint: $(PY)
	$(VENV)/bin/ruff check . && $(VENV)/bin/ruff format --check .

format: $(PY)
	$(VENV)/bin/ruff check --fix . && $(VENV)/bin/ruff format .

diagrams: $(PY)  ## regenerate diagrams/, the pictures the docs embed (needs Graphviz)
	$(PY) scripts/export_diagrams.py

bench: $(PY)
	$(PY) benchmarks/bench_loop.py

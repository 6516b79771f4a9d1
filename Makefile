# Every target bootstraps .venv/ first (Python >= 3.12, DOLFINx 0.11 from PyPI); idempotent.
PY := .venv/bin/python

.PHONY: bootstrap demo test test-all docs lint bench bench-compaction validate clean

bootstrap:
	@bash scripts/bootstrap.sh

demo: bootstrap  ## flagship demo on its embedded default case
	$(PY) demos/isotropic.py

# the serial tests on TEST_WORKERS pytest-xdist workers (one file per worker at a time: the
# module fixtures are built once; heaviest files first, tests/conftest.py), then the mpirun -n 2
# tests alone (their ranks must not share the cores)
TEST_WORKERS ?= auto
test: bootstrap  ## the CI suite (serial + mpirun -n 2), heavy cases excluded
	$(PY) -m pytest -n $(TEST_WORKERS) --dist loadfile --no-loadscope-reorder -m "not heavy and not mpi"
	$(PY) -m pytest -m "mpi and not heavy"

test-all: bootstrap  ## also the heavy cases
	$(PY) -m pytest -m ""

# the documentation site (Sphinx + MyST) -> docs/_build/html/index.html; any warning fails it
docs: bootstrap  ## the documentation site, built without warnings
	.venv/bin/sphinx-build -W --keep-going -b html docs docs/_build/html

lint: bootstrap  ## ruff: style, imports, docstrings (pyproject.toml [tool.ruff])
	$(PY) -m ruff check .

# the validation campaign, e.g. make validate STAGES="die dbc" JOBS=1 (JOBS cases at a time, one core each)
JOBS ?= 2
validate: bootstrap  ## the validation campaign: every stage's runs (hours), then validation/README.md tables
	$(PY) -m validation.run --jobs $(JOBS) $(STAGES)

bench: bootstrap
	$(PY) bench/material_assembly.py
	$(PY) bench/contact.py

# the compaction step benchmark (one JSON object), e.g.
#   make bench-compaction ARGS="--particles 350 --bc GDF --increments 40 --warmup 20 --steps 10" NP=2
ARGS ?= --particles 50 --bc CLP --increments 40 --warmup 20 --steps 20
bench-compaction: bootstrap
	$(if $(NP),.venv/bin/mpirun -n $(NP) )$(PY) bench/compaction.py $(ARGS)

clean:
	rm -rf results .pytest_cache docs/_build docs/_generated docs/_api
	find docs/demos -name "*.md" ! -name index.md -delete

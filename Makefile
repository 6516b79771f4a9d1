# Every target bootstraps .venv/ first (Python >= 3.12, DOLFINx 0.11 from PyPI); idempotent.
PY := .venv/bin/python

.PHONY: bootstrap demo test test-all bench clean

bootstrap:
	@bash scripts/bootstrap.sh

demo: bootstrap  ## flagship demo on its embedded default case
	$(PY) demos/isotropic.py

test: bootstrap  ## the CI suite (serial + mpirun -n 2), heavy cases excluded
	$(PY) -m pytest

test-all: bootstrap  ## also the heavy cases
	$(PY) -m pytest -m ""

bench: bootstrap
	$(PY) bench/material_assembly.py
	$(PY) bench/contact.py

clean:
	rm -rf results .pytest_cache

# Two commands on a fresh machine with python3, make and git: `make run` and `make test`.
VENV   := .venv
PY     := $(VENV)/bin/python
STAMP  := $(VENV)/.installed-stamp
OUT    := out/paper_table3
SPEEDUP ?= 1

.PHONY: install run plan sitl test lint bench sitl-bench clean

$(STAMP): pyproject.toml
	python3 -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -e '.[dev]'
	touch $(STAMP)

install: $(STAMP)

run: install
	$(VENV)/bin/gcs-ppf plan examples/paper_table3.json --out $(OUT)
	$(VENV)/bin/gcs-ppf demo examples/paper_table3.json --speedup $(SPEEDUP)

plan: install
	$(VENV)/bin/gcs-ppf plan examples/paper_table3.json --out $(OUT)

sitl: install
	$(PY) -m sitl examples/paper_table3.json

sitl-bench: install
	$(PY) -m sitl.benchmark

lint: install
	$(VENV)/bin/ruff check .
	$(VENV)/bin/ruff format --check .
	$(VENV)/bin/mypy

test: lint
	$(VENV)/bin/pytest

bench: install
	$(PY) -m gcs_ppf.offline.benchmark

clean:
	rm -rf $(VENV) out .pytest_cache .mypy_cache .ruff_cache

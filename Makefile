# Two commands on a fresh machine with python3, make and git: `make run` and `make test`.
VENV   := .venv
PY     := $(VENV)/bin/python
STAMP  := $(VENV)/.installed-stamp
KERNELS := $(VENV)/.kernels-stamp
SOURCES := $(shell find gcs_ppf -name '*.py')
OUT    := out/paper_table3
SPEEDUP ?= 1

# The lock: every version (runtime, the dev extra, pip and setuptools) with its hashes,
# resolved for every platform and Python >= 3.11. `make lock` refreshes it to the newest
# releases within pyproject.toml's ranges; `make lock LOCK_UPGRADE=` only adds what
# pyproject.toml asks for and the lock lacks, keeping every other pin.
LOCK   := requirements-lock.txt
UV_VERSION   := 0.13.9
LOCK_UPGRADE ?= --upgrade

.PHONY: install run plan sitl test lint bench sitl-bench clean lock chromium socat web-bench compose-check campaign-check mavproxy-check

# Exactly the locked set (pip refuses anything unpinned or with another hash), then gcs-ppf
# itself on top, editable, without dependencies, built by the locked setuptools; pip check
# fails if a runtime dependency in pyproject.toml is one the lock does not satisfy.
$(STAMP): pyproject.toml $(LOCK)
	python3 -m venv $(VENV)
	$(PY) -m pip install --quiet --require-hashes -r $(LOCK)
	$(PY) -m pip install --quiet --no-deps --no-build-isolation -e .
	$(PY) -m pip check
	touch $(STAMP)

# The compiled kernels built into numba's cache, again whenever a source file changed (a
# pull): otherwise the first run after it waited minutes for them, its vehicles flying on
# their last commands meanwhile. Seconds when the cache is still good.
$(KERNELS): $(STAMP) $(SOURCES)
	$(PY) -m gcs_ppf.service.kernels
	touch $(KERNELS)

install: $(STAMP) $(KERNELS) chromium socat

# Debian's chromium and chromium-driver for the operator's page tests (tests/web, skipped
# without them), with apt-get when either is missing (root, or sudo); otherwise nothing.
chromium:
	@if [ ! -x /usr/bin/chromium ] || [ ! -x /usr/bin/chromedriver ]; then \
	  SUDO=$$([ "$$(id -u)" = 0 ] || echo sudo); \
	  if command -v apt-get >/dev/null && $$SUDO apt-get update -qq && \
	    DEBIAN_FRONTEND=noninteractive $$SUDO apt-get install -y -qq chromium chromium-driver >/dev/null; \
	  then echo "installed chromium and chromium-driver"; \
	  else echo "chromium not installed: the browser tests (tests/web) will be skipped"; fi; \
	fi

# Debian's socat for the serial-radio tests (pseudo-terminal pairs; tests/integration/
# test_serial.py, skipped without it), the same way.
socat:
	@if ! command -v socat >/dev/null; then \
	  SUDO=$$([ "$$(id -u)" = 0 ] || echo sudo); \
	  if command -v apt-get >/dev/null && $$SUDO apt-get update -qq && \
	    DEBIAN_FRONTEND=noninteractive $$SUDO apt-get install -y -qq socat >/dev/null; \
	  then echo "installed socat"; \
	  else echo "socat not installed: the serial link tests will be skipped"; fi; \
	fi

# uv resolves (into the venv with pip, pinned); installing from the lock needs only pip.
lock:
	test -x $(PY) || python3 -m venv $(VENV)
	$(PY) -m pip install --quiet uv==$(UV_VERSION)
	$(VENV)/bin/uv pip compile pyproject.toml requirements-build.in --extra dev \
		--universal --python-version 3.11 --generate-hashes $(LOCK_UPGRADE) \
		--custom-compile-command 'make lock' --output-file $(LOCK) --quiet

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

# pytest in two passes, together exactly the tests `.venv/bin/pytest` alone runs: first
# those that only compute, spread over every core by pytest-xdist (PYTEST_WORKERS=0: in
# this process); then, one at a time with the machine to themselves as before, those that
# run against the wall clock (REALTIME: real processes, sockets, sleeps and deadlines).
# Both passes run even if the first fails; make fails if either did.
PYTEST_WORKERS ?= auto
REALTIME := integration or realtime or arduplane or mavproxy or docker
test: lint
	rc=0; \
	$(VENV)/bin/pytest -n $(PYTEST_WORKERS) -m "not campaign and not ($(REALTIME))" || rc=$$?; \
	$(VENV)/bin/pytest -m "not campaign and ($(REALTIME))" || rc=$$?; \
	exit $$rc

bench: install
	$(PY) -m gcs_ppf.offline.benchmark

# The reduced closed-loop campaign (Table 3 at x10 and on a lossy link, observer-checked),
# the service killed mid-run, the vehicles' fences, a radio unplugged, five vehicles on one
# UDP port, a loiter at a waypoint flown in formation: too slow for `make test`.
campaign-check: install
	$(VENV)/bin/pytest -m campaign tests/integration/test_campaign.py tests/integration/test_crash_recovery.py tests/integration/test_fences.py tests/integration/test_serial.py \
		tests/integration/test_service_sitl.py tests/integration/test_routes.py

# MAVProxy beside the service (tests/integration/test_mavproxy.py), from PyPI into a venv of
# its own: it pulls OpenCV, matplotlib and more, too heavy for the project's.
MAVPROXY_VENV    := .venv-mavproxy
MAVPROXY_VERSION := 1.8.75
$(MAVPROXY_VENV)/bin/mavproxy.py:
	python3 -m venv $(MAVPROXY_VENV)
	$(MAVPROXY_VENV)/bin/pip install --quiet MAVProxy==$(MAVPROXY_VERSION)

mavproxy-check: install $(MAVPROXY_VENV)/bin/mavproxy.py
	MAVPROXY=$(abspath $(MAVPROXY_VENV))/bin/mavproxy.py $(VENV)/bin/pytest -m mavproxy -s tests/integration/test_mavproxy.py

# The operator's page with 50 vehicles at 10 Hz in headless chromium: fps and JS heap
# (WEB_BENCH="--minutes 1" for a short run).
web-bench: install
	$(PY) -m tests.web.bench $(WEB_BENCH)

# docker-compose.yml built without a registry (a wheelhouse from the lock, a Debian base made by
# debootstrap), brought up, a mission flown through it over REST, brought down
# (scripts/compose-check.sh, docs/docker.md). FRESH=1: from an empty image store. Not part of
# `make test`: it needs a Docker engine (installed and started here when root with apt-get).
compose-check: install
	FRESH=$(FRESH) scripts/compose-check.sh

clean:
	rm -rf $(VENV) out .pytest_cache .mypy_cache .ruff_cache

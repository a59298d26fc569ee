# One image for both services of docker-compose.yml: the built-in SITL and the GCS.
#
# No stage needs the network: the dependencies come from a wheelhouse that the host
# downloads from the lock (`scripts/compose-check.sh wheelhouse`: `pip download
# --require-hashes -r requirements-lock.txt -d .wheelhouse`) and are installed with
# `--no-index --find-links`, every file checked against the lock's hashes. BASE is any
# image with Python 3.11+ and its venv module: python:3.11-slim where a registry is
# reachable, or a Debian made by debootstrap and `docker import` where none is
# (`scripts/compose-check.sh base`; docs/docker.md).
ARG BASE=python:3.11-slim

FROM ${BASE} AS build
# A virtual environment of its own: Debian's python3 refuses installs into the system's
# site-packages (PEP 668), and the runtime stage takes the whole environment at once.
RUN python3 -m venv /opt/venv
ENV PATH=/opt/venv/bin:$PATH
COPY .wheelhouse /wheelhouse
COPY requirements-lock.txt /app/
# Exactly the locked set (as `make install`: every version pinned with its hashes), then
# gcs-ppf itself on top without dependencies, built by the locked setuptools.
RUN pip install --no-cache-dir --no-index --find-links /wheelhouse \
        --require-hashes -r /app/requirements-lock.txt
WORKDIR /app
COPY pyproject.toml README.md ./
COPY gcs_ppf ./gcs_ppf
COPY sitl ./sitl
COPY api ./api
RUN pip install --no-cache-dir --no-index --no-deps --no-build-isolation . && pip check

FROM ${BASE}
COPY --from=build /opt/venv /opt/venv
ENV PATH=/opt/venv/bin:$PATH PYTHONUNBUFFERED=1
WORKDIR /app
COPY examples ./examples
# The planner's and the assurance's kernels compiled into numba's cache now, so that no
# container waits 1-2 min for them at its first run.
RUN python -m gcs_ppf.service.kernels
CMD ["gcs-ppf", "--help"]

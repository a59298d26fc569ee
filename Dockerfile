# One image for both services of docker-compose.yml: the built-in SITL and the GCS.
FROM python:3.11-slim
WORKDIR /app
# Exactly the locked set (as `make install`: every version pinned with its hashes), then
# gcs-ppf itself on top without dependencies, built by the locked setuptools.
COPY requirements-lock.txt ./
RUN pip install --no-cache-dir --require-hashes -r requirements-lock.txt
COPY pyproject.toml README.md ./
COPY gcs_ppf ./gcs_ppf
COPY sitl ./sitl
COPY api ./api
COPY examples ./examples
RUN pip install --no-cache-dir --no-deps --no-build-isolation . && pip check
ENV PYTHONUNBUFFERED=1
CMD ["gcs-ppf", "--help"]

# One image for both services of docker-compose.yml: the built-in SITL and the GCS.
FROM python:3.11-slim
WORKDIR /app
COPY pyproject.toml README.md ./
COPY gcs_ppf ./gcs_ppf
COPY sitl ./sitl
COPY api ./api
COPY examples ./examples
RUN pip install --no-cache-dir .
ENV PYTHONUNBUFFERED=1
CMD ["gcs-ppf", "--help"]

"""REST and WebSocket API of the gcs-ppf service (FastAPI)."""

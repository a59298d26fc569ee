"""Requests the service cannot honour, with the HTTP status that fits (``api/`` maps them)."""

from __future__ import annotations

from typing import Any


class ServiceError(Exception):
    """A request the service cannot honour; ``status`` is the HTTP status that fits."""

    status = 400

    def __init__(self, message: str, detail: dict[str, Any] | None = None) -> None:
        super().__init__(message)
        self.message = message
        self.detail = detail or {}


class NotFound(ServiceError):
    status = 404


class Conflict(ServiceError):
    status = 409


class Forbidden(ServiceError):
    status = 403


class Unprocessable(ServiceError):
    """A document that cannot be read as asked (the message names the field)."""

    status = 422


class TooLarge(ServiceError):
    status = 413

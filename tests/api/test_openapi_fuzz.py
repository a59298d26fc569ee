"""Schemathesis over the app's own OpenAPI schema: no request may cause a server error."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
import schemathesis
from fastapi.testclient import TestClient
from hypothesis import settings
from schemathesis.checks import not_a_server_error

from api.app import create_app
from gcs_ppf.service.settings import Settings

_app = create_app(Settings(db=Path(":memory:"), tlog_dir=None))
schema = schemathesis.openapi.from_asgi("/openapi.json", _app)


@pytest.fixture(scope="module")
def client() -> Iterator[TestClient]:
    with TestClient(_app) as c:  # runs the lifespan: store and service up
        yield c


@schema.parametrize()
@settings(max_examples=25, deadline=None)
def test_no_server_errors(case: schemathesis.Case[Any], client: TestClient) -> None:
    response = case.call(session=client)
    case.validate_response(response, checks=[not_a_server_error])

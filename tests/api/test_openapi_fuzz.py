"""Schemathesis over the app's own OpenAPI schema: no request may cause a server error."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
import schemathesis
from fastapi.testclient import TestClient
from hypothesis import HealthCheck, settings
from schemathesis.checks import not_a_server_error
from schemathesis.config import SchemathesisConfig
from schemathesis.specs.openapi.checks import positive_data_acceptance

from api.app import create_app
from gcs_ppf.service.settings import Settings
from gcs_ppf.tokens import new_token

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


# The same with API tokens: with a command token no request causes a server error; without
# one, every request but /health is refused (401), whatever its body or parameters.
TOKEN, ENTRY = new_token("fuzz")
_secured_settings = Settings(db=Path(":memory:"), tlog_dir=None, tokens=[ENTRY])
_secured = create_app(_secured_settings)
# A schema-violating request is rejected with schemathesis's own list of statuses, or 413: a
# body over ``max_body_bytes`` (10,001 obstacles, say, past the schema's maxItems) is
# refused by its size before anything reads it.
_DEFAULTS = SchemathesisConfig().projects.default.checks.negative_data_rejection
_REJECTED = [*_DEFAULTS.expected_statuses, "413"]
_checks = {"checks": {"negative_data_rejection": {"expected-statuses": _REJECTED}}}
secured_schema = schemathesis.openapi.from_asgi(
    "/openapi.json", _secured, config=SchemathesisConfig.from_dict(_checks)
)


@pytest.fixture(scope="module")
def secured_client() -> Iterator[TestClient]:
    with TestClient(_secured) as c:
        yield c


@secured_schema.parametrize()
@settings(max_examples=25, deadline=None)
def test_no_server_errors_with_a_token(
    case: schemathesis.Case[Any], secured_client: TestClient
) -> None:
    response = case.call(session=secured_client, headers={"Authorization": f"Bearer {TOKEN}"})
    case.validate_response(response, checks=[not_a_server_error])


@secured_schema.parametrize()
@settings(max_examples=10, deadline=None)
def test_nothing_but_health_without_a_token(
    case: schemathesis.Case[Any], secured_client: TestClient
) -> None:
    response = case.call(session=secured_client)
    if response.status_code == 405:  # schemathesis also tries methods a path does not have
        assert case.method.lower() not in _secured.openapi()["paths"][case.path]
    elif case.path == "/health":
        assert response.status_code == 200
    else:
        assert response.status_code in (400, 401, 413, 422), (case.method, case.path)
        if response.status_code == 413:  # the body-size guard runs before anything reads it
            sent = response.request.headers.get("content-length", "0")
            assert int(sent) > _secured_settings.max_body_bytes, sent
        if response.status_code != 401:  # FastAPI parses a body before it looks at the token:
            assert case.body is not None  # one that is not JSON is refused first (400/422)
            assert "detail" in response.json()


class SecuredMachine(secured_schema.as_state_machine()):  # type: ignore[misc]
    """Stateful: sequences of calls (a mission stored, then read, started, its obstacles
    replaced …) with the command token, every check of schemathesis but one:
    ``positive_data_acceptance`` (a schema-valid request must not be refused) does not hold
    for this API by design — the service refuses with 400/409 what only it can judge (a link
    URL's scheme, a keep-out around a vehicle, a start without vehicles)."""

    client: TestClient

    def setup(self) -> None:
        """Each scenario against a service of its own: Hypothesis replays a scenario to
        shrink it, and one that met the missions and runs an earlier scenario left behind
        would get other answers, follow other links, and draw differently
        (``FlakyStrategyDefinition``)."""
        self._client = TestClient(create_app(_secured_settings))
        self.client = self._client.__enter__()

    def teardown(self) -> None:
        self._client.__exit__(None, None, None)

    def get_call_kwargs(self, case: schemathesis.Case[Any]) -> dict[str, Any]:
        return {"session": self.client, "headers": {"Authorization": f"Bearer {TOKEN}"}}

    def validate_response(
        self,
        response: Any,
        case: schemathesis.Case[Any],
        additional_checks: list[Any] | None = None,
        **kwargs: Any,
    ) -> None:
        case.validate_response(
            response,
            additional_checks=additional_checks,
            excluded_checks=[positive_data_acceptance],
            transport_kwargs=kwargs or None,
            recorder=self.recorder,
        )


def test_stateful_with_a_token_all_checks() -> None:
    SecuredMachine.run(
        settings=settings(
            max_examples=30,
            deadline=None,
            stateful_step_count=6,
            suppress_health_check=list(HealthCheck),
        )
    )

"""docker-compose.yml really run: the two containers up, the service discovers the SITL's five
vehicles, a mission flown through it over REST to completion, and both containers down again
within seconds (SIGTERM ends them; they do not wait out the stop timeout).

Needs a Docker engine and the image built (``make compose-check`` builds it without a
registry and runs this test, docs/docker.md); skipped unless ``GCS_PPF_DOCKER=1``, so that
``make test`` neither waits for Docker nor needs it.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import time
from collections.abc import Iterator
from typing import Any

import pytest

from gcs_ppf.tokens import entries_json, new_token
from gcs_ppf.tools.demo import FINISHED, http_json
from gcs_ppf.tools.observer import free_port_block
from tests.checks import wait_for
from tests.conftest import EXAMPLES, ROOT

pytestmark = [
    pytest.mark.docker,
    pytest.mark.skipif(
        os.environ.get("GCS_PPF_DOCKER") != "1",
        reason="needs a Docker engine: GCS_PPF_DOCKER=1 (make compose-check)",
    ),
]

PROJECT = "gcs-ppf-check"
SPEEDUP = 10
STOP_S = 5.0  # `down` of both containers; a container that ignores SIGTERM takes 10 s
# docker-compose.yml serves on 0.0.0.0 in its container: it needs GCS_PPF_TOKENS
TOKEN, ENTRY = new_token("compose-check")


def http(method: str, url: str, body: Any = None) -> tuple[int, Any]:
    return http_json(method, url, body, token=TOKEN)


def compose_command() -> list[str]:
    """``docker compose`` where the plugin is there, else ``docker-compose``."""
    plugin = subprocess.run(["docker", "compose", "version"], capture_output=True, check=False)
    if plugin.returncode == 0:
        return ["docker", "compose", "-p", PROJECT]
    if shutil.which("docker-compose") is None:
        pytest.fail("neither `docker compose` nor `docker-compose` is installed")
    return ["docker-compose", "-p", PROJECT]


def vehicle_ids(api: str) -> list[int] | None:
    try:
        status, vehicles = http("GET", f"{api}/vehicles")
    except OSError:
        return None
    return sorted(v["system_id"] for v in vehicles) if status == 200 else None


def finished(api: str, mid: int) -> dict[str, Any] | None:
    try:
        status, s = http("GET", f"{api}/missions/{mid}/status")
    except OSError:
        return None
    return s if status == 200 and s["state"] in FINISHED else None


@pytest.fixture
def stack() -> Iterator[tuple[list[str], dict[str, str], str]]:
    """The compose project up (detached, without building); taken down however the test ends."""
    port = free_port_block(1)
    env = {
        **os.environ,
        "GCS_PPF_PORT": str(port),
        "GCS_PPF_SITL_SPEEDUP": str(SPEEDUP),
        "GCS_PPF_TOKENS": entries_json([ENTRY]),
    }
    compose = compose_command()
    subprocess.run([*compose, "down", "--volumes"], cwd=ROOT, env=env, check=False)
    try:
        subprocess.run([*compose, "up", "-d", "--no-build"], cwd=ROOT, env=env, check=True)
        yield compose, env, f"http://127.0.0.1:{port}"
    finally:
        logs = subprocess.run(
            [*compose, "logs", "--no-color", "--tail=40"],
            cwd=ROOT,
            env=env,
            capture_output=True,
            text=True,
            check=False,
        )
        print(logs.stdout)
        subprocess.run([*compose, "down", "--volumes"], cwd=ROOT, env=env, check=False)


def test_compose_serves_the_vehicles_and_flies_a_mission(
    stack: tuple[list[str], dict[str, str], str],
) -> None:
    compose, env, api = stack
    started = time.monotonic()
    mission = json.loads((EXAMPLES / "paper_table3.json").read_text())
    expected = sorted(v["id"] for v in mission["vehicles"])
    ids = wait_for(lambda: vehicle_ids(api) == expected or None, 120, "the five vehicles")
    assert ids
    print(f"\ncompose up: /vehicles lists {expected} {time.monotonic() - started:.1f} s after up")

    assert http_json("GET", f"{api}/vehicles")[0] == 401  # without the token
    status, created = http("POST", f"{api}/missions", mission)
    assert status == 201, created
    mid = created["id"]
    status, body = http("POST", f"{api}/missions/{mid}/start")
    assert status == 202, body
    flown = time.monotonic()
    final = wait_for(lambda: finished(api, mid), 300, "the mission to finish", every_s=1.0)
    assert final["state"] == "completed", final
    print(
        f"mission {final['state']} in {final['mission_time_s']:.1f} s of mission time, "
        f"{time.monotonic() - flown:.1f} s wall (SITL x{SPEEDUP})"
    )

    stopping = time.monotonic()
    subprocess.run([*compose, "stop"], cwd=ROOT, env=env, check=True)
    stop_s = time.monotonic() - stopping
    print(f"compose stop: {stop_s:.1f} s")
    assert stop_s < STOP_S

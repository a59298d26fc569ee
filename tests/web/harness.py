"""Headless chromium (Debian's ``chromium`` and ``chromium-driver``, driven by selenium) and
the service and SITL as real processes, for the page's tests and its benchmark."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import tempfile
import urllib.error
import urllib.request
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path
from typing import Any

from selenium import webdriver
from selenium.webdriver.chrome.service import Service as ChromeService
from selenium.webdriver.chrome.webdriver import WebDriver

from gcs_ppf.tools.campaign import process, stop
from gcs_ppf.tools.observer import free_port
from tests.checks import wait_for

__all__ = ["free_port", "process", "stop", "wait_for"]  # with the rest below, for the page's tests

ROOT = Path(__file__).resolve().parents[2]
CHROMIUM = os.environ.get("GCS_PPF_CHROMIUM", "/usr/bin/chromium")
CHROMEDRIVER = os.environ.get("GCS_PPF_CHROMEDRIVER", "/usr/bin/chromedriver")
ARTIFACTS = Path(os.environ.get("GCS_PPF_TEST_ARTIFACTS", ROOT / "out" / "test-artifacts" / "web"))
CHROMIUM_FLAGS = (
    "--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
    "--disable-background-networking", "--disable-component-update", "--disable-sync",
)  # fmt: skip


def chromium_missing() -> str | None:
    """Why the browser tests cannot run here, or None."""
    missing = [p for p in (CHROMIUM, CHROMEDRIVER) if shutil.which(p) is None]
    if missing:
        return (f"{' and '.join(missing)} not found: `make install` installs Debian's chromium "
                "and chromium-driver with apt-get (it needs root)")  # fmt: skip
    return None


@contextmanager
def browser(
    width: int = 1280, height: int = 720, extra: tuple[str, ...] = ()
) -> Iterator[WebDriver]:
    """A fresh headless chromium (own profile directory) at ``width`` × ``height``."""
    options = webdriver.ChromeOptions()
    options.binary_location = CHROMIUM
    for flag in (*CHROMIUM_FLAGS, f"--window-size={width},{height}", *extra):
        options.add_argument(flag)
    with tempfile.TemporaryDirectory(prefix="gcs-ppf-chromium-") as profile:
        options.add_argument(f"--user-data-dir={profile}")
        options.set_capability("goog:loggingPrefs", {"browser": "ALL"})
        driver = webdriver.Chrome(options=options, service=ChromeService(CHROMEDRIVER))
        try:
            yield driver
        finally:
            driver.quit()


def page_errors(driver: WebDriver) -> list[str]:
    """The page's JavaScript errors so far (console SEVERE entries, not failed requests)."""
    return [
        str(e["message"]) for e in driver.get_log("browser")  # type: ignore[no-untyped-call]
        if e["level"] == "SEVERE" and e.get("source") != "network"
    ]  # fmt: skip


def serve_args(port: int, db: Path, links: Sequence[str] = ()) -> list[str]:
    args = [sys.executable, "-m", "gcs_ppf.cli", "serve", "--port", str(port), "--db", str(db)]
    for url in links:
        args += ["--link", url]
    return args


def http(method: str, url: str, body: Any = None, token: str | None = None) -> tuple[int, Any]:
    """One JSON request (with ``token`` as its bearer, if any); (status, decoded body)."""
    data = None if body is None else json.dumps(body).encode()
    headers = {"Content-Type": "application/json"}
    if token is not None:
        headers["Authorization"] = f"Bearer {token}"
    request = urllib.request.Request(url, data=data, method=method, headers=headers)
    try:
        with urllib.request.urlopen(request, timeout=10) as r:
            raw = r.read()
            return r.status, json.loads(raw) if raw else None
    except urllib.error.HTTPError as e:
        raw = e.read()
        return e.code, json.loads(raw) if raw else None


def up(api: str) -> bool:
    try:
        return http("GET", f"{api}/health")[0] == 200
    except OSError:
        return False


def wait_serving(api: str, p: subprocess.Popen[bytes], log: Path, timeout_s: float = 90) -> None:
    """Until the service at ``api`` answers; fails at once, with its log, if it exited."""

    def ready() -> bool:
        if p.poll() is not None:
            raise AssertionError(f"the service exited ({p.returncode}):\n{log.read_text()[-3000:]}")
        return up(api)

    try:
        wait_for(ready, timeout_s, "the service")
    except AssertionError as exc:
        raise AssertionError(f"{exc}\n{log.read_text()[-3000:]}") from None


def screenshot(driver: WebDriver, name: str) -> Path:
    ARTIFACTS.mkdir(parents=True, exist_ok=True)
    path = ARTIFACTS / f"{name}.png"
    driver.save_screenshot(str(path))
    return path

"""The operator's page against a service with API tokens: it asks for a token once (or takes
it from ``/#token=…``), then reads, streams and commands with it."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from selenium.webdriver.chrome.webdriver import WebDriver
from selenium.webdriver.common.by import By
from selenium.webdriver.support import expected_conditions
from selenium.webdriver.support.ui import WebDriverWait

from gcs_ppf.tokens import add_to_token_file, new_token
from tests.web.harness import (
    ROOT,
    browser,
    free_port,
    http,
    page_errors,
    process,
    serve_args,
    wait_for,
    wait_serving,
)

MISSION = ROOT / "examples" / "paper_table3.json"


def text(driver: WebDriver, element_id: str) -> str:
    return str(driver.find_element(By.ID, element_id).text)


@pytest.mark.integration
def test_the_page_asks_for_a_token_once_and_works_with_it(tmp_path: Path) -> None:
    token, entry = new_token("operator")
    tokens = tmp_path / "tokens.json"
    add_to_token_file(tokens, entry)
    port = free_port()
    api = f"http://127.0.0.1:{port}"
    log = tmp_path / "gcs.log"
    args = [*serve_args(port, tmp_path / "gcs.db"), "--token-file", str(tokens)]
    with process(args, log) as gcs, browser() as driver:
        wait_serving(api, gcs, log)
        assert http("GET", f"{api}/missions")[0] == 401
        driver.get(f"{api}/")
        # the page's first request is refused: it asks (once, however many requests wait)
        alert = WebDriverWait(driver, 20).until(expected_conditions.alert_is_present())
        assert "needs a token" in alert.text
        alert.send_keys(token)
        alert.accept()
        wait_for(lambda: text(driver, "conn") == "connected", 20, "the page's stream")
        driver.find_element(By.ID, "file-input").send_keys(str(MISSION))
        wait_for(lambda: "stored as mission #1" in text(driver, "load-message"), 20, "the mission")
        assert (
            driver.execute_script("return window.sessionStorage.getItem('gcs-ppf-token')") == token
        )
        # a reload keeps it (sessionStorage): no second prompt, the stream connects again
        driver.refresh()
        wait_for(lambda: text(driver, "conn") == "connected", 20, "the stream after a reload")
        assert page_errors(driver) == []

    # the token in the address's fragment: no prompt, and the fragment is removed
    with process(args, tmp_path / "gcs2.log") as gcs, browser() as driver:
        wait_serving(api, gcs, tmp_path / "gcs2.log")
        driver.get(f"{api}/#token={token}")
        wait_for(lambda: text(driver, "conn") == "connected", 20, "the page's stream")
        assert "token" not in driver.current_url
    audit = [json.loads(line) for line in (tmp_path / "gcs.audit.jsonl").read_text().splitlines()]
    assert [(a["method"], a["path"], a["token_id"], a["status"]) for a in audit] == [
        ("POST", "/missions", "operator", 201)
    ]

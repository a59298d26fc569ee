"""The operator's page in headless chromium against the real service and the built-in SITL,
the service with an API token as it is deployed (the page takes it from ``/#token=…``;
``test_token.py`` covers the prompt for one).

Screenshots (planning, mid-run, replay) go to ``out/test-artifacts/web/``
(``GCS_PPF_TEST_ARTIFACTS`` to change it).
"""

from __future__ import annotations

import json
import math
import re
import sys
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pytest
from pymavlink import mavutil
from selenium.webdriver.chrome.webdriver import WebDriver
from selenium.webdriver.common.action_chains import ActionChains
from selenium.webdriver.common.by import By
from selenium.webdriver.remote.webelement import WebElement

from gcs_ppf.planning.ppf.primitives import influence_radius
from gcs_ppf.tokens import add_to_token_file, new_token
from gcs_ppf.tools.observer import free_port_block
from tests.web.harness import (
    ROOT,
    browser,
    free_port,
    page_errors,
    process,
    screenshot,
    serve_args,
    wait_for,
    wait_serving,
)
from tests.web.harness import http as http_open

TOKEN, TOKEN_ENTRY = new_token("operator")  # the command scope


def http(method: str, url: str, body: Any = None) -> tuple[int, Any]:
    """One JSON request with the operator's token."""
    return http_open(method, url, body, TOKEN)


MISSION = ROOT / "examples" / "paper_table3.json"
SPEEDUP = 10


def text(driver: WebDriver, element_id: str) -> str:
    return str(driver.find_element(By.ID, element_id).text)


def js(driver: WebDriver, script: str) -> Any:
    return driver.execute_script(f"return {script};")


def leader_position(driver: WebDriver) -> list[float] | None:
    pos = js(driver, "window.gcs.state.frame?.vehicles.find(v => v.role === 'leader')?.pos_m")
    return None if pos is None else [float(c) for c in pos]


@dataclass
class Flying:
    driver: WebDriver
    api: str
    ports: dict[int, int]  # vehicle id → its SITL port


@contextmanager
def sitl_service_and_page(tmp_path: Path) -> Iterator[Flying]:
    """Table 3's vehicles on the built-in SITL (10x), the service linked to them, the page
    open and its stream connected, every vehicle heard."""
    doc = json.loads(MISSION.read_text())
    base = free_port_block(10 * len(doc["vehicles"]))
    port = free_port()
    api = f"http://127.0.0.1:{port}"
    ports = {v["id"]: base + 10 * k for k, v in enumerate(doc["vehicles"])}
    links = [f"tcp:127.0.0.1:{p}" for p in ports.values()]
    sitl = [sys.executable, "-m", "sitl", str(MISSION), "--speedup", str(SPEEDUP),
            "--base-port", str(base)]  # fmt: skip
    env = {"GCS_PPF_TLOG_DIR": str(tmp_path / "tlogs")}
    tokens = tmp_path / "tokens.json"
    add_to_token_file(tokens, TOKEN_ENTRY)
    serve = [*serve_args(port, tmp_path / "gcs.db", links), "--token-file", str(tokens)]
    with (
        process(sitl, tmp_path / "sitl.log"),
        process(serve, tmp_path / "gcs.log", env) as gcs,
        browser() as driver,
    ):
        wait_serving(api, gcs, tmp_path / "gcs.log")
        assert http_open("GET", f"{api}/vehicles")[0] == 401  # the token is needed
        driver.get(f"{api}/#token={TOKEN}")
        wait_for(lambda: text(driver, "conn") == "connected", 20, "the page's stream")
        wait_for(lambda: len(http("GET", f"{api}/vehicles")[1]) == len(ports), 60,
                 "every vehicle heard")  # fmt: skip
        yield Flying(driver, api, ports)


def upload_and_start(driver: WebDriver, mission: Path) -> None:
    driver.find_element(By.ID, "file-input").send_keys(str(mission))
    wait_for(lambda: "stored as mission #1" in text(driver, "load-message"), 20,
             "the mission stored")  # fmt: skip
    driver.find_element(By.ID, "btn-start").click()
    wait_for(lambda: "mission 1: running" in text(driver, "run-state"), 90, "the run flying")


@pytest.mark.integration
def test_upload_preview_fly_and_replay_table3(tmp_path: Path) -> None:
    """Open the page, upload Table 3 by the file input, preview its plan, start it against
    the built-in SITL (10x), watch the vehicles move and the run complete, replay it."""
    doc = json.loads(MISSION.read_text())
    with sitl_service_and_page(tmp_path) as flying:
        driver, api = flying.driver, flying.api
        # Planning: upload by the file input; the service validates and stores it.
        driver.find_element(By.ID, "file-input").send_keys(str(MISSION))
        wait_for(lambda: "stored as mission #1" in text(driver, "load-message"), 20,
                 "the mission stored")  # fmt: skip
        assert text(driver, "mission-errors") == ""
        # The page's influence radius is the planner's (gcs_ppf/ppf/primitives.py).
        lim = doc["limits"]
        keep_out = doc["obstacles"][0]["radius"] + lim["safe_distance_obstacle"]
        v, w = lim["v_max"], lim["max_yaw_rate"]
        page_r = js(driver, f"window.gcs.influenceRadius({v}, {w}, {keep_out})")
        assert page_r == pytest.approx(influence_radius(v, w, keep_out))

        driver.find_element(By.ID, "btn-preview").click()
        wait_for(lambda: driver.find_elements(By.ID, "metrics-table"), 60, "the plan's metrics")
        metrics = text(driver, "metrics-table")
        assert "leader reaches target yes" in metrics
        assert "collisions 0" in metrics
        assert js(driver, "Object.keys(window.gcs.state.plan.trajectories).length") == 5
        screenshot(driver, "planning")

        # Flying: start, see the vehicles move, the run complete.
        driver.find_element(By.ID, "btn-start").click()
        wait_for(lambda: "mission 1: running" in text(driver, "run-state"), 90, "the run flying")
        first = wait_for(lambda: leader_position(driver), 10, "the leader's position")
        wait_for(lambda: math.dist(leader_position(driver) or first, first) > 1500.0, 60,
                 "the leader 1.5 km on")  # fmt: skip
        trails = js(driver, "[...window.gcs.state.trails.values()].map(t => t.length)")
        assert len(trails) == 5
        assert min(trails) > 10, trails
        assert "Every vehicle in GUIDED" in text(driver, "events")
        # The formation flown, as the service's watch measures it: the header's figure and
        # each wingman's slot error in its row.
        shown = text(driver, "formation")
        assert re.fullmatch(r"(not formed|formed) worst \d+\.\d m \(≤ [\d.]+\).*", shown), shown
        wingmen = [v["id"] for v in doc["vehicles"] if v.get("role") == "wingman"]
        for vid in wingmen:
            row = driver.find_element(By.CSS_SELECTOR, f"#vehicles-table tr[data-vehicle='{vid}']")
            assert re.fullmatch(r"\d+\.\d m( ✓)?", cell_text(row, 9))
        # the rate the service ticks at, measured, beside its own (service.tick_rate)
        wait_for(lambda: " / 10 Hz" in text(driver, "tick-rate"), 10, "the tick rate shown")
        screenshot(driver, "mid-run")
        finished = ("completed", "completed_unsafe", "aborted", "failed")
        wait_for(lambda: js(driver, "document.getElementById('run-state').dataset.state")
                 in finished, 180, "the run to end")  # fmt: skip
        assert js(driver, "document.getElementById('run-state').dataset.state") == "completed", (
            text(driver, "run-state"), text(driver, "events"))  # fmt: skip
        assert "mission 1: completed" in text(driver, "run-state")
        wait_for(lambda: "Run completed" in text(driver, "events"), 5, "the completion event")

        # The safety monitor watches on after the end and may yet make it completed_unsafe:
        # the page then follows the service's verdict.
        def agree() -> bool:
            shown = js(driver, "document.getElementById('run-state').dataset.state")
            return bool(shown == http("GET", f"{api}/runs")[1][-1]["state"])

        wait_for(agree, 10, "the page to show the run's state as the API does")
        final = http("GET", f"{api}/runs")[1][-1]["state"]

        # Replay: History, the run, the view at half its time with its events.
        driver.find_element(By.CSS_SELECTOR, "[data-tab=history]").click()
        wait_for(lambda: driver.find_elements(By.CSS_SELECTOR, "#runs li[data-run='1']"), 10,
                 "the run in the history")  # fmt: skip
        driver.find_element(By.CSS_SELECTOR, "#runs li[data-run='1']").click()
        wait_for(lambda: js(driver, "window.gcs.state.mode") == "replay", 10, "replay mode")
        replayed = js(driver, "Object.keys(window.gcs.state.replay.tracks).length")
        assert replayed == 5
        t_half = js(driver, "window.gcs.state.replay.t")
        assert t_half == pytest.approx(js(driver, "window.gcs.state.replay.T") / 2)
        assert f"REPLAY of run #1 ({final})" in text(driver, "map-mode")
        stored = http("GET", f"{api}/runs")[1][-1]["summary"]["formation"]
        words = "never formed" if stored["time_to_form_s"] is None else "formed at"
        assert text(driver, "formation").startswith(words), text(driver, "formation")
        run_item = driver.find_element(By.CSS_SELECTOR, "#runs li[data-run='1']").text
        assert f"formation: {words}" in run_item, run_item
        future = driver.find_elements(By.CSS_SELECTOR, "#events li.future")
        assert any("Run completed" in li.text for li in future)  # after half-time
        screenshot(driver, "replay")
        assert page_errors(driver) == []


def cell_text(row: WebElement, k: int) -> str:
    """A table cell's text, shown or not (the Fleet tab may be hidden)."""
    return str(row.find_elements(By.TAG_NAME, "td")[k].get_attribute("textContent"))


def kill(port: int, vehicle_id: int) -> None:
    """The vehicle falls silent (SIM_KILL), sent on its own SITL port until it is."""
    conn = mavutil.mavlink_connection(f"tcp:127.0.0.1:{port}", source_system=201)
    try:
        conn.wait_heartbeat(timeout=10)
        for _ in range(10):
            conn.mav.param_set_send(vehicle_id, 1, b"SIM_KILL", 1.0, 2)
            if conn.recv_match(blocking=True, timeout=1.0) is None:
                return
            while conn.recv_match(blocking=False) is not None:
                pass
    finally:
        conn.close()


@pytest.mark.integration
def test_a_wingman_lost_mid_run_is_marked(tmp_path: Path) -> None:
    """Table 3's fleet towards a target 42 km away.  Wingman 3 falls silent 15 s into the
    run: the page marks it lost (its row, its mark
    on the map, the event in words) while the others fly on; an obstacle added on the map
    reaches the running mission; Abort ends the run."""
    doc = json.loads(MISSION.read_text())
    doc["target"] = [30000.0, 30000.0, 300.0]  # a long flight: at 10x Table 3 lasts 6-8 s
    doc["planner"]["max_time"] = 900.0
    far = tmp_path / "far_target.json"
    far.write_text(json.dumps(doc))
    with sitl_service_and_page(tmp_path) as flying:
        driver = flying.driver
        upload_and_start(driver, far)
        wait_for(lambda: (js(driver, "window.gcs.state.frame.run.mission_time_s") or 0) > 15,
                 60, "15 s of the run")  # fmt: skip
        kill(flying.ports[3], 3)
        wait_for(lambda: "Vehicle 3 LOST" in text(driver, "events"), 60, "the loss in words")
        assert js(driver, "window.gcs.state.frame.vehicles.find(v => v.id === 3).lost") is True
        driver.find_element(By.CSS_SELECTOR, "[data-tab=fleet]").click()
        row = "#vehicles-table tr[data-vehicle='{}']"
        wait_for(lambda: "LOST" in driver.find_element(By.CSS_SELECTOR, row.format(3)).text, 5,
                 "the row marked")  # fmt: skip
        assert "LOST" not in driver.find_element(By.CSS_SELECTOR, row.format(2)).text
        assert "mission 1: running" in text(driver, "run-state")
        screenshot(driver, "wingman-lost")
        # An obstacle added on the map mid-run reaches the running mission by Validate.
        driver.find_element(By.CSS_SELECTOR, "[data-tab=plan]").click()
        driver.find_element(By.ID, "btn-add-obstacle").click()
        canvas = driver.find_element(By.ID, "map")
        sx, sy = js(driver, "window.gcs.top.toScreen(5000, 1500)")
        dpr = js(driver, "window.devicePixelRatio")
        offset = (round(sx / dpr - canvas.size["width"] / 2),
                  round(sy / dpr - canvas.size["height"] / 2))  # fmt: skip
        ActionChains(driver).move_to_element_with_offset(canvas, *offset).click().perform()
        assert "press Validate to send the obstacles to the running mission" in text(
            driver, "load-message")  # fmt: skip
        driver.find_element(By.ID, "btn-validate").click()
        wait_for(lambda: "Obstacles of mission #1 replaced (5)" in text(driver, "load-message"),
                 10, "the obstacles sent")  # fmt: skip
        wait_for(lambda: len(js(driver, "window.gcs.state.frame.obstacles")) == 5, 5,
                 "the running mission with the new obstacle")  # fmt: skip
        assert len(http("GET", f"{flying.api}/missions/1")[1]["mission"]["obstacles"]) == 5
        # Abort: every vehicle holds, the run ends aborted.
        driver.find_element(By.ID, "btn-abort").click()
        wait_for(lambda: "mission 1: aborted" in text(driver, "run-state"), 30, "the abort")
        wait_for(lambda: "Run aborted: aborted by the operator" in text(driver, "events"), 5,
                 "the abort in words")  # fmt: skip
        assert "aborted: every vehicle holds" in text(driver, "load-message")
        assert http("GET", f"{flying.api}/runs")[1][-1]["state"] == "aborted"
        assert page_errors(driver) == []


@pytest.mark.integration
def test_a_no_fly_polygon_drawn_on_the_map_is_added_to_the_mission(tmp_path: Path) -> None:
    """Issue 27: the operator draws a no-fly zone on the map (Z, a click per corner, a
    double click ends it); the page sends it and the service adds it to the stored mission,
    in the mission's ICS metres, as a polygon the map then draws."""
    port = free_port()
    api = f"http://127.0.0.1:{port}"
    tokens = tmp_path / "tokens.json"
    add_to_token_file(tokens, TOKEN_ENTRY)
    serve = [*serve_args(port, tmp_path / "gcs.db"), "--token-file", str(tokens)]
    with process(serve, tmp_path / "gcs.log") as gcs, browser() as driver:
        wait_serving(api, gcs, tmp_path / "gcs.log")
        driver.get(f"{api}/#token={TOKEN}")
        driver.find_element(By.ID, "file-input").send_keys(str(MISSION))
        wait_for(lambda: "stored as mission #1" in text(driver, "load-message"), 20,
                 "the mission stored")  # fmt: skip
        canvas = driver.find_element(By.ID, "map")
        driver.find_element(By.ID, "btn-draw-zone").click()
        assert driver.find_element(By.ID, "btn-draw-zone").get_attribute("aria-pressed") == "true"
        corners_px = [(-90, -70), (90, -70), (90, 70)]
        actions = ActionChains(driver)
        for dx, dy in corners_px:
            actions.move_to_element_with_offset(canvas, dx, dy).click()
        actions.move_to_element_with_offset(canvas, -90, 70).double_click().perform()
        wait_for(lambda: "No-fly zone" in text(driver, "load-message"), 20, "the zone added")
        assert page_errors(driver) == []
        status, stored = http("GET", f"{api}/missions/1")
        assert status == 200, stored
        (zone,) = stored["mission"]["zones"]
        assert (zone["kind"], zone["name"], zone["inclusion"]) == ("polygon", "drawn 1", False)
        corners = zone["vertices"]
        assert len(corners) == 4  # the double click's first press put the last corner
        width = max(x for x, _ in corners) - min(x for x, _ in corners)
        scale = js(driver, "window.gcs.top.view.scale")  # screen px per m
        dpr = js(driver, "window.devicePixelRatio")
        assert width == pytest.approx(180 * dpr / scale, rel=0.05)  # 180 px across
        assert driver.find_element(By.ID, "btn-draw-zone").get_attribute("aria-pressed") == "false"
        assert js(driver, "window.gcs.top.drawing") is None
        assert js(driver, "window.gcs.state.doc.zones.length") == 1

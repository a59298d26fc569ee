"""Bad input on the operator's page: a file that is not JSON, missions the API refuses, the
service restarted under the page; and obstacles edited on the map reach the service."""

from __future__ import annotations

import json
import subprocess
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pytest
from selenium.webdriver.chrome.webdriver import WebDriver
from selenium.webdriver.common.action_chains import ActionChains
from selenium.webdriver.common.by import By
from selenium.webdriver.common.keys import Keys

from tests.web.harness import (
    ROOT,
    browser,
    free_port,
    http,
    page_errors,
    process,
    screenshot,
    serve_args,
    stop,
    wait_for,
    wait_serving,
)

MISSION = ROOT / "examples" / "paper_table3.json"


@dataclass
class Page:
    driver: WebDriver
    api: str
    tmp: Path
    service: subprocess.Popen[bytes]

    def text(self, element_id: str) -> str:
        return str(self.driver.find_element(By.ID, element_id).text)

    def js(self, script: str) -> Any:
        return self.driver.execute_script(f"return {script};")

    def upload(self, name: str, content: str) -> None:
        path = self.tmp / name
        path.write_text(content)
        self.driver.find_element(By.ID, "file-input").send_keys(str(path))


@pytest.fixture
def page(tmp_path: Path) -> Iterator[Page]:
    """The service alone (no vehicles) and the page open on it."""
    port = free_port()
    api = f"http://127.0.0.1:{port}"
    log = tmp_path / "gcs.log"
    with process(serve_args(port, tmp_path / "gcs.db"), log) as gcs, browser() as driver:
        wait_serving(api, gcs, log)
        driver.get(f"{api}/")
        p = Page(driver, api, tmp_path, gcs)
        wait_for(lambda: p.text("conn") == "connected", 20, "the page's stream")
        yield p
        assert page_errors(driver) == []


def table3() -> dict[str, Any]:
    doc: dict[str, Any] = json.loads(MISSION.read_text())
    return doc


@pytest.mark.integration
def test_a_file_that_is_not_json_is_named_and_nothing_is_sent(page: Page) -> None:
    page.upload("broken.json", '{"name": "broken",\n  "target": [1, 2, 3]\n  "vehicles": []}')
    message = wait_for(lambda: page.text("load-message"), 10, "a message")
    assert "broken.json is not a JSON document (line 3, column" in message
    assert "Nothing was sent to the service" in message
    assert http("GET", f"{page.api}/missions")[1] == []
    page.upload("list.json", "[1, 2, 3]")
    wait_for(lambda: "JSON but not a mission" in page.text("load-message"), 10, "the message")
    assert http("GET", f"{page.api}/missions")[1] == []


@pytest.mark.integration
def test_zones_are_drawn_in_both_views_those_in_lat_lon_as_the_service_converts_them(
    page: Page,
) -> None:
    """Table 3's zones example with its hexagon given in lat/lon: stored, the page draws
    all four (the hexagon from the service's frames, in metres), with no script error."""
    from gcs_ppf.geodesy import enu_to_geodetic
    from gcs_ppf.mission import Mission

    doc = json.loads((ROOT / "examples" / "paper_table3_zones.json").read_text())
    origin = Mission.model_validate(doc).origin
    hexagon = doc["zones"][1]
    hexagon["vertices_latlon"] = [
        list(enu_to_geodetic(x, y, 0.0, origin)[:2]) for x, y in hexagon.pop("vertices")
    ]
    page.upload("zones.json", json.dumps(doc))
    wait_for(lambda: "stored as mission #1" in page.text("load-message"), 10, "the mission")
    names = "window.gcs.{}.scene.zones.map((z) => z.name)"
    want = ["tower", "hexagon", "restricted L", "dome"]
    wait_for(lambda: page.js(names.format("top")) == want, 10, "the zones on the map")
    assert page.js(names.format("side")) == want
    corner = page.js("window.gcs.top.scene.zones[1].vertices_m[0]")
    assert corner == pytest.approx([4150.0, 4500.0], abs=0.05)
    assert page.js("window.gcs.top.scene.zones[0].ceiling_m") == 450.0


@pytest.mark.integration
def test_the_apis_field_errors_are_shown_next_to_the_fields(page: Page) -> None:
    doc = table3()
    doc["limits"]["v_min"] = -3
    doc["vehicles"][2]["position"][1] = "north"
    doc["colour"] = "red"
    page.upload("bad_fields.json", json.dumps(doc))
    wait_for(lambda: "Not valid" in page.text("load-message"), 10, "the refusal")
    v_min = page.driver.find_element(By.CSS_SELECTOR, "input[data-path='limits.v_min']")
    assert "invalid" in str(v_min.get_attribute("class"))
    field = v_min.find_element(By.XPATH, "./ancestor::div[@class='field']")
    assert "limits.v_min: Input should be greater than 0" in field.text
    y = page.driver.find_element(By.CSS_SELECTOR, "[data-path='vehicles.2.position.1']")
    assert "invalid" in str(y.get_attribute("class"))
    row_error = y.find_element(By.XPATH, "./ancestor::tr/following-sibling::tr[1]")
    assert "vehicles.2.position.1: Input should be a valid number" in row_error.text
    errors = page.text("mission-errors")
    assert "The service refused the mission: 3 problem(s)" in errors
    assert "colour: Extra inputs are not permitted" in errors  # no field for it: listed
    screenshot(page.driver, "field-errors")

    # A whole-document check (duplicate ids) names its field in the message.
    doc = table3()
    doc["vehicles"][1]["id"] = 1
    page.upload("duplicate.json", json.dumps(doc))
    wait_for(lambda: "Not valid" in page.text("load-message"), 10, "the refusal")
    vid = page.driver.find_element(By.CSS_SELECTOR, "[data-path='vehicles.1.id']")
    assert "invalid" in str(vid.get_attribute("class"))
    row_error = vid.find_element(By.XPATH, "./ancestor::tr/following-sibling::tr[1]")
    assert "vehicles.1.id: duplicate id 1" in row_error.text
    assert http("GET", f"{page.api}/missions")[1] == []

    # Fixed in the form, it is accepted.
    vid.clear()
    vid.send_keys("2", Keys.TAB)
    page.driver.find_element(By.ID, "btn-validate").click()
    wait_for(lambda: "stored as mission #1" in page.text("load-message"), 10, "the mission")
    assert page.text("mission-errors") == ""
    assert not page.driver.find_elements(By.CSS_SELECTOR, ".field-error")


@pytest.mark.integration
def test_obstacles_added_moved_and_deleted_on_the_map_are_planned_around(page: Page) -> None:
    page.upload("table3.json", MISSION.read_text())
    wait_for(lambda: "stored as mission #1" in page.text("load-message"), 10, "the mission")
    canvas = page.driver.find_element(By.ID, "map")

    def at(x: float, y: float) -> tuple[int, int]:
        """Offset from the canvas' centre (CSS pixels) of the world point (x, y)."""
        sx, sy = page.js(f"window.gcs.top.toScreen({x}, {y})")
        dpr = page.js("window.devicePixelRatio")
        w, h = canvas.size["width"], canvas.size["height"]
        return round(sx / dpr - w / 2), round(sy / dpr - h / 2)

    # Add one at (5000, 1500) by the keyboard shortcut and a click.
    canvas.click()
    ActionChains(page.driver).send_keys("o").perform()
    ActionChains(page.driver).move_to_element_with_offset(canvas, *at(5000, 1500)).click().perform()
    obstacles = page.js("window.gcs.state.doc.obstacles")
    assert len(obstacles) == 5
    assert obstacles[4]["center"][:2] == pytest.approx([5000, 1500], abs=40)
    # Move obstacle 0 (350 m at (3000, 3000)) 1 km east by dragging its centre.
    start = at(3000, 3000)
    end = at(4000, 3000)
    ActionChains(page.driver).move_to_element_with_offset(canvas, *start).click_and_hold() \
        .move_by_offset(end[0] - start[0], 0).release().perform()  # fmt: skip
    moved = page.js("window.gcs.state.doc.obstacles[0].center")
    assert moved[0] == pytest.approx(4000, abs=40)
    assert moved[1] == pytest.approx(3000, abs=40)
    # Delete the added one (selected by clicking it) with the Delete key.
    ActionChains(page.driver).move_to_element_with_offset(canvas, *at(5000, 1500)).click() \
        .send_keys(Keys.DELETE).perform()  # fmt: skip
    assert len(page.js("window.gcs.state.doc.obstacles")) == 4

    page.driver.find_element(By.ID, "btn-preview").click()
    wait_for(lambda: page.driver.find_elements(By.ID, "metrics-table"), 60, "the plan")
    stored = http("GET", f"{page.api}/missions/1")[1]["mission"]["obstacles"]
    assert len(stored) == 4
    assert stored[0]["center"][0] == pytest.approx(4000, abs=40)
    assert "Obstacles of mission #1 replaced (4)" in page.text("load-message") or \
        "Plan of mission #1" in page.text("load-message")  # fmt: skip
    screenshot(page.driver, "obstacles-edited")


@pytest.mark.integration
def test_the_service_restarted_under_the_page(page: Page) -> None:
    page.upload("table3.json", MISSION.read_text())
    wait_for(lambda: "stored as mission #1" in page.text("load-message"), 10, "the mission")
    stop(page.service)
    wait_for(lambda: page.text("conn") == "connection lost", 15, "the page to notice")
    banner = page.text("banner")
    assert "Connection to the service lost at" in banner
    assert "Retrying in" in banner
    screenshot(page.driver, "connection-lost")
    port = page.api.rsplit(":", 1)[1]
    log = page.tmp / "gcs-again.log"
    with process(serve_args(int(port), page.tmp / "gcs.db"), log) as again:
        wait_serving(page.api, again, log)
        wait_for(lambda: page.text("conn") == "connected", 30, "the page to reconnect")
        assert "Reconnected to the service at" in page.text("banner")
        # The page carries on with the mission it had (stored before the restart).
        page.driver.find_element(By.ID, "btn-preview").click()
        wait_for(lambda: page.driver.find_elements(By.ID, "metrics-table"), 60, "the plan")
        assert "Plan of mission #1" in page.text("load-message")


@pytest.mark.integration
def test_keyboard_shortcuts_and_themes(page: Page) -> None:
    page.upload("table3.json", MISSION.read_text())
    wait_for(lambda: "stored as mission #1" in page.text("load-message"), 10, "the mission")
    body = page.driver.find_element(By.TAG_NAME, "body")
    # "+" zooms the view the user sees: framed around the mission (not the page's default)
    # even when pressed before the next frame is drawn.
    body.send_keys("+")
    zoomed = page.js("window.gcs.top.view.scale")
    body.send_keys("0")
    scale = page.js("window.gcs.top.view.scale")
    assert scale != pytest.approx(0.05)  # the default, before the mission was framed
    assert zoomed == pytest.approx(scale * 1.4)
    body.send_keys("+")
    assert page.js("window.gcs.top.view.scale") == pytest.approx(scale * 1.4)
    body.send_keys("0")
    assert page.js("window.gcs.top.view.scale") == pytest.approx(scale, rel=1e-3)
    body.send_keys("f")
    assert page.driver.find_element(By.ID, "btn-follow").get_attribute("aria-pressed") == "true"
    theme = page.js("document.documentElement.dataset.theme")
    body.send_keys("t")
    other = page.js("document.documentElement.dataset.theme")
    assert {theme, other} == {"light", "dark"}
    background = page.js("getComputedStyle(document.body).backgroundColor")
    body.send_keys("3")
    assert page.driver.find_element(By.ID, "tab-history").is_displayed()
    body.send_keys("1")
    screenshot(page.driver, f"plan-{other}")
    body.send_keys("t")
    assert page.js("getComputedStyle(document.body).backgroundColor") != background


@pytest.mark.integration
@pytest.mark.parametrize(("width", "height"), [(1280, 720), (3840, 2160)])
def test_the_page_fits_the_screen(tmp_path: Path, width: int, height: int) -> None:
    """Nothing sticks out of the window; the map keeps most of it; text grows on 4K."""
    port = free_port()
    api = f"http://127.0.0.1:{port}"
    log = tmp_path / "gcs.log"
    with process(serve_args(port, tmp_path / "gcs.db"), log) as gcs, \
            browser(width, height) as driver:  # fmt: skip
        wait_serving(api, gcs, log)
        driver.get(f"{api}/")
        wait_for(lambda: driver.find_element(By.ID, "conn").text == "connected", 20, "the page")
        inner = driver.execute_script("return [window.innerWidth, window.innerHeight]")
        scroll = driver.execute_script(
            "return [document.documentElement.scrollWidth, document.documentElement.scrollHeight]"
        )
        assert scroll[0] <= inner[0]
        assert scroll[1] <= inner[1]
        map_size = driver.find_element(By.ID, "map").size
        assert map_size["width"] >= 0.45 * inner[0]
        assert map_size["height"] >= 0.45 * inner[1]
        font_px = float(driver.execute_script(
            "return parseFloat(getComputedStyle(document.documentElement).fontSize)"))  # fmt: skip
        assert font_px >= (20 if width >= 3840 else 13)
        screenshot(driver, f"empty-{width}x{height}")


@pytest.mark.integration
def test_links_are_added_and_removed_from_the_fleet_tab(page: Page) -> None:
    page.driver.find_element(By.CSS_SELECTOR, "[data-tab=fleet]").click()
    page.driver.find_element(By.ID, "btn-add-link").click()
    assert "Type a MAVLink URL first" in page.text("link-message")
    url = f"udpin:127.0.0.1:{free_port()}"
    page.driver.find_element(By.ID, "link-url").send_keys(url)
    page.driver.find_element(By.ID, "btn-add-link").click()
    wait_for(lambda: url in page.text("links-table"), 10, "the link listed")
    assert "Link 1 added" in page.text("link-message")
    assert [link["url"] for link in http("GET", f"{page.api}/links")[1]] == [url]
    page.driver.find_element(By.CSS_SELECTOR, "#links-table button").click()
    wait_for(lambda: url not in page.text("links-table"), 10, "the link gone")
    assert http("GET", f"{page.api}/links")[1] == []


@pytest.mark.integration
def test_a_mission_dropped_on_the_map_is_read_and_validated(page: Page) -> None:
    drop = """
        const [text, target] = arguments;
        const data = new DataTransfer();
        data.items.add(new File([text], "dropped.json", {type: "application/json"}));
        document.getElementById(target).dispatchEvent(
            new DragEvent("drop", {dataTransfer: data, bubbles: true, cancelable: true}));
    """
    page.driver.execute_script(drop, MISSION.read_text(), "map")
    wait_for(lambda: "stored as mission #1" in page.text("load-message"), 10, "the mission")
    page.driver.execute_script(drop, "{nope", "drop")
    wait_for(lambda: "dropped.json is not a JSON document" in page.text("load-message"), 10,
             "the message")  # fmt: skip
    assert len(http("GET", f"{page.api}/missions")[1]) == 1

"""The browser tests run only where Debian's chromium and chromium-driver are installed."""

from __future__ import annotations

import pytest

from tests.web.harness import chromium_missing


def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    reason = chromium_missing()
    if reason is None:
        return
    for item in items:
        if "tests/web/" in item.nodeid:
            item.add_marker(pytest.mark.skip(reason=reason))

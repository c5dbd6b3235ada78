"""Debian's Chromium driven by Playwright, for the tests of our pages (Swagger UI, the live fleet page).

Playwright's sync API runs an event loop in the test's thread, where Django then refuses database access:
a test makes what it needs from the database before it opens a page, or allows it (`allow_database`)."""

import os
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import TYPE_CHECKING

import pytest

if TYPE_CHECKING:
    from playwright.sync_api import Page

CHROMIUM = Path(os.environ.get("PLAYWRIGHT_CHROMIUM_EXECUTABLE", "/usr/bin/chromium"))
TIMEOUT_MS = 30_000  # generous: the machine is shared

needs_chromium = pytest.mark.skipif(
    not CHROMIUM.exists(), reason=f"no Chromium at {CHROMIUM} (apt-get install chromium)"
)


@contextmanager
def chromium_page(*, width: int = 1280, height: int = 800) -> Iterator["Page"]:
    """A page of a new headless Chromium, closed at the end."""
    from playwright.sync_api import sync_playwright

    with sync_playwright() as playwright:
        browser = playwright.chromium.launch(executable_path=str(CHROMIUM), args=["--no-sandbox"])
        try:
            page = browser.new_page(viewport={"width": width, "height": height})
            page.set_default_timeout(TIMEOUT_MS)
            yield page
        finally:
            browser.close()


def allow_database(monkeypatch: pytest.MonkeyPatch) -> None:
    """Let the test use Django's database while a page is open: Playwright's loop never runs Django code, so
    Django's guard against database access from async code has nothing to guard here."""
    monkeypatch.setenv("DJANGO_ALLOW_ASYNC_UNSAFE", "true")


def log_in(page: "Page", url: str, *, username: str, password: str) -> None:
    """Open `url` and log in on the admin's login page it sends an anonymous visitor to."""
    page.goto(url)
    page.locator("#id_username").fill(username)
    page.locator("#id_password").fill(password)
    page.locator("input[type=submit]").click()

"""Swagger UI as a person uses it (in Chromium): without a token "Try it out" gets 401; after "Authorize"
with a token, GET /robot answers 200."""

from collections.abc import Iterator

import pytest

from access.services import api_token_create
from tests.browser import chromium_page, needs_chromium

pytestmark = [pytest.mark.e2e, pytest.mark.django_db(transaction=True), needs_chromium]
sync_api = pytest.importorskip("playwright.sync_api")


@pytest.fixture
def token(live_server) -> str:
    return api_token_create(name="swagger")[1]


@pytest.fixture
def page(token: str) -> Iterator["sync_api.Page"]:
    """A Chromium page; everything the test needs from the database is made before (`token`)."""
    with chromium_page() as page:
        yield page


def try_get_robots(page: "sync_api.Page") -> str:
    """Run GET /robot with "Try it out" and "Execute"; the status code Swagger UI shows."""
    operation = page.locator("#operations-robot-robot_list")
    if not operation.locator("button.execute").is_visible():
        operation.locator(".opblock-summary").click()
        operation.get_by_role("button", name="Try it out").click()
    clear = operation.locator("button.btn-clear")
    if clear.is_visible():
        clear.click()
    operation.locator("button.execute").click()
    status = operation.locator(".live-responses-table .response .response-col_status").first
    status.wait_for()
    return status.inner_text().strip()


def test_authorize_with_a_token_then_try_it_out(live_server, token, page):
    page.goto(f"{live_server.url}/docs")
    page.locator("#operations-robot-robot_list").wait_for()

    assert try_get_robots(page) == "401"

    page.locator("button.authorize").first.click()
    bearer = page.locator(".modal-ux .auth-container").filter(has_text="bearerAuth")
    bearer.locator("input").fill(token)
    bearer.locator("button[type=submit]").click()
    assert bearer.get_by_text("Authorized").is_visible()
    page.locator(".modal-ux button.btn-done").first.click()

    assert try_get_robots(page) == "200"

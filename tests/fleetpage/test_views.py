"""GET /fleet, the live fleet page, protected as the admin's pages are: a staff user's login, else the admin's
login page."""

import json
import re

import pytest
from django.contrib.staticfiles import finders
from django.core.management import call_command
from django.test import Client
from django.urls import reverse

from fleetpage.views import NAME
from tests.fleetpage.page import PASSWORD, staff_user

pytestmark = pytest.mark.django_db

LOGIN = reverse("admin:login")


def logged_in(*, staff: bool) -> Client:
    client = Client()
    assert client.login(username=staff_user(staff=staff), password=PASSWORD)
    return client


def test_an_anonymous_visitor_is_sent_to_the_admins_login():
    response = Client().get("/fleet")

    assert response.status_code == 302
    assert response["Location"] == f"{LOGIN}?next=/fleet"


def test_a_user_who_is_not_staff_is_sent_to_the_login_too():
    response = logged_in(staff=False).get("/fleet")

    assert response.status_code == 302
    assert response["Location"].startswith(LOGIN)


def test_an_api_token_does_not_open_the_page(api_token):
    response = Client().get("/fleet", HTTP_AUTHORIZATION=f"Bearer {api_token}")

    assert response.status_code == 302


def test_a_staff_user_gets_the_page_and_where_its_data_and_actions_are():
    response = logged_in(staff=True).get("/fleet")

    assert response.status_code == 200
    config = json.loads(
        re.search(rb'id="fleet-config" type="application/json">(.*?)</script>', response.content)[1]
    )
    assert config["events_url"] == reverse("events")
    assert config["mission_cancel_url"] == reverse("mission-cancel", kwargs={"name": NAME})
    assert config["robot_teleop_url"] == reverse("robot-teleop", kwargs={"name": NAME})
    assert config["mission_states"] == ["PENDING", "RUNNING", "COMPLETED", "CANCELED", "FAILED"]
    assert config["done_states"] == ["CANCELED", "COMPLETED", "FAILED"]
    assert b'name="csrf-token"' in response.content
    # Where the page sends the operator once the session has ended (hidden until then).
    assert f'<a href="{LOGIN}?next=/fleet">log in again</a>'.encode() in response.content


def test_every_script_and_stylesheet_is_ours():
    """Nothing from a CDN: the page's scripts and styles are our static files, Leaflet vendored with them."""
    page = logged_in(staff=True).get("/fleet").content.decode()

    sources = re.findall(r'<(?:script|link)[^>]* (?:src|href)="([^"]+)"', page)

    assert sources == [
        "/static/vendor/leaflet/leaflet.css",
        "/static/fleetpage/fleet.css",
        "/static/vendor/leaflet/leaflet.js",
        "/static/fleetpage/fleet.js",
    ]
    for source in sources:
        assert finders.find(source.removeprefix("/static/")), source
    assert finders.find("vendor/leaflet/LICENSE")


def test_collectstatic_gathers_the_pages_files(tmp_path, settings):
    """`make run` collects the static files, which whitenoise serves: the page's are among them."""
    settings.STATIC_ROOT = tmp_path
    call_command("collectstatic", interactive=False, verbosity=0)

    for name in (
        "fleetpage/fleet.js",
        "fleetpage/fleet.css",
        "vendor/leaflet/leaflet.js",
        "vendor/leaflet/LICENSE",
    ):
        assert (tmp_path / name).is_file(), name


def test_the_admin_links_to_the_page():
    response = logged_in(staff=True).get(reverse("admin:index"))

    assert b'<a href="/fleet">View fleet live</a>' in response.content

"""The browser path: a staff user's session (the admin's login) is accepted by the API, with Django's CSRF
check on writes; other users' sessions are refused."""

import pytest
from django.contrib.auth.models import User
from rest_framework.test import APIClient

from access.models import WriteRecord

pytestmark = pytest.mark.django_db


def logged_in(*, staff: bool) -> APIClient:
    """A browser's client: logged in, with the CSRF cookie a page gave it, CSRF checks as in production."""
    User.objects.create_user("alice", password="secret-password", is_staff=staff)
    client = APIClient(enforce_csrf_checks=True)
    client.get("/admin/login/")  # a page with a form sets the CSRF cookie
    assert client.login(username="alice", password="secret-password")
    return client


def test_a_staff_session_reads_the_api():
    assert logged_in(staff=True).get("/robot").status_code == 200


def test_a_staff_session_writes_only_with_the_csrf_token(woken):
    client = logged_in(staff=True)

    without = client.post("/robot", {"name": "r1"}, format="json")
    with_token = client.post(
        "/robot", {"name": "r1"}, format="json", HTTP_X_CSRFTOKEN=client.cookies["csrftoken"].value
    )

    assert without.status_code == 403
    assert "CSRF" in without.json()["detail"]
    assert with_token.status_code == 200, with_token.content
    assert list(WriteRecord.objects.values_list("actor", flat=True)) == ["user:alice"]


def test_a_session_of_a_user_who_is_not_staff_is_refused():
    client = logged_in(staff=False)

    response = client.get("/robot")

    assert response.status_code == 403
    assert response.json() == {"detail": "Only staff users may use the API through a session."}


def test_a_bearer_token_needs_no_csrf_token_even_next_to_a_session(api_token, woken):
    client = logged_in(staff=False)
    client.credentials(HTTP_AUTHORIZATION=f"Bearer {api_token}")

    assert client.post("/robot", {"name": "r1"}, format="json").status_code == 200
    assert list(WriteRecord.objects.values_list("actor", flat=True)) == ["token:tests"]

"""`manage.py api_token`: create (the token alone on the last line), list, revoke, dev; tokens stored hashed;
and the admin's token form."""

import io
import re
import stat

import pytest
from django.core.management import CommandError, call_command
from django.db import connection

from access.models import DUPLICATE_NAME, ApiToken
from tests.conftest import authenticated_client

pytestmark = pytest.mark.django_db


def api_token(*args: str) -> list[str]:
    out = io.StringIO()
    call_command("api_token", *args, stdout=out)
    return out.getvalue().splitlines()


def create(name: str, *options: str) -> str:
    return api_token("create", name, *options)[-1]


def test_create_prints_the_token_alone_on_the_last_line_and_it_works():
    key = create("ci")

    assert re.fullmatch(r"[A-Za-z0-9]+\.[A-Za-z0-9]+", key)
    assert authenticated_client(key).get("/robot").status_code == 200
    assert authenticated_client(key).post("/robot", {"name": "r1"}, format="json").status_code == 200


def test_the_token_is_stored_only_hashed():
    key = create("ci")
    prefix, secret = key.split(".")

    with connection.cursor() as cursor:
        cursor.execute(f"SELECT t::text FROM {ApiToken._meta.db_table} t")
        [(row,)] = cursor.fetchall()

    assert prefix in row  # how the token is found
    assert secret not in row and key not in row
    assert ApiToken.objects.get().hashed_key.startswith("sha512$$")


def test_a_read_only_token_reads_but_does_not_write():
    lines = api_token("create", "dashboard", "--read-only")

    assert "read-only" in lines[0]
    client = authenticated_client(lines[-1])
    assert client.get("/robot").status_code == 200
    assert client.post("/robot", {"name": "r1"}, format="json").status_code == 403


def test_a_duplicate_name_is_refused_until_the_first_is_revoked():
    first = create("ci")
    with pytest.raises(CommandError, match='A token named "ci" already exists'):
        create("ci")

    api_token("revoke", "ci")
    second = create("ci")

    assert second != first
    assert authenticated_client(first).get("/robot").status_code == 401
    assert authenticated_client(second).get("/robot").status_code == 200


def test_revoke_makes_the_token_401_and_unknown_names_are_an_error():
    key = create("ci")
    assert authenticated_client(key).get("/robot").status_code == 200

    assert api_token("revoke", "ci") == ['Revoked the API token "ci".']

    response = authenticated_client(key).get("/robot")
    assert response.status_code == 401
    with pytest.raises(CommandError, match='No usable token named "ci"'):
        api_token("revoke", "ci")
    with pytest.raises(CommandError, match='No usable token named "nobody"'):
        api_token("revoke", "nobody")


def test_list_shows_names_rights_and_revocations_but_no_secret():
    kept = create("ci")
    create("dashboard", "--read-only")
    gone = create("old")
    api_token("revoke", "old")
    authenticated_client(kept).get("/robot")

    header, *rows = api_token("list")

    assert header.split() == ["name", "access", "created", "last", "used", "revoked"]
    by_name = {row.split()[0]: row for row in rows}
    assert set(by_name) == {"ci", "dashboard", "old"}
    assert "read-write" in by_name["ci"] and "never" not in by_name["ci"]
    assert "read-only" in by_name["dashboard"] and "never" in by_name["dashboard"]
    assert by_name["old"].endswith("revoked")
    assert kept.split(".")[1] not in "\n".join(rows) and gone.split(".")[1] not in "\n".join(rows)


def test_an_empty_name_is_refused():
    with pytest.raises(CommandError, match="1 to 50 characters"):
        create(" ")


def test_dev_keeps_one_token_in_its_file_and_replaces_it_once_revoked(tmp_path):
    path = tmp_path / "dev-token"

    first = api_token("dev", "--file", str(path))
    again = api_token("dev", "--file", str(path))
    key = path.read_text().strip()

    assert first == again
    assert f"Development API token: {key}" in first
    assert any('curl -H "Authorization: Bearer $TOKEN"' in line for line in first)
    assert stat.S_IMODE(path.stat().st_mode) == 0o600
    assert authenticated_client(key).get("/robot").status_code == 200

    api_token("revoke", "development")
    api_token("dev", "--file", str(path))

    assert path.read_text().strip() != key
    assert authenticated_client(path.read_text().strip()).get("/robot").status_code == 200
    assert ApiToken.objects.filter(name="development", revoked=False).count() == 1


def test_the_admin_creates_a_token_and_shows_it_once(admin_client):
    response = admin_client.post(
        "/admin/access/apitoken/add/", {"name": "wms", "read_only": "on"}, follow=True
    )

    assert response.status_code == 200
    [message] = [
        str(message) for message in response.context["messages"] if "never shown again" in str(message)
    ]
    key = re.fullmatch(r'The new API token "wms" \(store it now: it is never shown again\): (\S+)', message)[
        1
    ]
    token = ApiToken.objects.get(name="wms")
    assert token.read_only
    assert authenticated_client(key).get("/robot").status_code == 200
    assert authenticated_client(key).delete("/robot/r1").status_code == 403
    assert key not in admin_client.get(f"/admin/access/apitoken/{token.pk}/change/").content.decode()


def test_the_admin_refuses_a_second_usable_token_of_the_same_name(admin_client):
    create("wms")

    response = admin_client.post("/admin/access/apitoken/add/", {"name": "wms"})

    assert response.status_code == 200  # the form again, with its error
    assert response.context["adminform"].form.non_field_errors() == [DUPLICATE_NAME]
    assert ApiToken.objects.filter(name="wms").count() == 1

"""The zone set admin as an operator uses it: the list, its filters and search, add through the service
(refusing what the API refuses), an existing set read-only, enable/disable actions, deletion of the
enabled set refused; the grants shown with their zone set and revoked through the service."""

import json

import pytest
from django.contrib import messages
from django.contrib.messages import get_messages
from django.test import Client
from django.urls import reverse
from django.utils import timezone

from access.models import WriteRecord
from tests.factories import ZoneSetFactory
from tests.zones.bodies import BOWTIE, zone
from zones.models import ZoneGrant, ZoneSet

pytestmark = pytest.mark.django_db

CHANGELIST = reverse("admin:zones_zoneset_changelist")
ADD = reverse("admin:zones_zoneset_add")


def listed(response) -> list[str]:
    return [zone_set.name for zone_set in response.context["cl"].result_list]


def test_the_list_filters_and_searches(admin_client: Client):
    ZoneSetFactory(name="floor1", description="ground floor")
    ZoneSetFactory(name="yard1", map_id="yard", enabled=True)

    assert admin_client.get(CHANGELIST).status_code == 200
    assert listed(admin_client.get(CHANGELIST, {"enabled__exact": "1"})) == ["yard1"]
    assert listed(admin_client.get(CHANGELIST, {"map_id__exact": "map"})) == ["floor1"]
    assert listed(admin_client.get(CHANGELIST, {"q": "ground"})) == ["floor1"]


def test_add_goes_through_the_service_and_a_set_is_then_read_only(admin_client: Client):
    form = {"name": "floor7", "map_id": "map", "description": "", "zones": json.dumps([zone("RELEASE")])}

    response = admin_client.post(ADD, form)

    assert response.status_code == 302, response.context["adminform"].form.errors
    assert ZoneSet.objects.get(name="floor7").zones[0]["capacity"] == 1
    change = reverse("admin:zones_zoneset_change", args=["floor7"])
    assert admin_client.post(change, {**form, "map_id": "other"}).status_code == 302
    assert ZoneSet.objects.get(name="floor7").map_id == "map"
    assert list(WriteRecord.objects.values_list("action", flat=True)) == ["zone_set_create"]


def test_add_refuses_what_the_api_refuses(admin_client: Client):
    form = {
        "name": "bad",
        "map_id": "map",
        "description": "",
        "zones": json.dumps([zone("RELEASE", vertices=BOWTIE)]),
    }

    response = admin_client.post(ADD, form)

    assert response.status_code == 200
    assert "cross" in str(response.context["adminform"].form.errors)
    assert not ZoneSet.objects.exists()


def test_enable_and_disable_actions_and_the_enabled_set_is_not_deleted(admin_client: Client):
    ZoneSetFactory(name="a")
    ZoneSetFactory(name="b")

    admin_client.post(CHANGELIST, {"action": "enable", "_selected_action": ["a"]})
    admin_client.post(CHANGELIST, {"action": "enable", "_selected_action": ["b"]})
    assert dict(ZoneSet.objects.values_list("name", "enabled")) == {"a": False, "b": True}
    response = admin_client.post(
        CHANGELIST, {"action": "delete_selected", "_selected_action": ["a", "b"], "post": "yes"}, follow=True
    )

    assert list(ZoneSet.objects.values_list("name", flat=True)) == ["b"]
    levels = {message.level for message in get_messages(response.wsgi_request)}
    assert messages.WARNING in levels
    admin_client.post(CHANGELIST, {"action": "disable", "_selected_action": ["b"]})
    assert ZoneSet.objects.get(name="b").enabled is False


GRANTS = reverse("admin:zones_zonegrant_changelist")


def test_the_enabled_set_shows_who_holds_its_zones(admin_client: Client):
    ZoneSetFactory(name="floor1", enabled=True)
    ZoneGrant.objects.create(map_id="map", zone_id="square", robot="carter01", granted_at=timezone.now())

    page = admin_client.get(reverse("admin:zones_zoneset_change", args=["floor1"])).content.decode()

    assert "<td>square</td><td>carter01</td>" in page


def test_revoke_goes_through_the_service_and_a_grant_revoked_already_is_refused(admin_client: Client):
    ZoneSetFactory(name="floor1", enabled=True)
    grant = ZoneGrant.objects.create(
        map_id="map", zone_id="square", robot="carter01", granted_at=timezone.now()
    )
    assert admin_client.get(GRANTS).status_code == 200

    first = admin_client.post(GRANTS, {"action": "revoke", "_selected_action": [grant.pk]}, follow=True)
    again = admin_client.post(GRANTS, {"action": "revoke", "_selected_action": [grant.pk]}, follow=True)

    assert ZoneGrant.objects.get(pk=grant.pk).revoked_at is not None
    assert list(WriteRecord.objects.values_list("action", flat=True)) == ["zone_grant_revoke"]
    assert [m.level for m in get_messages(first.wsgi_request)] == [messages.SUCCESS]
    assert [m.level for m in get_messages(again.wsgi_request)] == [messages.WARNING]
    assert admin_client.post(reverse("admin:zones_zonegrant_change", args=[grant.pk]), {}).status_code == 403

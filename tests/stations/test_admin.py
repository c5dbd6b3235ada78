"""The station admin as an operator uses it: the list, its filters and search, add and edit through the
services (refusing what the API refuses), deletion refused while robots hold a station."""

import pytest
from django.contrib import messages
from django.contrib.messages import get_messages
from django.test import Client
from django.urls import reverse

from access.models import WriteRecord
from stations.models import Station
from tests.factories import StationFactory

pytestmark = pytest.mark.django_db

CHANGELIST = reverse("admin:stations_station_changelist")
ADD = reverse("admin:stations_station_add")


def form(**fields: str) -> dict[str, str]:
    return {
        "kind": "CHARGER",
        "pose_x": "1.0",
        "pose_y": "2.0",
        "pose_theta": "0.0",
        "pose_map_id": "map",
        "robot_types": "[]",
        "capacity": "1",
        **fields,
    }


def listed(response) -> list[str]:
    return [station.name for station in response.context["cl"].result_list]


def test_the_list_filters_and_searches(admin_client: Client):
    StationFactory(name="charger01")
    StationFactory(name="park01", kind="PARKING", pose_map_id="yard")

    assert admin_client.get(CHANGELIST).status_code == 200
    assert listed(admin_client.get(CHANGELIST, {"kind__exact": "PARKING"})) == ["park01"]
    assert listed(admin_client.get(CHANGELIST, {"pose_map_id__exact": "yard"})) == ["park01"]
    assert listed(admin_client.get(CHANGELIST, {"q": "charger"})) == ["charger01"]


def test_add_and_change_go_through_the_services(admin_client: Client):
    response = admin_client.post(ADD, form(name="charger07", robot_types='["CARRIER"]'))

    assert response.status_code == 302, response.context["adminform"].form.errors
    station = Station.objects.get(name="charger07")
    assert (station.pose_x, station.robot_types) == (1.0, ["CARRIER"])
    change = reverse("admin:stations_station_change", args=["charger07"])
    assert admin_client.post(change, form(capacity="3")).status_code == 302
    assert Station.objects.get(name="charger07").capacity == 3
    actions = set(WriteRecord.objects.values_list("action", flat=True))
    assert actions == {"station_create", "station_update"}


@pytest.mark.parametrize(
    ("fields", "field"),
    [
        ({"capacity": "0"}, "capacity"),
        ({"robot_types": '["SPACESHIP"]'}, "robot_types"),
        ({"name": "a b"}, "name"),
    ],
)
def test_add_refuses_what_the_api_refuses(admin_client: Client, fields: dict[str, str], field: str):
    response = admin_client.post(ADD, form(**{"name": "charger08", **fields}))

    assert response.status_code == 200
    assert field in response.context["adminform"].form.errors
    assert not Station.objects.exists()


def test_a_held_station_is_not_deleted(admin_client: Client):
    StationFactory(name="held", reservations=["r1"])
    StationFactory(name="free")

    response = admin_client.post(
        CHANGELIST,
        {"action": "delete_selected", "_selected_action": ["held", "free"], "post": "yes"},
        follow=True,
    )

    assert list(Station.objects.values_list("name", flat=True)) == ["held"]
    assert (messages.WARNING, "Station held is held by r1: it can be deleted once they have left it.") in [
        (message.level, message.message) for message in get_messages(response.wsgi_request)
    ]

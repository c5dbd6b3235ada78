"""GET/POST /zone_set, GET/DELETE /zone_set/{name}, POST /zone_set/{name}/enable|disable: the shape, every
zone type and its fields, every validation rule, one enabled set per map, and the write records (real
PostgreSQL)."""

import re

import pytest
from django.utils import timezone

from access.models import WriteRecord
from tests.zones.bodies import ACTION, BOWTIE, SQUARE, TRIANGLE, ZONES, zone, zone_set
from zones.models import MAX_CAPACITY, MAX_VERTICES, ZoneGrant, ZoneSet

pytestmark = pytest.mark.django_db

GENERATED_NAME = re.compile(r"[a-z2-7]{26}")


def test_a_zone_set_is_created_disabled_with_the_shape_of_stations(api):
    response = api.post("/zone_set", {**zone_set(), "description": "Floor 1"}, format="json")

    assert response.status_code == 200, response.content
    assert response.json() == {
        "map_id": "map",
        "description": "Floor 1",
        "zones": [
            {
                "zone_id": "aisle",
                "zone_type": "RELEASE",
                "description": "",
                "vertices": SQUARE,
                "release_loss_behavior": "STOP",
                "capacity": 1,
            }
        ],
        "name": "floor1-v1",
        "status": {"enabled": False},
        "lifecycle": "ALIVE",
    }
    assert api.get("/zone_set/floor1-v1").json() == response.json()
    assert WriteRecord.objects.filter(action="zone_set_create", object_name="floor1-v1").exists()


def test_every_zone_type_keeps_its_fields(api):
    zones = [zone(zone_type, description=f"a {zone_type} zone") for zone_type in ZONES]

    response = api.post("/zone_set", zone_set(zones=zones), format="json")

    assert response.status_code == 200, response.content
    shown = {each["zone_type"]: each for each in response.json()["zones"]}
    for zone_type, fields in ZONES.items():
        expected = {**zone(zone_type, description=f"a {zone_type} zone"), **fields}
        if zone_type == "RELEASE":
            expected["capacity"] = 1
        assert shown[zone_type] == expected


def test_an_action_zones_actions_keep_every_field(api):
    full = {**ACTION, "description": "beep loud", "retriable": True}
    body = zone_set(zones=[zone("ACTION", entry_actions=[full], exit_actions=[ACTION])])

    shown = api.post("/zone_set", body, format="json").json()["zones"][0]

    assert (shown["entry_actions"], shown["during_actions"], shown["exit_actions"]) == ([full], [], [ACTION])


def test_a_release_zone_takes_our_capacity(api):
    body = zone_set(zones=[zone("RELEASE", capacity=3)])

    assert api.post("/zone_set", body, format="json").json()["zones"][0]["capacity"] == 3


def test_a_zone_set_without_a_name_gets_a_generated_one_or_its_prefix(api):
    unnamed = api.post("/zone_set", {"map_id": "map", "zones": []}, format="json").json()
    prefixed = api.post("/zone_set", {"prefix": "floor1", "map_id": "map", "zones": []}, format="json").json()

    assert GENERATED_NAME.fullmatch(unnamed["name"])
    assert prefixed["name"].startswith("floor1-")
    assert (unnamed["zones"], unnamed["description"]) == ([], "")


def test_a_duplicate_name_is_the_references_error(api):
    api.post("/zone_set", zone_set(), format="json")

    response = api.post("/zone_set", zone_set(map_id="other"), format="json")

    assert (response.status_code, response.json()) == (
        400,
        {"detail": "Object zone_set with name floor1-v1 already exists"},
    )


CLOCKWISE = list(reversed(SQUARE))
LINE = [{"x": 0.0, "y": 0.0}, {"x": 1.0, "y": 1.0}, {"x": 2.0, "y": 2.0}]
REPEATED = [*SQUARE, SQUARE[0]]


@pytest.mark.parametrize(
    ("body", "loc", "type"),
    [
        ({"zones": []}, ["body", "map_id"], "required"),
        ({"map_id": "map"}, ["body", "zones"], "required"),
        ({"map_id": 7, "zones": []}, ["body", "map_id"], "invalid"),
        (
            zone_set(zones=[{**zone("RELEASE"), "zone_type": "DOOR"}]),
            ["body", "zones", 0, "zone_type"],
            "invalid_choice",
        ),
        (
            zone_set(zones=[zone("RELEASE", vertices=TRIANGLE[:2])]),
            ["body", "zones", 0, "vertices"],
            "min_length",
        ),
        (
            zone_set(zones=[zone("RELEASE", vertices=BOWTIE)]),
            ["body", "zones", 0, "vertices"],
            "invalid_polygon",
        ),
        (
            zone_set(zones=[zone("RELEASE", vertices=CLOCKWISE)]),
            ["body", "zones", 0, "vertices"],
            "invalid_polygon",
        ),
        (
            zone_set(zones=[zone("RELEASE", vertices=LINE)]),
            ["body", "zones", 0, "vertices"],
            "invalid_polygon",
        ),
        (
            zone_set(zones=[zone("RELEASE", vertices=REPEATED)]),
            ["body", "zones", 0, "vertices"],
            "invalid_polygon",
        ),
        (
            zone_set(
                zones=[zone("RELEASE", vertices=[{"x": i, "y": i * i} for i in range(MAX_VERTICES + 1)])]
            ),
            ["body", "zones", 0, "vertices"],
            "max_length",
        ),
        (
            zone_set(zones=[zone("RELEASE", vertices=[{"x": 0.0}, *SQUARE[1:]])]),
            ["body", "zones", 0, "vertices", 0, "y"],
            "required",
        ),
        (
            zone_set(zones=[zone("RELEASE", vertices=[{"x": "0", "y": 0}, *SQUARE[1:]])]),
            ["body", "zones", 0, "vertices", 0, "x"],
            "invalid",
        ),
        (
            zone_set(zones=[zone("RELEASE", vertices=[{"x": 0, "y": 0, "z": 1}, *SQUARE[1:]])]),
            ["body", "zones", 0, "vertices", 0, "z"],
            "extra_forbidden",
        ),
        (
            zone_set(zones=[zone("RELEASE", "aisle"), zone("BLOCKED", "aisle")]),
            ["body", "zones"],
            "duplicate",
        ),
        (zone_set(zones=[zone("RELEASE", zone_id="a b")]), ["body", "zones", 0, "zone_id"], "invalid_name"),
        (
            zone_set(zones=[zone("RELEASE", release_loss_behavior="PANIC")]),
            ["body", "zones", 0, "release_loss_behavior"],
            "invalid_choice",
        ),
        (
            zone_set(zones=[{**zone("RELEASE"), "release_loss_behavior": None}]),
            ["body", "zones", 0, "release_loss_behavior"],
            "null",
        ),
        (zone_set(zones=[zone("RELEASE", capacity=0)]), ["body", "zones", 0, "capacity"], "min_value"),
        (
            zone_set(zones=[zone("RELEASE", capacity=MAX_CAPACITY + 1)]),
            ["body", "zones", 0, "capacity"],
            "max_value",
        ),
        (
            zone_set(zones=[zone("BLOCKED", capacity=2)]),
            ["body", "zones", 0, "capacity"],
            "not_for_zone_type",
        ),
        (
            zone_set(zones=[zone("BLOCKED", maximum_speed=1.0)]),
            ["body", "zones", 0, "maximum_speed"],
            "not_for_zone_type",
        ),
        (
            zone_set(zones=[zone("SPEED_LIMIT", maximum_speed=-1)]),
            ["body", "zones", 0, "maximum_speed"],
            "min_value",
        ),
        (
            zone_set(zones=[zone("PRIORITY", priority_factor=1.5)]),
            ["body", "zones", 0, "priority_factor"],
            "max_value",
        ),
        (
            zone_set(zones=[zone("PENALTY", penalty_factor=-0.1)]),
            ["body", "zones", 0, "penalty_factor"],
            "min_value",
        ),
        (
            zone_set(zones=[zone("DIRECTED", directed_limitation="LOOSE")]),
            ["body", "zones", 0, "directed_limitation"],
            "invalid_choice",
        ),
        (
            zone_set(zones=[zone("BIDIRECTED", bidirected_limitation="STRICT")]),
            ["body", "zones", 0, "bidirected_limitation"],
            "invalid_choice",
        ),
        (
            zone_set(zones=[zone("DIRECTED", bidirected_limitation="SOFT")]),
            ["body", "zones", 0, "bidirected_limitation"],
            "not_for_zone_type",
        ),
        (
            zone_set(zones=[zone("ACTION", entry_actions=[{**ACTION, "blocking_type": "MAYBE"}])]),
            ["body", "zones", 0, "entry_actions", 0, "blocking_type"],
            "invalid_choice",
        ),
        (
            zone_set(zones=[zone("ACTION", exit_actions=[{"blocking_type": "NONE"}])]),
            ["body", "zones", 0, "exit_actions", 0, "action_type"],
            "required",
        ),
        (
            zone_set(zones=[zone("ACTION", during_actions=[{**ACTION, "action_parameters": [1]}])]),
            ["body", "zones", 0, "during_actions", 0, "action_parameters"],
            "not_a_dict",
        ),
        (zone_set(zones=[zone("RELEASE", colour="red")]), ["body", "zones", 0, "colour"], "extra_forbidden"),
        ({**zone_set(), "colour": "red"}, ["body", "colour"], "extra_forbidden"),
        ({**zone_set(), "name": "a b"}, ["body", "name"], "invalid_name"),
    ],
)
def test_invalid_bodies_are_a_400_that_says_where(api, body, loc, type):
    response = api.post("/zone_set", body, format="json")

    assert response.status_code == 400
    assert {"loc": loc, "type": type} in [
        {"loc": error["loc"], "type": error["type"]} for error in response.json()["detail"]
    ], response.json()
    assert not ZoneSet.objects.exists()


@pytest.mark.parametrize("zone_type", sorted(zone_type for zone_type, fields in ZONES.items() if fields))
def test_each_zone_type_needs_each_of_its_fields(api, zone_type):
    for field in ZONES[zone_type]:
        body = zone_set(zones=[{k: v for k, v in zone(zone_type).items() if k != field}])

        response = api.post("/zone_set", body, format="json")

        assert response.status_code == 400
        errors = [(e["loc"], e["type"]) for e in response.json()["detail"]]
        assert (["body", "zones", 0, field], "required") in errors, response.json()


def test_a_polygon_error_says_why(api):
    body = zone_set(zones=[zone("RELEASE", vertices=CLOCKWISE)])

    [error] = api.post("/zone_set", body, format="json").json()["detail"]

    assert error["msg"] == "The vertices go clockwise; VDA 5050 lists them counter-clockwise."


def test_status_cannot_be_written_and_there_is_no_put(api):
    written = api.post("/zone_set", {**zone_set(), "status": {"enabled": True}}, format="json")
    api.post("/zone_set", zone_set(), format="json")
    put = api.put("/zone_set/floor1-v1", zone_set(), format="json")

    assert (written.status_code, written.json()["error_code"]) == (400, "USAGE")
    assert put.status_code == 405


def test_one_zone_set_per_map_is_enabled(api):
    for name, map_id in (("a", "map"), ("b", "map"), ("c", "yard")):
        api.post("/zone_set", zone_set(name=name, map_id=map_id), format="json")

    first = api.post("/zone_set/a/enable")
    api.post("/zone_set/c/enable")
    second = api.post("/zone_set/b/enable")

    assert (first.status_code, first.json()["status"]) == (200, {"enabled": True})
    assert second.json()["status"] == {"enabled": True}
    assert dict(ZoneSet.objects.values_list("name", "enabled")) == {"a": False, "b": True, "c": True}
    assert api.post("/zone_set/b/enable").json()["status"] == {"enabled": True}  # again: no change
    assert api.post("/zone_set/b/disable").json()["status"] == {"enabled": False}
    assert not ZoneSet.objects.filter(map_id="map", enabled=True).exists()
    actions = list(WriteRecord.objects.order_by("id").values_list("action", flat=True))
    assert actions[-4:] == ["zone_set_enable", "zone_set_enable", "zone_set_enable", "zone_set_disable"]


def test_the_enabled_set_is_not_deleted_a_disabled_one_is(api):
    api.post("/zone_set", zone_set(name="old"), format="json")
    api.post("/zone_set", zone_set(name="new"), format="json")
    api.post("/zone_set/old/enable")

    refused = api.delete("/zone_set/old")
    api.post("/zone_set/new/enable")
    deleted = api.delete("/zone_set/old")

    assert (refused.status_code, refused.json()["error_code"]) == (400, "USAGE")
    assert "disable it or enable another set" in refused.json()["message"]
    assert (deleted.status_code, deleted.json()) == (200, {"detail": "old is DELETED"})
    assert list(ZoneSet.objects.values_list("name", flat=True)) == ["new"]
    assert WriteRecord.objects.filter(action="zone_set_delete", object_name="old").exists()


def test_a_missing_zone_set_is_the_references_error(api):
    assert api.get("/zone_set/nope").json() == {"detail": 'Did not find "zone_set" with name "nope"'}
    assert api.post("/zone_set/nope/enable").json() == {"detail": 'Did not find "zone_set" with name "nope"'}
    assert api.post("/zone_set/nope/disable").json() == {"detail": 'Did not find "zone_set" with name "nope"'}
    assert api.delete("/zone_set/nope").json() == {"detail": "Could not find object nope"}


def test_the_list_filters_by_map_enabled_and_names(api):
    for name, map_id in (("a", "map"), ("b", "map"), ("c", "yard")):
        api.post("/zone_set", zone_set(name=name, map_id=map_id), format="json")
    api.post("/zone_set/b/enable")

    def names(query: str) -> list[str]:
        response = api.get("/zone_set" + query)
        assert response.status_code == 200, response.content
        return [each["name"] for each in response.json()]

    assert names("") == ["a", "b", "c"]
    assert names("?map_id=map") == ["a", "b"]
    assert names("?enabled=true") == ["b"]
    assert names("?enabled=false&map_id=map") == ["a"]
    assert names("?names=c&names=a") == ["a", "c"]
    assert api.get("/zone_set?enabled=perhaps").status_code == 400


def test_a_grant_is_revoked_through_the_api_and_unknown_ones_are_a_400(api):
    api.post("/zone_set", zone_set(name="floor"), format="json")
    api.post("/zone_set/floor/enable")
    ZoneGrant.objects.create(map_id="map", zone_id="aisle", robot="carter01", granted_at=timezone.now())

    revoked = api.post("/zone_set/floor/revoke", {"robot": "carter01", "zone_id": "aisle"}, format="json")
    again = api.post("/zone_set/floor/revoke", {"robot": "carter01", "zone_id": "aisle"}, format="json")
    unknown_zone = api.post("/zone_set/floor/revoke", {"robot": "carter01", "zone_id": "nope"}, format="json")
    bad_body = api.post("/zone_set/floor/revoke", {"robot": "carter01"}, format="json")
    missing = api.post("/zone_set/nope/revoke", {"robot": "carter01", "zone_id": "aisle"}, format="json")
    api.post("/zone_set", zone_set(name="floor-next"), format="json")  # same map and zones, not enabled
    ZoneGrant.objects.create(map_id="map", zone_id="aisle", robot="carter02", granted_at=timezone.now())
    disabled = api.post(
        "/zone_set/floor-next/revoke", {"robot": "carter02", "zone_id": "aisle"}, format="json"
    )

    assert (revoked.status_code, revoked.json()) == (
        200,
        {"detail": "Grant of zone aisle to carter01 is REVOKED"},
    )
    assert ZoneGrant.objects.get(robot="carter01").revoked_at is not None
    assert (again.status_code, again.json()["error_code"]) == (400, "USAGE")
    assert "holds no grant" in again.json()["message"]
    assert (unknown_zone.status_code, unknown_zone.json()["error_code"]) == (400, "USAGE")
    assert bad_body.status_code == 400 and bad_body.json()["detail"][0]["loc"] == ["body", "zone_id"]
    assert missing.json() == {"detail": 'Did not find "zone_set" with name "nope"'}
    assert (disabled.status_code, disabled.json()["error_code"]) == (400, "USAGE")
    assert "floor-next is not enabled" in disabled.json()["message"]
    assert ZoneGrant.objects.get(robot="carter02").revoked_at is None
    assert WriteRecord.objects.filter(action="zone_grant_revoke", object_name="floor").count() == 1
    assert not WriteRecord.objects.filter(action="zone_grant_revoke", object_name="floor-next").exists()

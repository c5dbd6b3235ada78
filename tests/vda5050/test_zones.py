"""The zoneSet message's content from zone sets in the API's shape: every zone type, validated against the
official 3.0.0 schema (main's errata for the zoneSet file, see tests/vda5050/schemas.py)."""

import pytest

from tests.vda5050.schemas import validate_message
from tests.zones.bodies import ACTION, ZONES, zone
from vda5050.zones import ZoneType, has_zones, supported_zones, zone_set_content

HEADER = {
    "headerId": 0,
    "timestamp": "2026-11-28T04:00:00.000Z",
    "version": "3.0.0",
    "manufacturer": "acme",
    "serialNumber": "carter01",
}


def message(content: dict) -> dict:
    return {**HEADER, "zoneSet": content}


def test_every_zone_type_is_a_valid_zone_set_message():
    zones = [zone(zone_type, description=f"{zone_type} zone") for zone_type in ZONES]
    zones[2]["capacity"] = 2  # RELEASE: ours, not on the wire

    content = zone_set_content(zone_set_id="floor1-v1", map_id="map", description="Floor 1", zones=zones)

    validate_message("zoneSet", "3.0.0", message(content))
    assert (content["mapId"], content["zoneSetId"], content["zoneSetDescriptor"]) == (
        "map",
        "floor1-v1",
        "Floor 1",
    )
    assert [each["zoneType"] for each in content["zones"]] == list(ZONES)
    release = content["zones"][2]
    assert release == {
        "zoneId": "release",
        "zoneType": "RELEASE",
        "zoneDescriptor": "RELEASE zone",
        "vertices": zones[2]["vertices"],
        "releaseLossBehavior": "STOP",
    }
    assert content["zones"][4]["maximumSpeed"] == 0.5
    assert content["zones"][8]["directedLimitation"] == "STRICT"
    assert content["zones"][9]["bidirectedLimitation"] == "RESTRICTED"


def test_zone_actions_become_vda_actions_with_parameters_as_key_value_pairs():
    full = {**ACTION, "description": "loud", "retriable": True}
    action_zone = zone(
        "ACTION", entry_actions=[full], during_actions=[{"action_type": "x", "blocking_type": "HARD"}]
    )

    content = zone_set_content(zone_set_id="z", map_id="map", description="", zones=[action_zone])

    validate_message("zoneSet", "3.0.0", message(content))
    [wire] = content["zones"]
    assert wire["entryActions"] == [
        {
            "actionType": "beep",
            "blockingType": "NONE",
            "actionDescriptor": "loud",
            "actionParameters": [{"key": "volume", "value": 3}],
            "retriable": True,
        }
    ]
    assert wire["duringActions"] == [{"actionType": "x", "blockingType": "HARD"}]
    assert (wire["exitActions"], "zoneSetDescriptor" in content) == ([], False)


def test_an_empty_zone_set_is_valid_and_only_3_0_has_zones():
    validate_message(
        "zoneSet", "3.0.0", message(zone_set_content(zone_set_id="z", map_id="m", description="", zones=[]))
    )
    assert [has_zones(version) for version in ("2.0.0", "2.1.0", "3.0.0")] == [False, False, True]


@pytest.mark.parametrize("zone_type", list(ZoneType))
def test_each_zone_type_of_the_schema_is_ours(zone_type):
    assert zone_type in ZONES


def test_supported_zones_are_read_from_the_factsheet_as_sent():
    assert supported_zones({"typeSpecification": {"supportedZones": ["RELEASE", "BLOCKED"]}}) == [
        "RELEASE",
        "BLOCKED",
    ]
    assert supported_zones({"typeSpecification": {"agvClass": "CARRIER"}}) == []  # 2.x
    assert supported_zones({"typeSpecification": {"supportedZones": "RELEASE"}}) == []  # not a list
    assert supported_zones(None) == supported_zones({}) == []

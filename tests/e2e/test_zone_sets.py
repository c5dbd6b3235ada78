"""Zone sets end to end (real API, bridge, workers, Mosquitto and simulated robots): enabling a set through
the API brings it to the 3.0 robot on its map (the zoneSet message, then enableZoneSet), which reports it in
`zoneSets`, shown in GET /robot/{name}; disabling it deletes it from the robot. A 2.1 robot on the same map
gets nothing."""

from collections.abc import Callable
from typing import Any

import pytest
from rest_framework.test import APIClient

from robots.models import Robot
from tests.e2e.conftest import Recorder
from tests.e2e.helpers import create_robot, get
from tests.waiting import wait_for
from tests.zones import bodies

pytestmark = [pytest.mark.e2e, pytest.mark.django_db(transaction=True)]

AISLE = bodies.zone(
    "RELEASE",
    "aisle",
    vertices=[{"x": 2.0, "y": -1.0}, {"x": 3.0, "y": -1.0}, {"x": 3.0, "y": 1.0}, {"x": 2.0, "y": 1.0}],
)


def post(api: APIClient, path: str, body: dict | None = None) -> dict:
    response = api.post(path, body or {}, format="json")
    assert response.status_code == 200, response.content
    return response.json()


def test_an_enabled_zone_set_reaches_the_3_0_robot_and_a_disabled_one_leaves_it(
    api: APIClient, simulator: Callable[..., Any], unique: Callable[[str], str], recorder: Recorder
) -> None:
    robot, old = unique("zones30"), unique("zones21")
    simulator(
        f"{robot},0,0,0,map,0,50,RobotCompany,{robot},CARRIER,3.0.0",
        f"{old},0,4,0,map,0,50,RobotCompany,{old},CARRIER,2.1.0",
    )
    create_robot(api, robot, vda5050={"version": "3.0.0"})
    create_robot(api, old, vda5050={"version": "2.1.0"})
    wait_for(
        lambda: get(api, "robot", robot)["status"]["factsheet"]["supported_zones"] == ["RELEASE"],
        message="the 3.0 robot's factsheet",
    )
    zone_set = unique("floor")
    post(api, "/zone_set", {"name": zone_set, "map_id": "map", "zones": [AISLE]})

    post(api, f"/zone_set/{zone_set}/enable")

    enabled = [{"map_id": "map", "zone_set_id": zone_set, "zone_set_status": "ENABLED"}]
    wait_for(lambda: get(api, "robot", robot)["status"]["zone_sets"] == enabled, message="zone set enabled")
    # The 2.1 robot was sent nothing (its simulator would report no zone sets whatever it got).
    sent = Robot.objects.values_list("name", "next_zone_set_header_id")
    assert dict(sent.filter(name__in=[robot, old])) == {robot: 1, old: 0}
    assert not [
        action
        for message in recorder.for_robot(old, "instantActions")
        for action in message.get("actions") or message.get("instantActions") or []
        if "ZoneSet" in action["actionType"]
    ]

    post(api, f"/zone_set/{zone_set}/disable")

    wait_for(lambda: get(api, "robot", robot)["status"]["zone_sets"] == [], message="zone set deleted")

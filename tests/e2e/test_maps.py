"""Maps end to end (real API, bridge, workers, Mosquitto and a simulated 2.1 robot): a mission on a map the
robot lacks is held, the operator downloads and enables the map through the API, each map action is tracked
to FINISHED, and the mission then completes; the operator can delete a map version too."""

import pytest

from tests.e2e.helpers import create_robot, get, post_mission, route, wait_mission, wait_mission_where
from tests.waiting import wait_for

pytestmark = [pytest.mark.e2e, pytest.mark.django_db(transaction=True)]


def map_action(api, robot: str, body: dict) -> str:
    response = api.post(f"/robot/{robot}/map", body, format="json")
    assert response.status_code == 200, response.content
    return response.json()["action_id"]


def wait_action(api, robot: str, action_id: str, status: str) -> None:
    def reported() -> bool:
        actions = api.get(f"/robot/{robot}/map").json()["actions"]
        return any(a["action_id"] == action_id and a["status"] == status for a in actions)

    wait_for(reported, message=f"map action {action_id} {status}")


def test_a_mission_on_a_missing_map_waits_until_the_operator_downloads_and_enables_it(api, simulator, unique):
    robot = unique("maps")
    simulator(f"{robot},0,0,0,map,0,50,RobotCompany,{robot},CARRIER,2.1.0")
    create_robot(api, robot, vda5050={"version": "2.1.0"})
    wait_for(lambda: get(api, "robot", robot)["status"]["maps"], message="the robot's maps")
    assert get(api, "robot", robot)["status"]["maps"] == [
        {"map_id": "map", "map_version": "1", "map_status": "ENABLED", "map_description": None}
    ]

    mission = unique("hall-mission")
    post_mission(api, mission, robot, [route("to_hall", (1, 0), (2, 0), map_id="hall")])
    held = wait_mission_where(api, mission, lambda s: s["waiting_reason"] is not None)["status"]
    assert (held["state"], held["waiting_reason"]) == (
        "PENDING",
        "Waiting for map hall to be enabled on the robot",
    )

    download = map_action(
        api,
        robot,
        {
            "action": "downloadMap",
            "map_id": "hall",
            "map_version": "3",
            "map_download_link": "https://maps.example/hall/3",
        },
    )
    wait_action(api, robot, download, "FINISHED")
    hall = {"map_id": "hall", "map_version": "3", "map_status": "DISABLED", "map_description": None}
    # The action's end comes with the step, the maps with the bridge's next status flush.
    wait_for(lambda: hall in api.get(f"/robot/{robot}/map").json()["maps"], message="map downloaded")
    assert get(api, "mission", mission)["status"]["state"] == "PENDING"  # downloaded is not enabled

    enable = map_action(api, robot, {"action": "enableMap", "map_id": "hall", "map_version": "3"})
    wait_action(api, robot, enable, "FINISHED")
    done = wait_mission(api, mission)["status"]
    assert (done["state"], done["waiting_reason"]) == ("COMPLETED", None)

    # A version the robot does not have: the robot refuses, and the API shows the action FAILED.
    missing = map_action(api, robot, {"action": "deleteMap", "map_id": "hall", "map_version": "9"})
    wait_action(api, robot, missing, "FAILED")
    delete = map_action(api, robot, {"action": "deleteMap", "map_id": "map", "map_version": "1"})
    wait_action(api, robot, delete, "FINISHED")
    wait_for(
        lambda: [m["map_id"] for m in get(api, "robot", robot)["status"]["maps"]] == ["hall"],
        message="map deleted",
    )

"""GET and POST /robot/{name}/map: a robot's maps and the map actions asked of it."""

import pytest
from rest_framework.test import APIClient

from access.choices import WriteAction
from access.models import WriteRecord
from access.services import api_token_create
from robots.models import InstantAction
from tests.conftest import authenticated_client
from tests.factories import RobotFactory

pytestmark = pytest.mark.django_db

HALL = {"map_id": "hall", "map_version": "2", "map_status": "ENABLED", "map_description": None}
DOWNLOAD = {
    "action": "downloadMap",
    "map_id": "hall",
    "map_version": "2",
    "map_download_link": "https://maps.example/hall/2",
    "map_hash": "9f2c",
}


@pytest.fixture
def robot():
    return RobotFactory(name="carter01", protocol_version="2.1.0", maps=[HALL])


def test_the_robot_list_and_get_show_which_robot_has_which_map(api, robot):
    RobotFactory(name="carter02", protocol_version="2.0.0")

    listed = {r["name"]: r["status"]["maps"] for r in api.get("/robot").json()}

    assert listed == {"carter01": [HALL], "carter02": []}
    assert api.get("/robot/carter01").json()["status"]["maps"] == [HALL]


@pytest.mark.parametrize(
    ("body", "parameters"),
    [
        (
            DOWNLOAD,
            {
                "mapId": "hall",
                "mapVersion": "2",
                "mapDownloadLink": "https://maps.example/hall/2",
                "mapHash": "9f2c",
            },
        ),
        (
            {key: value for key, value in DOWNLOAD.items() if key != "map_hash"},
            {"mapId": "hall", "mapVersion": "2", "mapDownloadLink": "https://maps.example/hall/2"},
        ),
        ({"action": "enableMap", "map_id": "hall", "map_version": "2"}, {"mapId": "hall", "mapVersion": "2"}),
        ({"action": "deleteMap", "map_id": "hall", "map_version": "1"}, {"mapId": "hall", "mapVersion": "1"}),
    ],
    ids=["download with hash", "download", "enable", "delete"],
)
def test_a_map_action_is_queued_recorded_and_wakes_the_robot(api, woken, robot, body, parameters):
    response = api.post("/robot/carter01/map", body)

    assert response.status_code == 200, response.content
    answer = response.json()
    assert (answer["action"], answer["parameters"], answer["status"], answer["sent_at"]) == (
        body["action"],
        parameters,
        None,
        None,
    )
    stored = InstantAction.objects.get(action_id=answer["action_id"])
    assert (stored.robot_id, stored.action_type, stored.parameters) == (
        "carter01",
        body["action"],
        parameters,
    )
    assert woken == ["carter01"]
    assert WriteRecord.objects.filter(action=WriteAction.ROBOT_MAP, object_name="carter01").count() == 1


def test_get_lists_the_maps_and_the_map_actions_newest_first_with_their_status(api, woken, robot):
    first = api.post("/robot/carter01/map", DOWNLOAD).json()
    second = api.post("/robot/carter01/map", {"action": "enableMap", "map_id": "hall", "map_version": "2"})
    InstantAction.objects.filter(action_id=first["action_id"]).update(status="FINISHED")
    RobotFactory(name="carter03", protocol_version="2.1.0")
    api.post("/robot/carter03/map", {"action": "deleteMap", "map_id": "x", "map_version": "1"})

    answer = api.get("/robot/carter01/map").json()

    assert answer["maps"] == [HALL]
    assert [(a["action_id"], a["status"]) for a in answer["actions"]] == [
        (second.json()["action_id"], None),
        (first["action_id"], "FINISHED"),
    ]


def test_a_vda5050_2_0_robot_has_no_map_actions(api, woken):
    RobotFactory(name="old01", protocol_version="2.0.0")

    response = api.post("/robot/old01/map", {"action": "enableMap", "map_id": "hall", "map_version": "2"})

    assert response.status_code == 400
    assert response.json() == {
        "message": "Robot old01 speaks VDA 5050 2.0.0, which has no map actions (maps came with 2.1.0).",
        "error_code": "USAGE",
    }
    assert not InstantAction.objects.filter(robot_id="old01", action_type="enableMap").exists()
    assert woken == []


@pytest.mark.parametrize(
    ("body", "errors"),
    [
        ({"map_id": "hall", "map_version": "2"}, [(["body", "action"], "required")]),
        (
            {"action": "loadMap", "map_id": "hall", "map_version": "2"},
            [(["body", "action"], "invalid_choice")],
        ),
        ({"action": "enableMap", "map_version": "2"}, [(["body", "map_id"], "required")]),
        ({"action": "enableMap", "map_id": "hall"}, [(["body", "map_version"], "required")]),
        ({"action": "enableMap", "map_id": "", "map_version": "2"}, [(["body", "map_id"], "blank")]),
        ({"action": "enableMap", "map_id": 7, "map_version": "2"}, [(["body", "map_id"], "invalid")]),
        (
            {"action": "downloadMap", "map_id": "hall", "map_version": "2"},
            [(["body", "map_download_link"], "missing")],
        ),
        (
            {"action": "deleteMap", "map_id": "hall", "map_version": "2", "map_hash": "ab"},
            [(["body", "map_hash"], "extra_forbidden")],
        ),
        (
            {"action": "enableMap", "map_id": "hall", "map_version": "2", "force": True},
            [(["body", "force"], "extra_forbidden")],
        ),
    ],
)
def test_bad_input_is_400_saying_what_is_wrong(api, woken, robot, body, errors):
    response = api.post("/robot/carter01/map", body)

    assert response.status_code == 400
    assert [(e["loc"], e["type"]) for e in response.json()["detail"]] == errors
    assert all(e["msg"] for e in response.json()["detail"])
    assert not InstantAction.objects.filter(robot_id="carter01", action_type__endswith="Map").exists()
    assert woken == []


def test_a_missing_robot_is_400_with_the_reference_message(api):
    for response in (
        api.get("/robot/carter99/map"),
        api.post("/robot/carter99/map", {"action": "enableMap", "map_id": "hall", "map_version": "2"}),
    ):
        assert response.status_code == 400
        assert response.json() == {"detail": 'Did not find "robot" with name "carter99"'}


def test_without_a_token_401_and_with_a_read_only_token_reads_only(robot):
    body = {"action": "enableMap", "map_id": "hall", "map_version": "2"}
    assert APIClient().post("/robot/carter01/map", body, format="json").status_code == 401

    reader = authenticated_client(api_token_create(name="reader", read_only=True)[1])
    assert reader.get("/robot/carter01/map").status_code == 200
    assert reader.post("/robot/carter01/map", body, format="json").status_code == 403
    assert not InstantAction.objects.filter(action_type="enableMap").exists()

"""The robot admin as an operator uses it: lists, the change page, and actions that go through services."""

from typing import Any

import pytest
from django.contrib import messages
from django.contrib.messages import get_messages
from django.http import HttpResponse
from django.test import Client
from django.urls import reverse

from robots.admin import EDITABLE_SPEC_FIELDS
from robots.choices import Lifecycle, MapAction, RobotState
from robots.models import InstantAction, Robot
from robots.services import robot_map_action
from tests.factories import CAN_CHARGE, MissionFactory, RobotFactory

pytestmark = pytest.mark.django_db

CHANGELIST = reverse("admin:robots_robot_changelist")
ADD = reverse("admin:robots_robot_add")


def change_url(robot: Robot) -> str:
    return reverse("admin:robots_robot_change", args=[robot.name])


def sent_messages(response: HttpResponse) -> list[tuple[int, str]]:
    return [(message.level, message.message) for message in get_messages(response.wsgi_request)]


def listed(response: HttpResponse) -> list[str]:
    return [robot.name for robot in response.context["cl"].result_list]


def spec_form(**fields: Any) -> dict[str, Any]:
    """A valid POST of the robot add/change form, default spec unless overridden."""
    return {
        "labels": "[]",
        "battery_critical_level": "10.0",
        "battery_recommended_minimum": "",
        "battery_recommended_maximum": "",
        "heartbeat_timeout": "30.0",
        **fields,
    }


def test_changelist_shows_status_columns(admin_client: Client):
    RobotFactory(name="carter01", state=RobotState.ON_TASK, online=True, battery_level=87.5, pose_x=1.25)

    response = admin_client.get(CHANGELIST)

    assert response.status_code == 200
    assert listed(response) == ["carter01"]
    content = response.content.decode()
    assert "87.5" in content
    assert "(1.25, 0.00, 0.00)" in content


def test_changelist_filters_by_state_online_and_lifecycle(admin_client: Client):
    RobotFactory(name="busy", state=RobotState.ON_TASK, online=True)
    RobotFactory(name="idle", state=RobotState.IDLE, online=False)
    RobotFactory(name="leaving", lifecycle=Lifecycle.PENDING_DELETE)

    assert listed(admin_client.get(CHANGELIST, {"state__exact": "ON_TASK"})) == ["busy"]
    assert listed(admin_client.get(CHANGELIST, {"online__exact": "1"})) == ["busy"]
    assert listed(admin_client.get(CHANGELIST, {"lifecycle__exact": "PENDING_DELETE"})) == ["leaving"]


def test_changelist_searches_by_name(admin_client: Client):
    RobotFactory(name="carter01")
    RobotFactory(name="carter02")
    RobotFactory(name="forklift01")

    assert listed(admin_client.get(CHANGELIST, {"q": "carter"})) == ["carter01", "carter02"]


def test_change_page_edits_only_spec_fields(admin_client: Client):
    robot = RobotFactory(battery_level=42.0)

    response = admin_client.get(change_url(robot))

    assert response.status_code == 200
    assert set(response.context["adminform"].form.fields) == set(EDITABLE_SPEC_FIELDS)
    assert "42.0" in response.content.decode()


def test_change_updates_the_spec_through_the_service_and_ignores_status(
    admin_client: Client, woken: list[str]
):
    robot = RobotFactory(battery_level=42.0, state=RobotState.IDLE)

    response = admin_client.post(
        change_url(robot),
        spec_form(labels='["dock"]', heartbeat_timeout="12.5", battery_level="99", state="TELEOP"),
    )

    assert response.status_code == 302
    robot.refresh_from_db()
    assert (robot.labels, robot.heartbeat_timeout) == (["dock"], 12.5)
    assert (robot.battery_level, robot.state) == (42.0, RobotState.IDLE)
    assert robot.serial_number == robot.name
    assert woken == [robot.name]


def test_change_rejects_what_the_api_rejects(admin_client: Client):
    robot = RobotFactory()

    response = admin_client.post(
        change_url(robot), spec_form(labels='{"not": "a list"}', heartbeat_timeout="0")
    )

    assert response.status_code == 200
    errors = response.context["adminform"].form.errors
    assert set(errors) == {"labels", "heartbeat_timeout"}
    robot.refresh_from_db()
    assert (robot.labels, robot.heartbeat_timeout) == ([], 30.0)


def test_add_creates_the_robot_through_the_service(admin_client: Client, woken: list[str]):
    response = admin_client.post(ADD, spec_form(name="carter07", heartbeat_timeout="5"))

    assert response.status_code == 302
    robot = Robot.objects.get(name="carter07")
    assert (robot.heartbeat_timeout, robot.serial_number, robot.switch_teleop) == (5.0, "carter07", False)
    assert woken == ["carter07"]


@pytest.mark.parametrize("name", ["has space", "carter01"])
def test_add_refuses_invalid_or_taken_names(admin_client: Client, name: str):
    RobotFactory(name="carter01")

    response = admin_client.post(ADD, spec_form(name=name))

    assert response.status_code == 200
    assert set(response.context["adminform"].form.errors) == {"name"}
    assert Robot.objects.count() == 1


def test_add_reports_a_vda5050_identity_another_robot_uses(admin_client: Client):
    RobotFactory(name="other", serial_number="carter09")

    response = admin_client.post(ADD, spec_form(name="carter09"))

    assert (response.status_code, response["Location"]) == (302, ADD)
    assert list(Robot.objects.values_list("name", flat=True)) == ["other"]
    ((level, message),) = sent_messages(response)
    assert level == messages.ERROR
    assert message.startswith("Another robot already uses the VDA 5050 identity")


@pytest.mark.parametrize(
    ("action", "before", "after"), [("start_teleop", False, True), ("stop_teleop", True, False)]
)
def test_teleop_actions_switch_teleop(admin_client: Client, action: str, before: bool, after: bool):
    robots = [RobotFactory(switch_teleop=before), RobotFactory(switch_teleop=before)]

    response = admin_client.post(CHANGELIST, {"action": action, "_selected_action": [r.name for r in robots]})

    assert response.status_code == 302
    assert [robot.switch_teleop for robot in Robot.objects.order_by("name")] == [after, after]
    assert [level for level, _ in sent_messages(response)] == [messages.SUCCESS]


def test_start_teleop_reports_robots_the_service_refuses(admin_client: Client):
    charging = RobotFactory(name="charging", state=RobotState.CHARGING)
    idle = RobotFactory(name="idle")

    response = admin_client.post(
        CHANGELIST, {"action": "start_teleop", "_selected_action": [charging.name, idle.name]}
    )

    assert response.status_code == 302
    assert dict(Robot.objects.values_list("name", "switch_teleop")) == {"charging": False, "idle": True}
    (success, warning) = sent_messages(response)
    assert success == (messages.SUCCESS, "START teleop requested for 1 robot.")
    assert warning[0] == messages.WARNING
    assert warning[1].startswith("Robot charging is in CHARGING and request cannot be satisfied")


def test_charge_now_asks_robots_that_can_charge_and_reports_those_the_service_refuses(admin_client: Client):
    able = RobotFactory(name="able", online=True, factsheet=CAN_CHARGE)
    offline = RobotFactory(name="offline", online=False, factsheet=CAN_CHARGE)

    response = admin_client.post(
        CHANGELIST, {"action": "charge", "_selected_action": [able.name, offline.name]}
    )

    assert response.status_code == 302
    assert dict(Robot.objects.values_list("name", "charge_requested")) == {"able": True, "offline": False}
    (success, warning) = sent_messages(response)
    assert success == (messages.SUCCESS, "sent to charge for 1 robot.")
    assert warning == (messages.WARNING, "Robot offline is offline: it cannot be sent to charge.")


def test_delete_removes_a_robot_without_a_running_mission(admin_client: Client):
    robot = RobotFactory()

    response = admin_client.post(reverse("admin:robots_robot_delete", args=[robot.name]), {"post": "yes"})

    assert response.status_code == 302
    assert not Robot.objects.filter(name=robot.name).exists()
    assert [level for level, _ in sent_messages(response)] == [messages.SUCCESS]


def test_bulk_delete_leaves_a_robot_with_a_running_mission_pending_delete(admin_client: Client):
    busy = RobotFactory(name="busy", state=RobotState.ON_TASK)
    MissionFactory(robot="busy", running=True)
    free = RobotFactory(name="free")

    response = admin_client.post(
        CHANGELIST, {"action": "delete_selected", "_selected_action": [busy.name, free.name], "post": "yes"}
    )

    assert response.status_code == 302
    assert list(Robot.objects.values_list("name", "lifecycle")) == [("busy", Lifecycle.PENDING_DELETE)]
    assert (
        messages.INFO,
        "PENDING_DELETE until the engine has failed their running mission: busy.",
    ) in sent_messages(response)


LEARNED_LEGACY = {
    "protocol_version": "3.0.0",
    "protocol_version_source": "LEARNED",
    "instant_actions_key": "instantActions",
    "instant_actions_key_source": "LEARNED",
    "compatibility_rules": [
        {
            "rule": "legacy_instant_actions_key",
            "applied_at": "2026-11-26T10:00:00+00:00",
            "reason": "#/instantActions",
        }
    ],
}


def test_the_change_page_shows_the_version_its_source_and_the_compatibility_rules(admin_client: Client):
    robot = RobotFactory(**LEARNED_LEGACY)

    page = admin_client.get(change_url(robot)).content.decode()
    listing = admin_client.get(CHANGELIST, {"protocol_version": "3.0.0"})

    assert "3.0.0" in page and "LEARNED" in page and "legacy_instant_actions_key" in page
    assert listed(listing) == [robot.name]


def test_the_change_page_shows_the_zones_the_robot_holds_and_waits_for(admin_client: Client):
    robot = RobotFactory(
        zone_access={"held": [{"map_id": "map", "zone_id": "aisle"}], "waiting": []},
    )

    page = admin_client.get(change_url(robot)).content.decode()

    assert "holds map/aisle; waits for none" in page


def test_an_admin_save_keeps_what_the_robot_taught(admin_client: Client, woken: list[str]):
    robot = RobotFactory(**LEARNED_LEGACY)

    assert admin_client.post(change_url(robot), spec_form(heartbeat_timeout="12")).status_code == 302

    robot.refresh_from_db()
    assert (robot.protocol_version, robot.protocol_version_source) == ("3.0.0", "LEARNED")
    assert (robot.instant_actions_key, robot.instant_actions_key_source) == ("instantActions", "LEARNED")
    assert [rule["rule"] for rule in robot.compatibility_rules] == ["legacy_instant_actions_key"]


def test_the_change_page_shows_the_reported_maps_and_the_map_actions(admin_client: Client):
    robot = RobotFactory(
        name="carter01",
        protocol_version="2.1.0",
        maps=[{"map_id": "hall", "map_version": "2", "map_status": "ENABLED", "map_description": "ground"}],
    )
    robot_map_action(actor="test", robot=robot, action=MapAction.DELETE, map_id="yard", map_version="1")

    content = admin_client.get(change_url(robot)).content.decode()

    assert "<td>hall</td><td>2</td><td>ENABLED</td><td>ground</td>" in content
    assert "<td>deleteMap</td><td>mapId=yard, mapVersion=1</td><td>not reported yet</td>" in content


MAP_ACTION_ADD = reverse("admin:robots_robotmapaction_add")


def test_an_operator_asks_a_map_action_in_the_admin_and_sees_its_status(admin_client: Client, woken):
    RobotFactory(name="carter01", protocol_version="3.0.0")
    form = {"robot": "carter01", "action": "downloadMap", "map_id": "hall", "map_version": "3"}

    refused = admin_client.post(MAP_ACTION_ADD, form)
    assert "downloadMap needs a map_download_link." in refused.content.decode()

    link = "https://maps.example/hall/3"
    response = admin_client.post(MAP_ACTION_ADD, {**form, "map_download_link": link}, follow=True)

    assert response.status_code == 200
    [action] = InstantAction.objects.filter(robot_id="carter01", action_type="downloadMap")
    assert action.parameters == {"mapId": "hall", "mapVersion": "3", "mapDownloadLink": link}
    assert woken == ["carter01"]
    InstantAction.objects.filter(pk=action.pk).update(status="FINISHED")
    listing = admin_client.get(reverse("admin:robots_robotmapaction_changelist")).content.decode()
    assert "FINISHED" in listing and "downloadMap" in listing


def test_the_admin_refuses_map_actions_for_a_2_0_robot(admin_client: Client, woken):
    RobotFactory(name="old01", protocol_version="2.0.0")
    form = {"robot": "old01", "action": "enableMap", "map_id": "hall", "map_version": "3"}

    response = admin_client.post(MAP_ACTION_ADD, form, follow=True)

    assert (
        messages.ERROR,
        "Robot old01 speaks VDA 5050 2.0.0, which has no map actions (maps came with 2.1.0).",
    ) in sent_messages(response)
    assert not InstantAction.objects.filter(robot_id="old01", action_type="enableMap").exists()
    assert woken == []

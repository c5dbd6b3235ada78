"""The mission admin: a read-only view of missions and their trees; cancel and delete go through services."""

from datetime import UTC, datetime

import pytest
from django.contrib import messages
from django.contrib.messages import get_messages
from django.http import HttpResponse
from django.test import Client
from django.urls import reverse

from missions.admin import mission_tree_rows
from missions.choices import Lifecycle, MissionState
from missions.models import Mission
from tests.factories import MissionFactory, route_node

pytestmark = pytest.mark.django_db

CHANGELIST = reverse("admin:missions_mission_changelist")


def change_url(mission: Mission) -> str:
    return reverse("admin:missions_mission_change", args=[mission.name])


def sent_messages(response: HttpResponse) -> list[tuple[int, str]]:
    return [(message.level, message.message) for message in get_messages(response.wsgi_request)]


def listed(response: HttpResponse) -> list[str]:
    return sorted(mission.name for mission in response.context["cl"].result_list)


def node_state(state: str, error_msg: str | None = None) -> dict:
    return {"state": state, "error_msg": error_msg}


@pytest.fixture
def picking_mission() -> Mission:
    """A running mission: route done, then a selector whose action failed and whose notify now runs."""
    return MissionFactory(
        name="picking",
        robot="carter01",
        running=True,
        mission_tree=[
            route_node("goto", (1.0, 2.0), (3.0, 4.0)),
            {"name": "pick", "parent": "root", "selector": {}},
            {
                "name": "grab",
                "parent": "pick",
                "action": {"action_type": "gripper_close", "action_parameters": {"force": 5}},
            },
            {"name": "tell", "parent": "pick", "notify": {"url": "http://wms.local/done", "json_data": {}}},
            {"name": "finish", "parent": "root", "constant": {"success": True}},
        ],
        node_status={
            "root": node_state("RUNNING"),
            "goto": node_state("COMPLETED"),
            "pick": node_state("RUNNING"),
            "grab": node_state("FAILED", "Action failure"),
            "tell": node_state("RUNNING"),
            "finish": node_state("PENDING"),
        },
        current_node=3,
    )


def test_changelist_shows_missions_with_their_current_node(admin_client: Client, picking_mission: Mission):
    MissionFactory(name="done", completed=True)

    response = admin_client.get(CHANGELIST)

    assert response.status_code == 200
    assert listed(response) == ["done", "picking"]
    assert "tell" in response.content.decode()


def test_changelist_filters_and_searches(admin_client: Client):
    MissionFactory(name="m-failed", robot="carter01", failed=True)
    MissionFactory(name="m-queued", robot="carter02")
    MissionFactory(name="m-leaving", robot="carter02", lifecycle=Lifecycle.PENDING_DELETE)

    assert listed(admin_client.get(CHANGELIST, {"state__exact": "FAILED"})) == ["m-failed"]
    assert listed(admin_client.get(CHANGELIST, {"failure_category__exact": "TIMEOUT"})) == ["m-failed"]
    assert listed(admin_client.get(CHANGELIST, {"lifecycle__exact": "PENDING_DELETE"})) == ["m-leaving"]
    assert listed(admin_client.get(CHANGELIST, {"q": "carter02"})) == ["m-leaving", "m-queued"]
    assert listed(admin_client.get(CHANGELIST, {"q": "m-queued"})) == ["m-queued"]


def test_changelist_drills_down_by_start_date(admin_client: Client):
    MissionFactory(name="old", running=True, start_timestamp=datetime(2024, 3, 1, tzinfo=UTC))
    MissionFactory(name="new", running=True, start_timestamp=datetime(2025, 6, 1, tzinfo=UTC))

    assert listed(admin_client.get(CHANGELIST, {"start_timestamp__year": "2024"})) == ["old"]


def test_change_page_shows_the_tree_with_node_states(admin_client: Client, picking_mission: Mission):
    rows = mission_tree_rows(picking_mission)

    response = admin_client.get(change_url(picking_mission))

    assert [(row.name, row.kind, row.params, row.depth, row.error_msg) for row in rows] == [
        ("root", "sequence", "", 0, ""),
        ("goto", "route", "2 waypoint(s)", 1, ""),
        ("pick", "selector", "", 1, ""),
        ("grab", "action", 'action_type gripper_close, parameters {"force": 5}', 2, "Action failure"),
        ("tell", "notify", "url http://wms.local/done", 2, ""),
        ("finish", "constant", "success", 1, ""),
    ]
    assert [row.name for row in rows if row.is_current] == ["tell"]
    assert [state for row in rows for state in MissionState.values if f">{state}</span>" in row.badge] == [
        "RUNNING",
        "COMPLETED",
        "RUNNING",
        "FAILED",
        "RUNNING",
        "PENDING",
    ]
    assert response.status_code == 200
    content = response.content.decode()
    for row in rows:
        assert f'<td style="padding-left: {row.indent_px}px">' in content
        assert row.badge in content
    assert "<td>Action failure</td>" in content
    assert "<strong>tell</strong> &#x25C0; current" in content


def test_tree_view_shows_updated_route_waypoints():
    mission = MissionFactory(update_nodes={"goto": route_node("goto", (0, 0), (1, 1), (2, 2))["route"]})

    assert mission_tree_rows(mission)[1].params == "3 waypoint(s) (updated)"


def test_change_page_of_a_mission_with_an_invalid_stored_tree_still_renders(admin_client: Client):
    mission = MissionFactory(mission_tree=[route_node("lost", parent="nowhere")], node_status={})

    response = admin_client.get(change_url(mission))

    assert response.status_code == 200
    assert (
        "The stored mission tree is invalid: Given parent nowhere does not exist" in response.content.decode()
    )


def test_missions_cannot_be_added_or_edited(admin_client: Client):
    mission = MissionFactory(name="fixed")

    assert admin_client.get(reverse("admin:missions_mission_add")).status_code == 403
    response = admin_client.post(change_url(mission), {"state": "COMPLETED", "robot": "other"})

    assert response.status_code == 403
    mission.refresh_from_db()
    assert (mission.state, mission.robot) == (MissionState.PENDING, "carter01")


def test_cancel_action_cancels_a_queued_mission_and_reports_a_completed_one(admin_client: Client):
    queued = MissionFactory(name="queued")
    done = MissionFactory(name="done", completed=True)

    response = admin_client.post(
        CHANGELIST, {"action": "cancel_missions", "_selected_action": [queued.name, done.name]}
    )

    assert response.status_code == 302
    assert dict(Mission.objects.values_list("name", "state")) == {
        "queued": MissionState.CANCELED,
        "done": MissionState.COMPLETED,
    }
    assert sent_messages(response) == [
        (messages.SUCCESS, "Cancel requested for 1 mission."),
        (messages.WARNING, "Completed mission done can't be canceled."),
    ]


def test_cancel_action_asks_the_engine_to_cancel_a_running_mission(admin_client: Client, woken: list[str]):
    running = MissionFactory(name="running", robot="carter05", running=True)

    admin_client.post(CHANGELIST, {"action": "cancel_missions", "_selected_action": [running.name]})

    running.refresh_from_db()
    assert (running.state, running.needs_canceled) == (MissionState.RUNNING, True)
    assert woken == ["carter05"]


def test_delete_removes_a_queued_mission(admin_client: Client):
    mission = MissionFactory()

    response = admin_client.post(
        reverse("admin:missions_mission_delete", args=[mission.name]), {"post": "yes"}
    )

    assert response.status_code == 302
    assert not Mission.objects.exists()
    assert [level for level, _ in sent_messages(response)] == [messages.SUCCESS]


def test_deleting_one_running_mission_goes_through_the_service(admin_client: Client):
    running = MissionFactory(name="running", running=True)

    admin_client.post(reverse("admin:missions_mission_delete", args=[running.name]), {"post": "yes"})

    # The service keeps it until its robot confirms the cancel; Django's own delete would remove the row.
    assert list(Mission.objects.values_list("name", "lifecycle", "needs_canceled")) == [
        ("running", Lifecycle.PENDING_DELETE, True)
    ]


def test_bulk_delete_leaves_a_running_mission_pending_delete(admin_client: Client):
    running = MissionFactory(name="running", running=True)
    done = MissionFactory(name="done", completed=True)

    response = admin_client.post(
        CHANGELIST,
        {"action": "delete_selected", "_selected_action": [running.name, done.name], "post": "yes"},
    )

    assert response.status_code == 302
    assert list(Mission.objects.values_list("name", "lifecycle", "needs_canceled")) == [
        ("running", Lifecycle.PENDING_DELETE, True)
    ]
    assert (
        messages.INFO,
        "PENDING_DELETE until their robot has confirmed the cancel: running.",
    ) in sent_messages(response)


def test_unbound_missions_are_listed_with_their_reason_and_priority_and_filtered(admin_client: Client):
    MissionFactory(name="named", robot="carter01")
    MissionFactory(name="free", robot=None, priority=7, waiting_reason="Every capable robot is busy")

    response = admin_client.get(CHANGELIST, {"robot__isempty": "1"})

    assert listed(response) == ["free"]
    content = response.content.decode()
    assert "(unbound)" in content and "Every capable robot is busy" in content
    assert admin_client.get(change_url(Mission.objects.get(name="free"))).status_code == 200


def test_priority_actions_change_a_queued_missions_priority_through_the_service(admin_client: Client):
    queued = MissionFactory(name="queued", robot=None, priority=995)
    done = MissionFactory(name="done", completed=True)

    admin_client.post(CHANGELIST, {"action": "lower_priority", "_selected_action": [queued.name]})
    assert Mission.objects.get(name="queued").priority == 985
    response = admin_client.post(
        CHANGELIST, {"action": "raise_priority", "_selected_action": [queued.name, done.name]}, follow=True
    )

    assert Mission.objects.get(name="queued").priority == 995
    assert Mission.objects.get(name="done").priority == 0
    assert any(level == messages.WARNING for level, _ in sent_messages(response))
    response = admin_client.post(
        CHANGELIST, {"action": "raise_priority", "_selected_action": [queued.name]}, follow=True
    )
    assert Mission.objects.get(name="queued").priority == 995  # 1005 is out of range
    assert any("within -1000..1000" in text for _, text in sent_messages(response))

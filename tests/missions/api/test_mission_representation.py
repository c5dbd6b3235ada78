"""The hand-built mission representation says exactly what the declared serializer fields say."""

from datetime import UTC, datetime

import pytest
from rest_framework import serializers

from missions.api.serializers import MissionSerializer
from missions.models import Mission
from tests.readme import README_MISSIONS

pytestmark = pytest.mark.django_db


def declared_representation(mission: Mission) -> dict:
    """What DRF's generic Serializer.to_representation makes of the declared fields."""
    return serializers.Serializer.to_representation(MissionSerializer(), mission)


@pytest.mark.parametrize("example", README_MISSIONS.values(), ids=README_MISSIONS.keys())
def test_readme_missions_are_represented_as_declared(api, example) -> None:
    assert api.post("/mission", example, format="json").status_code == 200
    mission = Mission.objects.get(name=example["name"])
    assert MissionSerializer(mission).data == declared_representation(mission)


def test_a_finished_updated_waiting_mission_is_represented_as_declared(api) -> None:
    tree = [
        {"name": "go", "route": {"waypoints": [{"x": 1, "y": 2}]}},
        {"name": "s", "selector": {}},
        {"name": "act", "parent": "s", "action": {"action_type": "beep", "action_parameters": {"n": 2}}},
        {"name": "tell", "notify": {"url": "http://example.com/x", "json_data": {"a": [1]}}},
        {"name": "turn", "move": {"rotation": 1.5}},
        {"name": "no", "constant": {"success": False}},
    ]
    body = {"name": "m", "robot": "r1", "mission_tree": tree, "deadline": "2030-01-02T03:04:05.678Z"}
    assert api.post("/mission", body, format="json").status_code == 200
    update = {"go": {"waypoints": [{"x": 3, "y": 4}]}}
    assert api.post("/mission/m/update", update, format="json").status_code == 200
    mission = Mission.objects.get(name="m")
    mission.state = "FAILED"
    mission.start_timestamp = datetime(2030, 1, 1, tzinfo=UTC)
    mission.end_timestamp = datetime(2030, 1, 1, 0, 0, 1, 500, tzinfo=UTC)
    mission.failure_reason, mission.failure_category = "Mission timed out", "TIMEOUT"
    mission.waiting_reason = "Robot is offline"
    mission.task_status = {"go": 1}
    assert MissionSerializer(mission).data == declared_representation(mission)

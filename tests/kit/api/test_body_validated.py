"""kit.api.serializers.body_validated: one shared serializer per class gives every request, in every
thread, what a fresh serializer's is_valid() gives."""

from concurrent.futures import ThreadPoolExecutor

import pytest
from rest_framework.exceptions import ValidationError

from kit.api.serializers import body_validated
from missions.api.serializers import MissionCreateSerializer

THREADS = 8


def body(number: int) -> dict:
    """A valid mission body, or (every third) one with errors at several depths."""
    waypoint = {"x": number, "y": -number} if number % 3 else {"x": "far", "z": number}
    nodes = [{"name": f"n{number}", "route": {"waypoints": [waypoint]}}, {"move": {"rotation": number}}]
    return {"robot": f"r{number}", "mission_tree": nodes, "timeout": number + 1}


def outcome(validate, data: dict) -> tuple[str, object]:
    try:
        return ("valid", validate(data))
    except ValidationError as error:
        return ("invalid", error.detail)


def fresh(data: dict) -> dict:
    serializer = MissionCreateSerializer(data=data)
    serializer.is_valid(raise_exception=True)
    return serializer.validated_data


def test_shared_validation_matches_a_fresh_serializer_in_concurrent_threads():
    bodies = [body(number) for number in range(300)]

    with ThreadPoolExecutor(THREADS) as pool:
        shared = list(
            pool.map(lambda data: outcome(lambda d: body_validated(MissionCreateSerializer, d), data), bodies)
        )

    assert shared == [outcome(fresh, data) for data in bodies]
    assert {kind for kind, _ in shared} == {"valid", "invalid"}


@pytest.mark.parametrize("data", [None, [], "go", {}])
def test_errors_of_bodies_that_are_no_object_are_is_valids(data):
    assert outcome(lambda d: body_validated(MissionCreateSerializer, d), data) == outcome(fresh, data)

"""GET /health and GET /behaviors."""

import pytest


def test_health(api):
    response = api.get("/health")

    assert response.status_code == 200
    assert response.json() == {"status": "Mission Dispatch: Running"}


def test_behaviors_lists_every_node_kind_with_its_parameters(api):
    response = api.get("/behaviors")

    assert response.status_code == 200
    assert [(behavior["name"], behavior["params"]) for behavior in response.json()] == [
        ("route", ["waypoints"]),
        ("move", ["distance", "rotation"]),
        ("action", ["action_type", "action_parameters"]),
        ("notify", ["url", "json_data", "timeout"]),
        ("constant", ["success"]),
        ("sequence", []),
        ("selector", []),
    ]
    assert all(
        behavior["description"] and "\n" not in behavior["description"] for behavior in response.json()
    )


@pytest.mark.django_db
def test_unknown_paths_are_404(api):
    assert api.get("/robots").status_code == 404

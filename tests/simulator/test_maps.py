"""Simulated robots' maps (2.1+): reported in state.maps, managed by downloadMap, enableMap and deleteMap,
and required for orders; every message checked against its version's schema."""

from __future__ import annotations

import pytest

from tests.simulator.conftest import RobotHarness, route
from vda5050.maps import map_action_parameters
from vda5050.models import ActionStatus, ActionType, MapStatus
from vda5050.orders import instant_action

SPECS = {
    "2.1.0": "carter21,0,0,0,map,0,20,RobotCompany,carter21,CARRIER,2.1.0",
    "3.0.0": "carter30,0,0,0,map,0,20,RobotCompany,carter30,CARRIER,3.0.0",
}


def map_action(action_type: str, action_id: str, map_id: str, version: str, **extra: str):
    return instant_action(
        action_type,
        action_id,
        map_action_parameters(action_type, map_id=map_id, map_version=version, **extra),
    )


def download(action_id: str, map_id: str, version: str):
    link = f"https://maps.example/{map_id}/{version}"
    return map_action(ActionType.DOWNLOAD_MAP, action_id, map_id, version, map_download_link=link)


def maps(h: RobotHarness) -> set[tuple[str, str, MapStatus]]:
    return {(m.map_id, m.map_version, m.map_status) for m in h.state.maps or ()}


def status(h: RobotHarness, action_id: str) -> ActionStatus:
    states = [*h.state.action_states, *(h.state.instant_action_states or ())]
    return next(a.action_status for a in states if a.action_id == action_id)


@pytest.fixture(params=sorted(SPECS))
def h(request) -> RobotHarness:
    return RobotHarness(SPECS[request.param], tick_period=0.25)


def test_a_robot_reports_its_configured_map_enabled_and_a_2_0_robot_no_maps(h: RobotHarness) -> None:
    assert maps(h) == {("map", "1", MapStatus.ENABLED)}
    assert RobotHarness("old,0,0").state.maps is None


def test_a_download_runs_then_the_map_is_there_disabled(h: RobotHarness) -> None:
    h.send_actions(download("d1", "hall", "2"))
    assert status(h, "d1") == ActionStatus.RUNNING
    assert ("hall", "2", MapStatus.DISABLED) not in maps(h)

    h.run(1.0)

    assert status(h, "d1") == ActionStatus.FINISHED
    assert maps(h) == {("map", "1", MapStatus.ENABLED), ("hall", "2", MapStatus.DISABLED)}


def test_enabling_a_version_disables_the_other_versions_of_its_map(h: RobotHarness) -> None:
    h.send_actions(download("d2", "map", "2"))
    h.run(1.0)

    h.send_actions(map_action(ActionType.ENABLE_MAP, "e2", "map", "2"))

    assert status(h, "e2") == ActionStatus.FINISHED
    assert maps(h) == {("map", "1", MapStatus.DISABLED), ("map", "2", MapStatus.ENABLED)}


def test_delete_removes_a_version(h: RobotHarness) -> None:
    h.send_actions(download("d1", "hall", "2"))
    h.run(1.0)

    h.send_actions(map_action(ActionType.DELETE_MAP, "x1", "hall", "2"))

    assert status(h, "x1") == ActionStatus.FINISHED
    assert maps(h) == {("map", "1", MapStatus.ENABLED)}


def test_a_duplicate_download_and_actions_on_maps_the_robot_lacks_fail_with_an_error(h: RobotHarness) -> None:
    h.send_actions(
        download("dup", "map", "1"),
        map_action(ActionType.ENABLE_MAP, "e9", "hall", "9"),
        map_action(ActionType.DELETE_MAP, "x9", "hall", "9"),
    )

    assert [status(h, a) for a in ("dup", "e9", "x9")] == [ActionStatus.FAILED] * 3
    types = {e.error_type for e in h.state.errors}
    assert types == ({"DUPLICATE_MAP", "UNKNOWN_MAP_ID"} if h.robot.is_3 else {"duplicateMap", "unknownMap"})
    assert maps(h) == {("map", "1", MapStatus.ENABLED)}


def test_an_order_on_a_map_not_enabled_is_rejected_and_taken_once_it_is(h: RobotHarness) -> None:
    order = route((2.0, 0.0))
    order.nodes[-1].node_position.map_id = "hall"
    h.send_order(order)
    assert h.state.order_id == ""
    assert any("not enabled" in (e.error_description or "") for e in h.state.errors)

    h.send_actions(download("d1", "hall", "1"))
    h.run(1.0)
    h.send_actions(map_action(ActionType.ENABLE_MAP, "e1", "hall", "1"))
    h.send_order(order)

    assert h.state.order_id == order.order_id

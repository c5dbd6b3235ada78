"""Maps (VDA 5050 2.1+): a mission waits for the maps its waypoints name; map actions are sent with their
parameters and tracked to their end."""

import orjson
import pytest

from dispatch.held import state_digest
from dispatch.records import ActionRecord
from dispatch.vocabulary import MissionState
from tests.dispatch.builders import (
    IDLE_STATE,
    NOW,
    ROBOT,
    Dispatcher,
    checked_step,
    finished,
    instant_actions_sent,
    mission,
    move,
    orders_sent,
    robot_state,
    route,
)
from tests.vda5050.schemas import validate_message
from vda5050.codec import encode, header_for
from vda5050.errors import ProtocolError
from vda5050.maps import map_action_parameters, maps_not_enabled
from vda5050.models import ActionStatus, ActionType, Map, MapStatus, State
from vda5050.orders import instant_action as wire_action
from vda5050.orders import instant_actions
from vda5050.topics import RobotAddress


def with_maps(state: State, *maps: tuple[str, str, MapStatus]) -> State:
    return state.model_copy(update={"maps": [Map(map_id=i, map_version=v, map_status=s) for i, v, s in maps]})


def test_a_mission_on_a_map_the_robot_lacks_is_held_with_the_map_named() -> None:
    state = with_maps(IDLE_STATE, ("other", "1", MapStatus.ENABLED))

    result = checked_step(state=state, mission=mission(route("r")))

    assert result.mission is not None
    assert result.mission.state == MissionState.PENDING
    assert result.mission.waiting_reason == "Waiting for map map to be enabled on the robot"
    assert result.messages == []


def test_a_map_the_robot_has_only_disabled_holds_the_mission_too() -> None:
    state = with_maps(IDLE_STATE, ("map", "1", MapStatus.DISABLED), ("map", "2", MapStatus.DISABLED))

    result = checked_step(state=state, mission=mission(route("r")))

    assert result.mission is not None and result.mission.state == MissionState.PENDING
    assert "map map" in (result.mission.waiting_reason or "")


def test_every_missing_map_of_every_route_is_named_once() -> None:
    state = with_maps(IDLE_STATE, ("map", "1", MapStatus.ENABLED))
    tree = [route("a", map_id="hall"), route("b", map_id="yard"), route("c", map_id="hall"), route("d")]

    result = checked_step(state=state, mission=mission(*tree))

    assert result.mission is not None
    assert result.mission.waiting_reason == "Waiting for map hall, yard to be enabled on the robot"


def test_the_mission_starts_once_the_robot_reports_the_map_enabled() -> None:
    held = checked_step(state=with_maps(IDLE_STATE, ("map", "1", MapStatus.DISABLED)), mission=mission())
    assert held.mission is not None

    result = checked_step(
        state=with_maps(IDLE_STATE, ("map", "1", MapStatus.DISABLED), ("map", "2", MapStatus.ENABLED)),
        mission=held.mission,
    )

    assert result.mission is not None
    assert (result.mission.state, result.mission.waiting_reason) == (MissionState.RUNNING, None)
    assert len(orders_sent(result)) == 1


@pytest.mark.parametrize("maps", [None, []], ids=["no maps field (2.0)", "empty maps"])
def test_a_robot_that_reports_no_maps_is_not_held(maps) -> None:
    state = IDLE_STATE.model_copy(update={"maps": maps})

    result = checked_step(state=state, mission=mission(route("r", map_id="anything")))

    assert result.mission is not None and result.mission.state == MissionState.RUNNING
    assert len(orders_sent(result)) == 1


def test_a_later_route_leaf_whose_map_went_away_waits_and_goes_once_it_is_back() -> None:
    enabled = ("map", "1", MapStatus.ENABLED)
    hall = ("hall", "1", MapStatus.ENABLED)
    run = Dispatcher(mission(move("a"), route("b", map_id="hall")))  # a route after a route goes ahead
    run.step(with_maps(IDLE_STATE, enabled, hall))
    first = run.order
    assert run.mission is not None and run.mission.state == MissionState.RUNNING

    # The hall map was deleted while the first leaf ran: the second leaf waits.
    result = run.step(with_maps(finished(first), enabled), after=1)
    assert orders_sent(result) == []
    assert run.mission is not None
    assert run.mission.waiting_reason == "Waiting for map hall to be enabled on the robot"
    assert run.mission.node_status["b"]["state"] == MissionState.PENDING

    result = run.step(with_maps(finished(first), enabled, hall), after=1)
    assert [o.nodes[-1].node_position.map_id for o in orders_sent(result)] == ["hall"]
    assert run.mission.waiting_reason is None


@pytest.mark.parametrize(
    ("action_type", "extra"),
    [
        (ActionType.DOWNLOAD_MAP, {"map_download_link": "https://maps.example/hall/2", "map_hash": "ab12"}),
        (ActionType.DOWNLOAD_MAP, {"map_download_link": "https://maps.example/hall/2"}),
        (ActionType.ENABLE_MAP, {}),
        (ActionType.DELETE_MAP, {}),
    ],
)
@pytest.mark.parametrize("version", ["2.1.0", "3.0.0"])
def test_map_actions_conform_to_the_schemas_of_the_versions_with_maps(action_type, extra, version) -> None:
    parameters = map_action_parameters(action_type, map_id="hall", map_version="2", **extra)
    content = instant_actions([wire_action(action_type, "a1", parameters)])
    header = header_for(RobotAddress("uagv", "RobotCompany", ROBOT, version), header_id=1, at=NOW)

    message = orjson.loads(encode(content, header))

    validate_message("instantActions", version, message)
    [sent] = message["actions"]
    assert sent["actionType"] == action_type
    assert {p["key"]: p["value"] for p in sent["actionParameters"]} == {
        "mapId": "hall",
        "mapVersion": "2",
        **({"mapDownloadLink": extra["map_download_link"]} if extra else {}),
        **({"mapHash": extra["map_hash"]} if "map_hash" in extra else {}),
    }


@pytest.mark.parametrize(
    ("action_type", "extra", "message"),
    [
        (ActionType.DOWNLOAD_MAP, {}, "downloadMap needs a mapDownloadLink"),
        (ActionType.ENABLE_MAP, {"map_hash": "ab"}, "enableMap takes no mapDownloadLink or mapHash"),
        (ActionType.CANCEL_ORDER, {}, "cancelOrder is not a map action"),
    ],
)
def test_map_action_parameters_refuse_what_the_action_does_not_take(action_type, extra, message) -> None:
    with pytest.raises(ProtocolError, match=message):
        map_action_parameters(action_type, map_id="hall", map_version="2", **extra)


def test_a_map_action_is_sent_with_its_parameters_and_tracked_until_finished() -> None:
    parameters = map_action_parameters(ActionType.ENABLE_MAP, map_id="hall", map_version="2")
    enable = ActionRecord(
        action_id=f"{ROBOT}-enableMap-1",
        action_type=ActionType.ENABLE_MAP,
        mission=None,
        status=None,
        sent_at=None,
        parameters=parameters,
    )
    run = Dispatcher(None, actions=[enable])

    [sent] = instant_actions_sent(run.step(IDLE_STATE))
    assert {p.key: p.value for p in sent.action_parameters or ()} == parameters

    running = robot_state(action_states=[(enable.action_id, ActionStatus.RUNNING, "enableMap")])
    [record] = run.step(running, after=1).actions
    assert record.status == ActionStatus.RUNNING

    done = robot_state(action_states=[(enable.action_id, ActionStatus.FINISHED, "enableMap")])
    [record] = run.step(with_maps(done, ("hall", "2", MapStatus.ENABLED)), after=1).actions
    assert record.status == ActionStatus.FINISHED
    assert run.actions == []


def test_a_change_of_maps_is_an_event_that_needs_a_step() -> None:
    before = state_digest(with_maps(IDLE_STATE, ("hall", "2", MapStatus.DISABLED)))
    after = state_digest(with_maps(IDLE_STATE, ("hall", "2", MapStatus.ENABLED)))

    assert before.events != after.events


def test_maps_not_enabled_ignores_empty_map_ids_and_robots_without_maps() -> None:
    state = with_maps(IDLE_STATE, ("hall", "2", MapStatus.ENABLED))

    assert maps_not_enabled(state, ["hall", "", "yard", "yard"]) == ["yard"]
    assert maps_not_enabled(IDLE_STATE, ["yard"]) == []

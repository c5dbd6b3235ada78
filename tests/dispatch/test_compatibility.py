"""Vehicle compatibility rules in the pure step (`vda5050.compat`), and 3.0's error levels and modes.

The robot's answers are those of the real npm `vda-5050-lib` 1.4.0 virtual AGV (recorded from it)."""

from datetime import timedelta

import pytest

from dispatch.vocabulary import MissionState
from tests.dispatch.builders import (
    NOW,
    checked_step,
    error,
    instant_action,
    instant_actions_sent,
    on_order,
    robot_state,
    robot_view,
    route,
    started,
)
from vda5050.compat import Rule, actions_key_rejection
from vda5050.models import ActionStatus, ActionType, ErrorLevel, OperatingMode

# What vda-5050-lib 1.4.0 reports for instant actions under the 2.0 key `actions`.
LIB_1_4_REJECTION = error(
    "validationError",
    ErrorLevel.WARNING,
    "invalid instant actions: TypeError: Invalid VDA 5050 InstantActions"
    " at #/allOf/1/required, #/instantActions",
    topic="instantActions",
    headerId="0",
)


# ... and for a cancelOrder while it has no order: this error, and no action state at all.
def lib_1_4_no_order_to_cancel(action_id: str):
    return error(
        "noOrderToCancel",
        ErrorLevel.WARNING,
        "instant action is not executable: no active order to be canceled",
        topic="instantActions",
        actionId=action_id,
        actionType="cancelOrder",
    )


def test_a_robot_rejecting_actions_gets_them_again_at_once_under_the_legacy_key() -> None:
    sent = instant_action(ActionType.FACTSHEET_REQUEST, sent_at=NOW)

    result = checked_step(
        state=robot_state(errors=[LIB_1_4_REJECTION]),
        mission=None,
        actions=[sent],
        now=NOW + timedelta(seconds=1),
    )

    assert result.instant_actions_key == "instantActions"
    assert [rule for rule, _ in result.rules_applied] == [Rule.LEGACY_INSTANT_ACTIONS_KEY]
    assert "#/instantActions" in result.rules_applied[0][1]
    [resent] = instant_actions_sent(result)  # well before the resend period
    assert resent.action_id == sent.action_id
    assert result.actions[0].send_count == 2


@pytest.mark.parametrize(
    "robot",
    [
        pytest.param(
            robot_view(instant_actions_key="actions", instant_actions_key_by_operator=True),
            id="operator-chose",
        ),
        pytest.param(robot_view(instant_actions_key="instantActions"), id="already-legacy"),
    ],
)
def test_the_key_rule_leaves_an_operators_choice_and_a_legacy_robot_alone(robot) -> None:
    sent = instant_action(ActionType.FACTSHEET_REQUEST, sent_at=NOW)

    result = checked_step(
        state=robot_state(errors=[LIB_1_4_REJECTION]),
        mission=None,
        robot=robot,
        actions=[sent],
        now=NOW + timedelta(seconds=1),
    )

    assert (result.instant_actions_key, result.rules_applied, result.messages) == (None, [], [])


def test_the_key_rule_needs_an_instant_action_in_flight() -> None:
    result = checked_step(state=robot_state(errors=[LIB_1_4_REJECTION]), mission=None, actions=[])

    assert (result.instant_actions_key, result.rules_applied) == (None, [])


@pytest.mark.parametrize(
    ("description", "references", "names_key"),
    [
        ("Invalid VDA 5050 InstantActions at #/allOf/1/required, #/instantActions", {}, True),
        ("'instantActions' is a required property", {}, True),
        ("missing property instantActions", {}, True),
        ("invalid instantActions message: actions[0].blockingType", {"topic": "instantActions"}, False),
        ("bad", {"field": "instantActions"}, True),
        ("blockingType HARD not allowed", {"topic": "instantActions"}, False),
    ],
)
def test_which_validation_errors_name_the_legacy_key(
    description: str, references: dict, names_key: bool
) -> None:
    state = robot_state(errors=[error("validationError", ErrorLevel.WARNING, description, **references)])

    assert (actions_key_rejection(state) is not None) is names_key


def test_an_order_validation_error_is_not_a_key_rejection() -> None:
    state = robot_state(errors=[error("orderError", ErrorLevel.WARNING, "#/instantActions")])

    assert actions_key_rejection(state) is None


def test_a_cancel_refused_only_by_an_error_counts_as_failed_and_the_queue_goes_on() -> None:
    cancel = instant_action(ActionType.CANCEL_ORDER, "m0-n0-r0-cancel-1", sent_at=NOW)

    result = checked_step(
        state=robot_state(errors=[lib_1_4_no_order_to_cancel(cancel.action_id)]),
        mission=None,
        actions=[cancel],
        now=NOW + timedelta(seconds=1),
    )

    assert result.actions[0].status == ActionStatus.FAILED
    assert [rule for rule, _ in result.rules_applied] == [Rule.CANCEL_REFUSED_BY_ERROR_ONLY]


def test_a_cancel_the_robot_reports_needs_no_rule() -> None:
    cancel = instant_action(ActionType.CANCEL_ORDER, "m0-n0-r0-cancel-1", sent_at=NOW)
    state = robot_state(
        action_states=[(cancel.action_id, ActionStatus.FAILED)],
        errors=[lib_1_4_no_order_to_cancel(cancel.action_id)],
    )

    result = checked_step(state=state, mission=None, actions=[cancel])

    assert (result.actions[0].status, result.rules_applied) == (ActionStatus.FAILED, [])


def test_a_critical_error_about_the_order_fails_the_leaf_but_leaves_the_robot_available() -> None:
    dispatcher = started(route("r", (1.0, 0.0)))
    critical = error(
        "NODE_UNREACHABLE", ErrorLevel.CRITICAL, "cannot reach", nodeId=f"{dispatcher.order.order_id}-s2"
    )

    dispatcher.step(on_order(dispatcher.order, 0, errors=[critical]), after=1.0)

    assert dispatcher.mission.state == MissionState.FAILED
    assert dispatcher.mission.failure_reason == "cannot reach"


def test_an_intervened_robot_gets_only_its_cancel() -> None:
    actions = [instant_action(ActionType.START_TELEOP), instant_action(ActionType.CANCEL_ORDER, "x-cancel-1")]

    result = checked_step(
        state=robot_state(operating_mode=OperatingMode.INTERVENED), mission=None, actions=actions
    )

    assert [a.action_type for a in instant_actions_sent(result)] == [ActionType.CANCEL_ORDER]

"""The current leaf's order: resent until the robot accepts it, failed when the robot rejects it."""

import pytest

from dispatch.held import ORDER_ECHO
from dispatch.vocabulary import MissionState
from tests.dispatch.builders import (
    IDLE_STATE,
    SETTINGS,
    action,
    error,
    finished,
    on_order,
    orders_sent,
    robot_state,
    route,
    selector,
    started,
    wire,
)
from vda5050.models import ErrorLevel, OperatingMode


def test_an_unaccepted_order_is_not_resent_before_the_resend_period() -> None:
    dispatcher = started()

    result = dispatcher.step(IDLE_STATE, after=SETTINGS.order_resend.total_seconds() - 0.001)

    assert result.messages == []
    assert dispatcher.mission.order_sent_at == dispatcher.results[0].mission.order_sent_at


def test_an_unaccepted_order_is_resent_after_the_resend_period_with_identical_content() -> None:
    dispatcher = started(route("r", (5.0, 6.0), (7.0, 8.0)))
    [first] = orders_sent(dispatcher.results[0])

    result = dispatcher.step(IDLE_STATE, after=SETTINGS.order_resend.total_seconds())

    [resent] = orders_sent(result)
    assert wire(resent) == wire(first)
    assert dispatcher.mission.order_sent_at == dispatcher.now
    assert dispatcher.mission.attempts == {"r": 1}


def test_a_resent_order_is_not_resent_again_before_another_resend_period() -> None:
    dispatcher = started()
    dispatcher.step(IDLE_STATE, after=3.0)

    result = dispatcher.step(IDLE_STATE, after=2.0)

    assert result.messages == []


def test_a_state_that_may_have_left_the_robot_before_the_order_reached_it_is_no_reason_to_resend() -> None:
    """A bridge behind on a busy fleet stores states late: one that arrived within ORDER_ECHO of the order
    says nothing about whether the robot got it, however late the step that reads it."""
    dispatcher = started()
    sent_at = dispatcher.mission.order_sent_at

    late = dispatcher.step(IDLE_STATE, after=10.0, arrived_at=sent_at + ORDER_ECHO / 2)
    evidence = dispatcher.step(IDLE_STATE, after=0.0, arrived_at=sent_at + ORDER_ECHO)

    assert late.messages == []
    assert orders_sent(evidence)


def test_a_state_from_before_the_order_does_not_make_it_resend_early() -> None:
    """A state from before the order was sent (the robot's old order) is no reason to resend early."""
    dispatcher = started()

    result = dispatcher.step(robot_state(order_id="previous-n0-r0", last_node_sequence_id=4), after=1.0)

    assert result.messages == []


def test_acceptance_is_recorded_once_the_robot_reports_the_order() -> None:
    dispatcher = started(route("r", (5.0, 6.0), (7.0, 8.0)))

    result = dispatcher.step(on_order(dispatcher.order, 0), after=1.0)

    assert dispatcher.mission.order_accepted is True
    assert dispatcher.node("r") == MissionState.RUNNING
    assert result.messages == []


def test_an_accepted_order_is_never_resent() -> None:
    dispatcher = started()
    dispatcher.step(on_order(dispatcher.order, 0), after=1.0)

    result = dispatcher.step(on_order(dispatcher.order, 0), after=60.0)

    assert result.messages == []


@pytest.mark.parametrize(
    "rejection",
    [
        pytest.param(
            error("validationError", ErrorLevel.WARNING, "nodePosition missing", orderId="m1-n0-r0"),
            id="warning-validation-error",
        ),
        pytest.param(
            error(
                "orderError", ErrorLevel.FATAL, "nodePosition missing", orderId="m1-n0-r0", orderUpdateId="0"
            ),
            id="fatal-order-error",
        ),
        pytest.param(
            error("noRouteError", ErrorLevel.WARNING, "nodePosition missing", order_id="m1-n0-r0"),
            id="vendor-type-snake-key",
        ),
    ],
)
def test_a_rejected_order_fails_the_leaf_with_the_errors_description(rejection) -> None:
    dispatcher = started()

    result = dispatcher.step(robot_state(order_id="", errors=[rejection]), after=0.5)

    assert result.rejected is True
    assert dispatcher.mission.node_status["r"] == {
        "state": MissionState.FAILED,
        "error_msg": "nodePosition missing",
    }
    assert dispatcher.mission.failure_reason == "nodePosition missing"
    assert dispatcher.mission.state == MissionState.FAILED
    assert result.messages == []


def test_a_rejection_without_description_is_described_by_its_error_type() -> None:
    dispatcher = started()

    dispatcher.step(robot_state(errors=[error("orderError", orderId="m1-n0-r0")]), after=0.5)

    assert dispatcher.mission.node_status["r"]["error_msg"] == "orderError"


def test_an_error_referencing_another_order_is_no_rejection() -> None:
    dispatcher = started()

    result = dispatcher.step(robot_state(errors=[error("orderError", orderId="m1-n0-r7")]), after=0.5)

    assert result.rejected is False
    assert (dispatcher.mission.state, dispatcher.node("r")) == (MissionState.RUNNING, MissionState.RUNNING)


def test_an_error_naming_another_update_of_the_order_is_no_rejection() -> None:
    dispatcher = started()

    dispatcher.step(
        robot_state(errors=[error("orderError", orderId="m1-n0-r0", orderUpdateId="3")]), after=0.5
    )

    assert dispatcher.node("r") == MissionState.RUNNING


def test_a_rejected_leaf_in_a_selector_moves_on_to_the_next_leafs_order() -> None:
    dispatcher = started(selector("s"), action("a", parent="s"), route("r", parent="s"))

    result = dispatcher.step(robot_state(errors=[error("orderError", orderId="m1-n1-r0")]), after=0.5)

    assert result.rejected is True
    assert (dispatcher.node("a"), dispatcher.node("r")) == (MissionState.FAILED, MissionState.RUNNING)
    assert [order.order_id for order in orders_sent(result)] == ["m1-n2-r0"]
    assert dispatcher.mission.current_node == 2


def test_a_robot_that_accepts_and_finishes_in_one_state_completes_the_leaf() -> None:
    dispatcher = started(route("r", (5.0, 6.0), (7.0, 8.0)))

    dispatcher.step(finished(dispatcher.order), after=0.5)

    assert (dispatcher.mission.order_accepted, dispatcher.mission.state) == (True, MissionState.COMPLETED)


def test_an_unaccepted_order_is_not_resent_while_the_robot_is_in_manual_mode() -> None:
    dispatcher = started()

    result = dispatcher.step(robot_state(operating_mode=OperatingMode.MANUAL), after=10.0)

    assert orders_sent(result) == []

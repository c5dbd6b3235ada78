"""A mission assignment bound to a robot that started it but never got its first order accepted goes back to
the pool when the robot becomes unfit (issue 41): PENDING as if new, its order canceled on the robot, the
leaf's attempt count kept so the next robot's orderId is a new one."""

from __future__ import annotations

from dataclasses import replace
from typing import Any

import pytest

from dispatch import engine
from dispatch.records import MissionRecord
from dispatch.vocabulary import Lifecycle, MissionState, RobotState
from tests.dispatch.builders import (
    IDLE_STATE,
    Dispatcher,
    action,
    cancel_actions,
    error,
    finished,
    instant_actions_sent,
    on_order,
    orders_sent,
    robot_state,
    route,
    started,
)
from vda5050.models import ActionType, ErrorLevel

BOUND = [{"robot": "carter01", "bound_at": "2026-03-01T11:59:59.000000Z"}]
OFFLINE = "Robot is offline"


def bound_and_started() -> Dispatcher:
    """A mission assignment bound, started: its first order m1-n0-r0 sent, not yet accepted."""
    dispatcher = started(route("r", (5.0, 6.0)), assignment=BOUND)
    assert [o.order_id for o in orders_sent(dispatcher.results[-1])] == ["m1-n0-r0"]
    return dispatcher


UNFIT: dict[str, tuple[dict[str, Any], Any, str]] = {
    # case: (robot view fields, state, reason)
    "offline": ({"online": False}, None, OFFLINE),
    "low battery": ({}, robot_state(battery=3.0), "Battery 3% is below the robot's critical level 10%"),
    "fatal error": (
        {},
        robot_state(errors=[error("hardwareFault", ErrorLevel.FATAL)]),
        "Robot reports a FATAL error: hardwareFault",
    ),
}


@pytest.mark.parametrize("case", UNFIT)
def test_a_started_mission_whose_first_order_was_never_accepted_is_released_as_new(case: str) -> None:
    fields, state, reason = UNFIT[case]
    dispatcher = bound_and_started()
    dispatcher.robot = replace(dispatcher.robot, **fields)

    result = dispatcher.step(state, after=1.0)

    mission = result.mission
    assert mission is not None and result.release == mission.waiting_reason
    assert mission.waiting_reason.startswith(reason.split(":")[0])
    assert (mission.state, mission.start_timestamp, mission.order, mission.order_sent_at) == (
        MissionState.PENDING,
        None,
        None,
        None,
    )
    tree = engine.parse_tree(mission.mission_tree)
    assert mission.node_status == engine.initial_node_status(tree) and not mission.order_accepted
    assert mission.attempts == {"r": 1}  # the next robot's first order is m1-n0-r1
    assert result.robot_state == RobotState.IDLE and orders_sent(result) == []
    # The order is canceled on the robot, now if it is online, else once it is back.
    [cancel] = cancel_actions(result.actions)
    assert cancel.action_id.startswith("m1-n0-r0-cancel") and cancel.mission == "m1"
    sent = [a.action_type for a in instant_actions_sent(result)]
    assert sent == ([] if case == "offline" else [ActionType.CANCEL_ORDER])


def test_the_next_robot_gets_the_released_mission_under_a_new_order_id() -> None:
    dispatcher = bound_and_started()
    dispatcher.robot = replace(dispatcher.robot, online=False)
    released = dispatcher.step(None, after=1.0).mission
    assert released is not None

    other = Dispatcher(replace(released, waiting_reason=None))
    other.step(IDLE_STATE, after=2.0)

    assert [o.order_id for o in orders_sent(other.results[-1])] == ["m1-n0-r1"]


def test_a_robot_being_deleted_gives_the_mission_back_and_is_deleted_without_a_cancel() -> None:
    dispatcher = bound_and_started()
    dispatcher.robot = replace(dispatcher.robot, lifecycle=Lifecycle.PENDING_DELETE)

    result = dispatcher.step(IDLE_STATE, after=1.0)

    assert result.release == "Robot is being deleted" and result.delete_robot
    assert result.mission is not None and result.mission.state == MissionState.PENDING
    assert cancel_actions(result.actions) == []


def _accepted(dispatcher: Dispatcher) -> MissionRecord:
    dispatcher.step(on_order(dispatcher.order), after=0.5)
    assert dispatcher.mission is not None and dispatcher.mission.order_accepted
    return dispatcher.mission


KEPT = {
    "named, not assigned": lambda: started(route("r", (5.0, 6.0))),
    "first order accepted": lambda: (d := bound_and_started(), _accepted(d), d)[-1],
    "cancel asked for": lambda: (
        d := bound_and_started(),
        setattr(d, "mission", replace(d.mission, needs_canceled=True)),
        d,
    )[-1],
}


@pytest.mark.parametrize("case", KEPT)
def test_a_mission_the_robot_took_up_or_that_was_not_assigned_is_not_released(case: str) -> None:
    dispatcher = KEPT[case]()
    dispatcher.robot = replace(dispatcher.robot, online=False)

    result = dispatcher.step(None, after=1.0)

    assert result.release is None
    assert result.mission is not None and result.mission.state != MissionState.PENDING


def test_a_mission_whose_first_leaf_ended_is_not_released() -> None:
    tree = (route("a", (5.0, 6.0)), action("b", "dummy_action", time=2, should_fail=False))
    dispatcher = started(*tree, assignment=BOUND)
    dispatcher.step(finished(dispatcher.order), after=0.5)
    assert dispatcher.node("a") == MissionState.COMPLETED and not dispatcher.mission.order_accepted
    dispatcher.robot = replace(dispatcher.robot, online=False)

    result = dispatcher.step(None, after=1.0)

    assert result.release is None and result.mission is not None
    assert result.mission.state == MissionState.RUNNING

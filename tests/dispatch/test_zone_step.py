"""The step carrying out the zone plan (`RobotView.zone_reach`): a route's base held back at a zone's edge,
extended by an order update from the robot's decision point, that update re-sent as it was (not the stored
order, stitched, from its first node), and a robot waiting at its decision point with only horizon ahead
not taken for stalled."""

from dataclasses import replace
from datetime import timedelta

from dispatch.records import ZoneReach
from dispatch.step import ZONE_WAITING, step
from tests.dispatch.builders import (
    NOW,
    SETTINGS,
    Dispatcher,
    cancel_actions,
    mission,
    on_order,
    orders_sent,
    robot_state,
    robot_view,
    route,
    wire,
)
from vda5050.models import EdgeState, NodeState, OrderContent, Request, State

ORDER = "m1-n0-r0"
R = route("r", (1.0, 0.0), (2.0, 0.0), (3.0, 0.0))  # nodes 0 (the start), 2, 4, 6
STALL = timedelta(seconds=30)
STALL_SETTINGS = replace(SETTINGS, order_stall=STALL)


def held(order: OrderContent, reached: int) -> State:
    """The robot holding `order` as sent (its horizon unreleased), at the node with sequenceId `reached`."""
    return on_order(order, reached).model_copy(
        update={
            "node_states": [
                NodeState(node_id=n.node_id, sequence_id=n.sequence_id, released=n.released)
                for n in order.nodes
                if n.sequence_id > reached
            ],
            "edge_states": [
                EdgeState(edge_id=e.edge_id, sequence_id=e.sequence_id, released=e.released)
                for e in order.edges
                if e.sequence_id > reached
            ],
        }
    )


def released(order: OrderContent) -> list[int]:
    return [node.sequence_id for node in order.nodes if node.released]


def reaching(through: int, *waiting: str, settings=SETTINGS) -> Dispatcher:
    """A dispatcher of a one-route mission whose robot's zone reach ends at sequenceId `through`."""
    reach = ZoneReach(order_id=ORDER, release_through=through, waiting=waiting)
    return Dispatcher(mission(R), robot=robot_view(zone_reach=reach), settings=settings)


def test_the_base_ends_at_the_reach_and_an_update_from_the_decision_point_extends_it() -> None:
    dispatcher = reaching(2, "aisle")
    [order] = orders_sent(dispatcher.step(robot_state()))
    assert (order.order_id, released(order)) == (ORDER, [0, 2])
    dispatcher.step(held(order, 0), after=1.0)
    assert dispatcher.mission.waiting_reason == f"{ZONE_WAITING} aisle"

    dispatcher.robot = replace(dispatcher.robot, zone_reach=ZoneReach(order_id=ORDER, release_through=6))
    [update] = orders_sent(dispatcher.step(held(order, 2), after=1.0))

    assert (update.order_update_id, [n.sequence_id for n in update.nodes]) == (1, [2, 4, 6])
    assert released(update) == [2, 4, 6]
    assert released(dispatcher.order) == [0, 2, 4, 6] and dispatcher.mission.waiting_reason is None


def test_an_update_the_robot_lacks_is_resent_from_its_decision_point_as_it_was_sent() -> None:
    dispatcher = reaching(2)
    [order] = orders_sent(dispatcher.step(robot_state()))
    dispatcher.step(held(order, 0), after=1.0)
    dispatcher.robot = replace(dispatcher.robot, zone_reach=ZoneReach(order_id=ORDER, release_through=6))
    [update] = orders_sent(dispatcher.step(held(order, 2), after=1.0))
    assert dispatcher.order.nodes[0].sequence_id == 0  # the stored order is stitched: from the start

    [again] = orders_sent(dispatcher.step(held(order, 2), after=SETTINGS.order_resend.total_seconds()))

    assert wire(again) == wire(update)  # from node 2, where the robot waits, not from node 0


def test_a_robot_at_its_decision_point_with_only_horizon_ahead_is_not_stalled() -> None:
    dispatcher = reaching(0, "aisle", settings=STALL_SETTINGS)
    [order] = orders_sent(dispatcher.step(robot_state()))
    waiting = held(order, 0)
    dispatcher.step(waiting, after=1.0)

    for _ in range(3):
        result = dispatcher.step(waiting, after=STALL.total_seconds())
        assert (orders_sent(result), cancel_actions(result.actions)) == ([], [])

    assert dispatcher.node("r") == "RUNNING" and dispatcher.mission.waiting_reason == f"{ZONE_WAITING} aisle"


def test_a_robot_standing_with_released_nodes_ahead_is_stalled_zones_or_not() -> None:
    """The excuse is the horizon alone: a base the robot does not drive is still a stall."""
    dispatcher = reaching(4, settings=STALL_SETTINGS)
    [order] = orders_sent(dispatcher.step(robot_state()))
    standing = held(order, 0)
    dispatcher.step(standing, after=1.0)

    result = dispatcher.step(standing, after=STALL.total_seconds())

    assert cancel_actions(result.actions)


def asking_for_a_plan(requests: list[Request], answered: tuple[str, ...], *, online: bool = True) -> bool:
    """Whether an idle robot's step asks for a zone plan run, given its state's requests and the requestIds
    the plan answered."""
    reach = ZoneReach(responses=tuple((request_id, "GRANTED") for request_id in answered))
    state = robot_state().model_copy(update={"zone_requests": requests})
    result = step(
        now=NOW,
        robot=robot_view(zone_reach=reach, online=online),
        state=state,
        state_arrived_at=NOW,
        mission=None,
        actions=[],
        settings=SETTINGS,
    )
    return result.zones_plan


def zone_request(request_id: str, zone_id: str | None = "aisle", status: str = "REQUESTED") -> Request:
    request_type = "ACCESS" if zone_id is not None else "CORRIDOR"
    return Request(
        request_id=request_id,
        request_type=request_type,
        request_status=status,
        zone_id=zone_id,
        zone_set_id="set" if zone_id is not None else None,
        edge_id=None if zone_id is not None else "e1",
        sequence_id=None if zone_id is not None else 1,
    )


def test_a_step_asks_for_a_plan_run_only_for_zone_requests_the_plan_answers_and_has_not() -> None:
    answered = zone_request("r1")
    assert not asking_for_a_plan([answered], ("r1",))
    assert asking_for_a_plan([answered, zone_request("r2")], ("r1",))  # a new request
    assert asking_for_a_plan([], ("r1",))  # an answer to a request the robot no longer makes
    # Neither an edge request nor one EXPIRED is ever answered: each state would ask again.
    assert not asking_for_a_plan([answered, zone_request("e1", zone_id=None)], ("r1",))
    assert not asking_for_a_plan([answered, zone_request("r3", status="EXPIRED")], ("r1",))
    # The plan answers online robots only.
    assert not asking_for_a_plan([answered, zone_request("r2")], ("r1",), online=False)

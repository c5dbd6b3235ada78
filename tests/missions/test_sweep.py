"""Beat's sweep (`robots_due_for_step`) against the real PostgreSQL and Redis: which robots' orders it has
stepped again, judged by the robots' latest states as the bridge stored them."""

import time
from datetime import timedelta

from django.conf import settings
from django.utils import timezone

from dispatch.held import ORDER_ECHO
from missions.choices import MissionState
from missions.models import Mission
from missions.robot_step import robot_step
from missions.selectors import robots_due_for_step, robots_stalled
from missions.services import mission_create
from missions.tuning import STALLED_MISSION_SECONDS
from robots.models import Robot
from tests.factories import TEST_ACTOR
from tests.workers.bridge.messages import running_order, state_message
from vda5050.models import OrderContent
from workers.bridge.loop import Bridge

END = (5.0, 6.0, 0.0, "map")  # where running_order's route ends
RESEND_DUE = timedelta(seconds=settings.DISPATCH_ORDER_RESEND_SECONDS + 1)


def after_the_order() -> float:
    """An arrival time (epoch s) by which a robot that got the order just sent would report holding it."""
    return time.time() + ORDER_ECHO.total_seconds() + 1


def orders_resent(robot: Robot) -> list[str]:
    """The orderIds the robot's step sends once the resend period has passed."""
    outcome = robot_step(name=robot.name, now=timezone.now() + RESEND_DUE)
    return [m.content.order_id for m in outcome.messages if isinstance(m.content, OrderContent)]


def test_an_order_the_robot_has_not_taken_is_due_again_and_sent_again(bridge: Bridge, robot: Robot) -> None:
    order_id = running_order(bridge, robot)
    bridge.handle([state_message(robot, header_id=2, at=1.0)], received_at=after_the_order())

    assert robot.name in robots_due_for_step(now=timezone.now() + RESEND_DUE)
    assert orders_resent(robot) == [order_id]


def test_an_order_is_not_sent_again_before_a_state_says_the_robot_lacks_it(
    bridge: Bridge, robot: Robot
) -> None:
    """No state since the order went out, or one that may have left the robot before the order reached it:
    a bridge behind on a busy fleet looks like that, and resending would only add to its load."""
    running_order(bridge, robot)
    assert robot.name not in robots_due_for_step(now=timezone.now() + RESEND_DUE)
    assert orders_resent(robot) == []  # nor does a step for another reason send it

    bridge.handle([state_message(robot, header_id=2, at=1.0)], received_at=time.time())
    assert robot.name not in robots_due_for_step(now=timezone.now() + RESEND_DUE)
    assert orders_resent(robot) == []


def test_an_order_the_robot_took_is_not_sent_again_before_its_state_is_stepped(
    bridge: Bridge, robot: Robot
) -> None:
    order_id = running_order(bridge, robot)
    bridge.handle(
        [state_message(robot, header_id=2, at=1.0, order_id=order_id, last_node_sequence_id=2)],
        received_at=after_the_order(),
    )
    assert not Mission.objects.get(robot=robot.name).order_accepted  # the step that would mark it waits

    assert robot.name not in robots_due_for_step(now=timezone.now() + RESEND_DUE)


def test_a_robot_on_an_older_update_of_the_order_is_due_again(bridge: Bridge, robot: Robot) -> None:
    order_id = running_order(bridge, robot)
    bridge.handle(
        [state_message(robot, header_id=2, at=1.0, order_id=order_id, node_states=[2])],
        received_at=after_the_order(),
    )
    mission = Mission.objects.get(robot=robot.name)
    Mission.objects.filter(name=mission.name).update(order={**mission.order, "orderUpdateId": 1})

    assert robot.name in robots_due_for_step(now=timezone.now() + RESEND_DUE)


def test_a_timed_out_mission_is_due_whatever_the_robot_holds(bridge: Bridge, robot: Robot) -> None:
    order_id = running_order(bridge, robot)
    bridge.handle([state_message(robot, header_id=2, at=1.0, order_id=order_id, node_states=[2])])
    timeout = timedelta(seconds=Mission.objects.get(robot=robot.name).timeout + 1)

    assert robot.name in robots_due_for_step(now=timezone.now() + timeout)


# --- stalled missions ----------------------------------------------------------------------------------

STALLED = timedelta(seconds=STALLED_MISSION_SECONDS + 1)


def test_a_robot_idle_at_the_end_of_its_missions_order_is_stepped_once_the_mission_stalls(
    bridge: Bridge, robot: Robot
) -> None:
    """The state that ended the order was stored, but its step was lost (its process killed while PostgreSQL
    was away): nothing but this check steps the robot again, which now sends nothing new."""
    order_id = running_order(bridge, robot)
    bridge.handle(
        [state_message(robot, header_id=2, at=1.0, order_id=order_id, last_node_sequence_id=2, pose=END)],
        received_at=after_the_order(),
    )

    assert robot.name not in robots_stalled()  # the state's own step may still come
    assert robot.name in robots_stalled(now=timezone.now() + STALLED)

    robot_step(name=robot.name)
    assert Mission.objects.get(robot=robot.name).state == MissionState.COMPLETED
    assert robot.name not in robots_stalled(now=timezone.now() + STALLED)


def test_a_robot_still_on_its_missions_order_or_on_another_is_not_stalled(
    bridge: Bridge, robot: Robot
) -> None:
    order_id = running_order(bridge, robot)
    later = timezone.now() + STALLED

    bridge.handle(
        [state_message(robot, header_id=2, at=1.0, order_id=order_id, node_states=[2])],
        received_at=after_the_order(),
    )
    assert robot.name not in robots_stalled(now=later)  # driving it

    bridge.handle(
        [state_message(robot, header_id=3, at=2.0, order_id="elsewhere-n0")], received_at=time.time()
    )
    assert robot.name not in robots_stalled(now=later)  # idle, but on an order not the mission's


# --- orders taken and not executed ------------------------------------------------------------------------

ORDER_STALL = timedelta(seconds=settings.DISPATCH_ORDER_STALL_SECONDS + 1)


def test_a_robot_that_took_its_order_and_stands_still_is_stepped_and_the_order_canceled(
    bridge: Bridge, robot: Robot
) -> None:
    """A stalled robot's states wake no step (they do not change): beat does, once its clock has run."""
    order_id = running_order(bridge, robot)
    bridge.handle(
        [state_message(robot, header_id=2, at=1.0, order_id=order_id, node_states=[2])],
        received_at=after_the_order(),
    )
    robot_step(name=robot.name)
    assert Mission.objects.get(robot=robot.name).progress_seen_at is not None

    assert robot.name not in robots_stalled(now=timezone.now() + STALLED)
    assert robot.name in robots_stalled(now=timezone.now() + ORDER_STALL)
    outcome = robot_step(name=robot.name, now=timezone.now() + ORDER_STALL)
    assert "cancelOrder" in [
        a.action_type for m in outcome.messages for a in getattr(m.content, "actions", [])
    ]


def test_a_robot_with_the_order_update_rule_is_sent_no_route_ahead(bridge: Bridge, robot: Robot) -> None:
    Robot.objects.filter(name=robot.name).update(
        compatibility_rules=[{"rule": "order_update_not_executed", "applied_at": "", "reason": ""}]
    )
    bridge.handle([state_message(robot, header_id=1, at=0.0)])
    routes = [
        {"name": name, "route": {"waypoints": [{"x": x, "y": 6.0, "theta": 0.0, "map_id": "map"}]}}
        for name, x in (("r1", 5.0), ("r2", 7.0))
    ]
    mission_create(
        actor=TEST_ACTOR,
        name=f"{robot.name}-m",
        prefix=None,
        spec={"robot": robot.name, "mission_tree": routes},
    )

    orders = [m.content for m in robot_step(name=robot.name).messages if isinstance(m.content, OrderContent)]

    assert [order.order_update_id for order in orders] == [0]


def test_a_robot_that_no_longer_holds_its_taken_order_is_stepped_once_the_mission_stands_still(
    bridge: Bridge, robot: Robot
) -> None:
    """A restarted robot whose first states, alike, came too soon after the order to say it lost it: none of
    them wakes a step, beat's check does."""
    order_id = running_order(bridge, robot)
    bridge.handle(
        [state_message(robot, header_id=2, at=1.0, order_id=order_id, node_states=[2])],
        received_at=after_the_order(),
    )
    robot_step(name=robot.name)
    bridge.handle([state_message(robot, header_id=0, at=2.0)], received_at=after_the_order() + 1)

    assert robot.name in robots_stalled(now=timezone.now() + STALLED)
    outcome = robot_step(name=robot.name, now=timezone.now() + STALLED)
    resumed = [m.content.order_id for m in outcome.messages if isinstance(m.content, OrderContent)]
    assert resumed == [order_id.replace("-r0", "-r1")]

"""`missions.zone_plan.zones_plan_run` and the steps that carry it out, against the real PostgreSQL and Redis:
grants written and let go, the order's base held back at a zone's edge and extended by an order update once
granted, the mission's waiting reason, the robot's status, an operator's revoke.

The zone is the factory's 2 m square at the origin of map `map`. Robot A, at (-1, 1), drives through it
eastward to (3, 1); robot B, at (1, 3), southward to (1, -1): their routes cross in the square.
"""

from collections.abc import Callable
from typing import Any

import pytest
from django.utils import timezone

import missions.zone_plan
from kit.api.errors import UsageError
from missions.models import Mission
from missions.robot_step import robot_step
from missions.selectors import orders_held_back
from missions.services import mission_create
from missions.zone_plan import zones_plan_run
from robots.models import Robot
from robots.services import robot_rows_delete
from tests.dispatch.builders import on_order, robot_state
from tests.factories import TEST_ACTOR, ZoneSetFactory
from tests.missions.test_robot_step import orders, put_state, step
from vda5050.models import OrderContent, Request, ResponsesContent
from vda5050.topics import Topic
from zones.models import ZoneGrant, ZoneReach, ZoneSet
from zones.services import zone_grant_revoke, zone_set_disable, zone_set_enable

pytestmark = pytest.mark.django_db(transaction=True)

MakeRobot = Callable[..., Robot]
A_START, A_ROUTE = (-1.0, 1.0), [(1.0, 1.0), (3.0, 1.0)]
B_START, B_ROUTE = (1.0, 3.0), [(1.0, 1.0), (1.0, -1.0)]


@pytest.fixture
def zone_set() -> ZoneSet:
    return zone_set_enable(actor=TEST_ACTOR, zone_set=ZoneSetFactory())


def at(
    robot: Robot, x: float, y: float, *, header_id: int = 1, map_id: str = "map", version: str = "2.0.0"
) -> None:
    """The robot reports (x, y) on `map_id`, in its live state and in its row (the bridge's flush)."""
    Robot.objects.filter(name=robot.name).update(
        online=True, pose_x=x, pose_y=y, pose_map_id=map_id, last_state_at=timezone.now()
    )
    put_state(robot, header_id=header_id, pose=(x, y, 0.0, map_id), version=version)


def on_route(
    make_robot: MakeRobot, start: tuple[float, float], route: list[tuple[float, float]], map_id: str = "map"
) -> Robot:
    """An online robot at `start` on `map_id` with a mission through `route` there, not stepped yet."""
    robot = make_robot(prefix="zone")
    at(robot, *start, map_id=map_id)
    waypoints = [{"x": x, "y": y, "theta": 0.0, "map_id": map_id} for x, y in route]
    mission_create(
        actor=TEST_ACTOR,
        name=f"m-{robot.name}",
        prefix=None,
        spec={"robot": robot.name, "mission_tree": [{"name": "r", "route": {"waypoints": waypoints}}]},
    )
    return robot


def sent_order(robot: Robot) -> OrderContent:
    return OrderContent.model_validate(Mission.objects.get(robot=robot.name).order)


def takes(robot: Robot, header_id: int, reached: int = 0) -> None:
    """The robot reports it holds its mission's order (as last sent), at the node `reached`."""
    order = sent_order(robot)
    x, y = Robot.objects.filter(name=robot.name).values_list("pose_x", "pose_y").get()
    put_state(robot, header_id=header_id, state=on_order(order, reached, pose=(x, y, 0.0, "map")))
    step(robot)


def released(order: OrderContent) -> list[int]:
    return [node.sequence_id for node in order.nodes if node.released]


def holders() -> set[tuple[str, str]]:
    return set(ZoneGrant.objects.values_list("zone_id", "robot"))


def both_at_the_square(make_robot: MakeRobot, *, planned: bool = True) -> tuple[Robot, Robot]:
    """A and B on their routes, each holding its first order (its start alone released); the plan run
    after that (`planned`) gives A the square and has B wait."""
    zones_plan_run()
    a = on_route(make_robot, A_START, A_ROUTE)
    b = on_route(make_robot, B_START, B_ROUTE)
    zones_plan_run()
    for robot in (a, b):
        step(robot)
        takes(robot, header_id=2)
    if planned:
        zones_plan_run()
    return a, b


def test_a_new_order_releases_nothing_but_its_start_until_the_plan_has_seen_it(
    zone_set: ZoneSet, make_robot: MakeRobot
) -> None:
    zones_plan_run()  # every robot gets its reach: the one below is held by zones from its first order
    robot = on_route(make_robot, A_START, A_ROUTE)
    robot = Robot.objects.get(name=robot.name)
    zones_plan_run()

    [order] = orders(step(robot))

    assert released(order) == [0]
    assert [node.sequence_id for node in order.nodes] == [0, 2, 4]


def test_a_robot_the_plan_has_never_seen_releases_only_its_start_on_a_zoned_map(
    zone_set: ZoneSet, make_robot: MakeRobot
) -> None:
    robot = on_route(make_robot, A_START, A_ROUTE)  # no plan run since: the robot has no reach yet
    assert not ZoneReach.objects.filter(robot=robot.name).exists()

    [order] = orders(step(robot))

    assert released(order) == [0]
    zones_plan_run()  # which the step asked for: from now on the robot has its reach
    assert ZoneReach.objects.filter(robot=robot.name).exists()


def test_a_robot_the_plan_has_never_seen_is_not_held_back_on_a_map_without_zones(
    zone_set: ZoneSet, make_robot: MakeRobot
) -> None:
    robot = on_route(make_robot, A_START, A_ROUTE, map_id="elsewhere")

    [order] = orders(step(robot))

    assert released(order) == [0, 2, 4]


def test_the_first_robot_gets_the_zone_and_drives_through_it_the_second_waits_at_its_edge(
    zone_set: ZoneSet, make_robot: MakeRobot
) -> None:
    a, b = both_at_the_square(make_robot, planned=False)

    decision = zones_plan_run()

    assert decision is not None
    assert holders() == {("square", a.name)}
    assert ZoneReach.objects.get(robot=b.name).waiting == ["square"]
    [update] = orders(step(a))
    assert (update.order_update_id, released(update)) == (1, [0, 2, 4])
    assert sent_order(a).order_update_id == 1 and released(sent_order(a)) == [0, 2, 4]
    assert orders(step(b)) == []
    assert Mission.objects.get(robot=b.name).waiting_reason == "Waiting for zone square"
    assert Robot.objects.get(name=a.name).zone_access == {
        "held": [{"map_id": "map", "zone_id": "square"}],
        "waiting": [],
    }
    assert Robot.objects.get(name=b.name).zone_access["waiting"] == [{"map_id": "map", "zone_id": "square"}]


@pytest.mark.parametrize("version", ["2.0.0", "3.0.0"])  # 3.0 names it mobileRobotPosition on the wire
def test_where_a_robot_is_comes_from_its_latest_state_not_its_row(
    zone_set: ZoneSet, make_robot: MakeRobot, version: str
) -> None:
    """The row's position (the bridge's status flush) may lag: a robot that has just driven into the
    square holds it as its latest state says."""
    inside = make_robot(prefix="zone")
    Robot.objects.filter(name=inside.name).update(protocol_version=version)
    at(inside, 1.0, 1.0, version=version)
    Robot.objects.filter(name=inside.name).update(pose_x=-5.0, pose_y=-5.0)  # not flushed yet
    zones_plan_run()
    b = on_route(make_robot, B_START, B_ROUTE)
    zones_plan_run()
    step(b)
    takes(b, header_id=2)

    zones_plan_run()

    assert holders() == {("square", inside.name)}
    assert ZoneReach.objects.get(robot=b.name).waiting == ["square"]


@pytest.fixture
def stepped(monkeypatch: pytest.MonkeyPatch) -> list[list[str]]:
    """The robots each plan run asks steps of (its `request_steps` calls)."""
    calls: list[list[str]] = []
    monkeypatch.setattr(missions.zone_plan, "request_steps", lambda names: calls.append(sorted(names)))
    return calls


def test_a_robot_whose_base_is_behind_its_reach_is_stepped_at_every_run_until_it_caught_up(
    zone_set: ZoneSet, make_robot: MakeRobot, stepped: list[list[str]]
) -> None:
    zones_plan_run()
    robot = on_route(make_robot, B_START, B_ROUTE)
    zones_plan_run()
    step(robot)
    takes(robot, header_id=2)  # its start alone released
    zones_plan_run()  # its reach: through the square
    stepped.clear()

    zones_plan_run()  # the reach unchanged: a step that missed it gets another chance
    zones_plan_run()

    assert stepped == [[robot.name], [robot.name]]
    [update] = orders(step(robot))
    assert released(update) == [0, 2, 4]
    stepped.clear()
    zones_plan_run()
    assert stepped == []


def test_the_zone_passes_to_the_waiting_robot_once_the_holder_has_left_it(
    zone_set: ZoneSet, make_robot: MakeRobot
) -> None:
    a, b = both_at_the_square(make_robot)
    step(a)
    takes(a, header_id=3)  # holds the update
    at(a, 3.0, 1.0, header_id=4)  # through the square, at its last node
    put_state(a, header_id=5, state=on_order(sent_order(a), 4, pose=(3.0, 1.0, 0.0, "map")))
    step(a)

    zones_plan_run()

    assert holders() == {("square", b.name)}
    [update] = orders(step(b))
    assert released(update) == [0, 2, 4]
    assert Mission.objects.get(robot=b.name).waiting_reason is None


@pytest.mark.parametrize("gone", ["offline", "deleted"])
def test_a_robot_offline_or_deleted_holds_nothing(
    zone_set: ZoneSet, make_robot: MakeRobot, gone: str
) -> None:
    a, b = both_at_the_square(make_robot)
    assert holders() == {("square", a.name)}
    if gone == "offline":
        Robot.objects.filter(name=a.name).update(online=False)
    else:
        robot_rows_delete(a.name)

    zones_plan_run()

    assert holders() == {("square", b.name)}
    assert ZoneReach.objects.filter(robot=a.name).exists() == (gone == "offline")


def test_a_revoked_grant_of_a_robot_not_yet_in_the_zone_goes_to_the_next(
    zone_set: ZoneSet, make_robot: MakeRobot
) -> None:
    a, b = both_at_the_square(make_robot)

    zone_grant_revoke(actor=TEST_ACTOR, zone_set=zone_set, robot=a.name, zone_id="square")
    zones_plan_run()

    assert holders() == {("square", b.name)}
    assert ZoneReach.objects.get(robot=a.name).waiting == ["square"]
    assert orders(step(a)) == []


def test_revoking_what_no_robot_holds_is_refused(zone_set: ZoneSet, make_robot: MakeRobot) -> None:
    robot = make_robot(prefix="zone")
    with pytest.raises(UsageError, match="holds no grant"):
        zone_grant_revoke(actor=TEST_ACTOR, zone_set=zone_set, robot=robot.name, zone_id="square")
    with pytest.raises(UsageError, match="has no zone"):
        zone_grant_revoke(actor=TEST_ACTOR, zone_set=zone_set, robot=robot.name, zone_id="nowhere")


def test_disabling_the_zone_set_lets_everything_go_and_the_held_back_base_is_released(
    zone_set: ZoneSet, make_robot: MakeRobot
) -> None:
    a, b = both_at_the_square(make_robot)

    zone_set_disable(actor=TEST_ACTOR, zone_set=zone_set)
    assert zones_plan_run() is None

    assert holders() == set() and not ZoneReach.objects.exists()
    [update] = orders(step(b))
    assert released(update) == [0, 2, 4]
    assert Robot.objects.get(name=a.name).zone_access == {}


def test_a_robot_held_back_when_its_zone_set_went_is_stepped_at_every_run_until_released(
    zone_set: ZoneSet, make_robot: MakeRobot, stepped: list[list[str]]
) -> None:
    a, b = both_at_the_square(make_robot)  # neither stepped since: both orders hold their start alone
    zone_set_disable(actor=TEST_ACTOR, zone_set=zone_set)
    zones_plan_run()
    stepped.clear()
    assert orders_held_back()  # beat goes on running the plan

    zones_plan_run()  # their steps missed the news: asked for again

    assert stepped == [sorted([a.name, b.name])]
    for robot in (a, b):
        orders(step(robot))
    assert not orders_held_back()


def asks(
    robot: Robot,
    request_id: str,
    zone_set: ZoneSet,
    *,
    header_id: int = 2,
    where: tuple[float, float] = (5.0, 5.0),
) -> None:
    """The 3.0 robot, idle at `where` (outside the square unless said), asks for access to the square."""
    x, y = where
    Robot.objects.filter(name=robot.name).update(
        online=True, pose_x=x, pose_y=y, pose_map_id="map", last_state_at=timezone.now()
    )
    request = Request(
        request_id=request_id,
        request_type="ACCESS",
        request_status="REQUESTED",
        zone_id="square",
        zone_set_id=zone_set.name,
    )
    state = robot_state(pose=(x, y, 0.0, "map")).model_copy(update={"zone_requests": [request]})
    put_state(robot, header_id=header_id, state=state)


def responses(outcome: Any) -> list[tuple[str, str]]:
    return [
        (response.request_id, response.grant_type)
        for message in outcome.messages
        if isinstance(message.content, ResponsesContent)
        for response in message.content.responses
    ]


def test_3_0_zone_requests_are_answered_once_on_the_responses_topic_through_the_outbox(
    zone_set: ZoneSet, make_robot: MakeRobot
) -> None:
    first, second = make_robot(prefix="zone"), make_robot(prefix="zone")
    Robot.objects.filter(name__in=[first.name, second.name]).update(protocol_version="3.0.0")
    first, second = Robot.objects.get(name=first.name), Robot.objects.get(name=second.name)
    asks(first, "r1", zone_set)
    zones_plan_run()
    granted = robot_step(name=first.name)
    asks(second, "r2", zone_set)
    assert responses(robot_step(name=second.name)) == []  # not answered yet: it asks for a plan run

    zones_plan_run()
    queued = robot_step(name=second.name)

    assert responses(granted) == [("r1", "GRANTED")]
    assert responses(queued) == [("r2", "QUEUED")]
    assert [(m.topic, m.header_id) for m in granted.wire if m.topic == Topic.RESPONSES] == [
        (Topic.RESPONSES, 0)
    ]
    assert responses(robot_step(name=first.name)) == []  # sent once
    assert holders() == {("square", first.name)}


def test_answers_after_the_zone_set_was_disabled_and_enabled_again_go_on_with_the_robots_header_ids(
    zone_set: ZoneSet, make_robot: MakeRobot
) -> None:
    """The plan deletes a robot's reach while no zone is enabled; the responses topic's headerIds are the
    robot's, so the answers after that go on from where they were (a robot, and the publisher's claims in
    Redis, drop a headerId that goes back)."""
    robot = make_robot(prefix="zone")
    Robot.objects.filter(name=robot.name).update(protocol_version="3.0.0")
    robot = Robot.objects.get(name=robot.name)
    asks(robot, "r1", zone_set)
    zones_plan_run()
    before = robot_step(name=robot.name)

    zone_set_disable(actor=TEST_ACTOR, zone_set=zone_set)
    zones_plan_run()
    assert not ZoneReach.objects.exists()
    zone_set_enable(actor=TEST_ACTOR, zone_set=zone_set)
    zones_plan_run()
    after = robot_step(name=robot.name)

    assert responses(before) == responses(after) == [("r1", "GRANTED")]
    assert [m.header_id for m in before.wire if m.topic == Topic.RESPONSES] == [0]
    # (Its outbox sends the first again too: in this test nothing publishes, so it may not have gone out.)
    assert [m.header_id for m in after.wire if m.topic == Topic.RESPONSES][-1] == 1


def test_a_3_0_robot_revoked_inside_the_zone_is_answered_revoked_and_holds_it_until_it_has_left(
    zone_set: ZoneSet, make_robot: MakeRobot
) -> None:
    robot = make_robot(prefix="zone")
    Robot.objects.filter(name=robot.name).update(protocol_version="3.0.0")
    robot = Robot.objects.get(name=robot.name)
    asks(robot, "r1", zone_set, where=(1.0, 1.0))
    zones_plan_run()
    assert responses(robot_step(name=robot.name)) == [("r1", "GRANTED")]

    zone_grant_revoke(actor=TEST_ACTOR, zone_set=zone_set, robot=robot.name, zone_id="square")
    zones_plan_run()
    assert responses(robot_step(name=robot.name)) == [("r1", "REVOKED")]
    zones_plan_run()  # the next runs keep the revocation while it is inside: no GRANTED again
    assert responses(robot_step(name=robot.name)) == []
    assert holders() == {("square", robot.name)}

    asks(robot, "r1", zone_set, header_id=3, where=(5.0, 5.0))  # it left (and still reports its request)
    zones_plan_run()
    assert not ZoneGrant.objects.filter(robot=robot.name, revoked_at__isnull=False).exists()

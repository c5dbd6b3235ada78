"""`missions.robot_step.robot_step`: the dispatch step's I/O wrapper, against the real PostgreSQL and Redis.

The robot's state is put into Redis by hand, as the bridge stores it; missions are created by the service.
Outside a test's transaction, as the bridge and the workers step: the step sends its own BEGIN and COMMIT.
"""

import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from datetime import timedelta
from itertools import pairwise
from pathlib import Path
from typing import Any

import pytest
from django.db import connection
from django.utils import timezone

from changes.choices import ChangeKind
from changes.models import Change
from dispatch.held import state_digest
from missions import robot_step as robot_step_module
from missions.choices import FailureCategory, Lifecycle, MissionState
from missions.models import Mission
from missions.robot_step import StepOutcome, robot_step
from missions.services import mission_cancel, mission_create, mission_delete
from robots import livestate
from robots.choices import RobotState
from robots.models import InstantAction, Robot
from robots.services import FACTSHEET_REQUEST, robot_delete
from tests.dispatch.builders import check_schema, finished, on_order, robot_state
from tests.factories import TEST_ACTOR
from tests.workers.bridge.messages import T0, wire
from vda5050.codec import parse_state
from vda5050.models import Action, ActionStatus, InstantActionsContent, OrderContent, State
from vda5050.orders import stitch
from vda5050.topics import Topic
from workers.step_runs import step_and_publish

pytestmark = pytest.mark.django_db(transaction=True)

MakeRobot = Callable[..., Robot]
NOW = timezone.now().replace(microsecond=0)


@pytest.fixture
def robot(make_robot: MakeRobot) -> Robot:
    """An online robot whose latest state says it is idle."""
    created = make_robot(prefix="step")
    Robot.objects.filter(name=created.name).update(online=True)
    put_state(created, header_id=1)
    return created


def put_state(
    robot: Robot,
    *,
    header_id: int,
    state: State | None = None,
    arrived_at: float | None = None,
    version: str = "2.0.0",
    **fields: Any,
) -> None:
    """Store a state as the bridge does (the payload as the robot sent it, speaking `version`): `state`
    (retargeted to the robot), else one built from `fields`; it arrived at `arrived_at` (epoch s), by
    default now."""
    content = state or robot_state(**fields)
    payload = wire(robot, content, header_id=header_id, at=float(header_id), version=version)
    pipe = livestate.client().pipeline()
    livestate.store_state(
        pipe,
        name=robot.name,
        payload=payload,
        timestamp_ms=int((T0 + timedelta(seconds=header_id)).timestamp() * 1000),
        header_id=header_id,
        digest=state_digest(parse_state(payload)),
        arrived_at=time.time() if arrived_at is None else arrived_at,
    )
    livestate.execute(pipe)


def step(robot: Robot, *, after: float = 0.0) -> StepOutcome:
    """robot_step `after` seconds after NOW, every message checked against the schemas."""
    now = NOW + timedelta(seconds=after)
    outcome = robot_step(name=robot.name, now=now)
    for header_id, message in enumerate(outcome.messages):
        check_schema(message.content, header_id, now)
    return outcome


def orders(outcome: StepOutcome) -> list[OrderContent]:
    return [m.content for m in outcome.messages if isinstance(m.content, OrderContent)]


def instant_actions(outcome: StepOutcome) -> list[Action]:
    return [
        a for m in outcome.messages if isinstance(m.content, InstantActionsContent) for a in m.content.actions
    ]


def create(name: str, robot: Robot, *tree: dict[str, Any]) -> Mission:
    route = {"name": "r", "route": {"waypoints": [{"x": 5.0, "y": 6.0, "theta": 0.0, "map_id": "map"}]}}
    return mission_create(
        actor=TEST_ACTOR,
        name=name,
        prefix=None,
        spec={"robot": robot.name, "mission_tree": list(tree) or [route]},
    )


def test_the_first_step_starts_the_mission_and_returns_and_stores_its_order(robot: Robot) -> None:
    create("m1", robot)

    outcome = step(robot)

    [order] = orders(outcome)
    assert order.order_id == "m1-n0-r0"
    mission = Mission.objects.get(name="m1")
    assert (mission.state, mission.start_timestamp, mission.current_node) == (MissionState.RUNNING, NOW, 0)
    assert mission.order == order.model_dump(mode="json", by_alias=True, exclude_none=True)
    assert (mission.order_sent_at, mission.order_accepted, mission.attempts) == (NOW, False, {"r": 1})
    assert mission.node_status["r"]["state"] == MissionState.RUNNING
    assert Robot.objects.get(name=robot.name).state == RobotState.ON_TASK
    assert outcome.address.serial_number == robot.serial_number


def test_the_first_step_sends_the_factsheet_request_queued_at_creation(robot: Robot) -> None:
    outcome = step(robot)

    [request] = InstantAction.objects.filter(robot=robot, action_type=FACTSHEET_REQUEST)
    assert [(a.action_type, a.action_id) for a in instant_actions(outcome)] == [
        (FACTSHEET_REQUEST, request.action_id)
    ]
    assert (request.sent_at, request.send_count, request.status) == (NOW, 1, None)


def test_a_second_step_without_a_new_state_sends_nothing(robot: Robot) -> None:
    create("m1", robot)
    step(robot)
    stored = Mission.objects.get(name="m1")

    outcome = step(robot, after=1.0)

    assert outcome.messages == []
    assert Mission.objects.get(name="m1").updated_at == stored.updated_at


def test_an_unaccepted_order_is_resent_by_a_later_step(robot: Robot) -> None:
    create("m1", robot)
    [first] = orders(step(robot))
    # A state from well after the order that does not hold it: the robot lacks the order.
    put_state(robot, header_id=2, arrived_at=(NOW + timedelta(seconds=30)).timestamp())

    outcome = step(robot, after=60.0)

    assert orders(outcome) == [first]


def header_ids(outcome: StepOutcome) -> list[tuple[Topic, int]]:
    return [
        (message.topic, header_id)
        for message, header_id in zip(outcome.messages, outcome.header_ids, strict=True)
    ]


def test_each_topic_numbers_the_messages_sent_to_the_robot_from_0_and_a_resend_gets_the_next(
    robot: Robot,
) -> None:
    create("m1", robot)
    first = step(robot)  # the factsheet request queued at creation, and the mission's order
    put_state(robot, header_id=2, arrived_at=(NOW + timedelta(seconds=30)).timestamp())

    resend = step(robot, after=60.0)

    assert sorted(header_ids(first)) == [(Topic.INSTANT_ACTIONS, 0), (Topic.ORDER, 0)]
    assert sorted(header_ids(resend)) == [(Topic.INSTANT_ACTIONS, 1), (Topic.ORDER, 1)]  # both unanswered
    stored = Robot.objects.get(name=robot.name)
    assert (stored.next_order_header_id, stored.next_instant_actions_header_id) == (2, 2)


def test_header_ids_go_on_from_the_robots_row_when_redis_lost_everything_else(robot: Robot) -> None:
    """Redis keeps nothing on disk; a restarted one must not make a robot see headerIds start again."""
    Robot.objects.filter(name=robot.name).update(next_order_header_id=41, next_instant_actions_header_id=7)
    livestate.forget(robot.name)  # what a restarted Redis holds about the robot: nothing
    put_state(robot, header_id=1)
    create("m1", robot)

    outcome = step(robot)

    assert sorted(header_ids(outcome)) == [(Topic.INSTANT_ACTIONS, 7), (Topic.ORDER, 41)]
    stored = Robot.objects.get(name=robot.name)
    assert (stored.next_order_header_id, stored.next_instant_actions_header_id) == (42, 8)


def on_the_wire(outcome: StepOutcome) -> list[tuple[Topic, int]]:
    return [(message.topic, message.header_id) for message in outcome.wire]


def test_what_a_step_killed_before_publishing_decided_goes_out_first_with_the_next_step_identically(
    robot: Robot,
) -> None:
    """Its process died between COMMIT and publish: its headerIds must not be left out on the wire."""
    InstantAction.objects.filter(robot=robot).update(status=None, sent_at=None)
    step_and_publish(robot.name)  # the robot's factsheet request goes out: Redis marks what it was sent
    create("m1", robot)
    killed = step(robot)  # committed, never published
    put_state(robot, header_id=2, arrived_at=(NOW + timedelta(seconds=30)).timestamp())

    resend = step(robot, after=60.0)

    assert on_the_wire(killed) == [(Topic.ORDER, 0)]
    assert resend.wire[:1] == killed.wire  # to the byte
    assert (Topic.ORDER, 1) in on_the_wire(resend)[1:]


def test_once_redis_lost_the_marks_only_the_newest_message_on_each_topic_is_sent_again(robot: Robot) -> None:
    """An older one could hand the robot an order its mission has moved past (the fault suite saw a first
    leaf's order arrive after the second's); the newest may be the one a killed step left unsent."""
    create("m1", robot)
    step_and_publish(robot.name)  # publishes, and marks what it published; now, not at NOW
    sent_at = timezone.now()

    def resend(after: float) -> StepOutcome:
        arrived_at = sent_at + timedelta(seconds=after - 5)  # well after the last send
        put_state(robot, header_id=int(after), arrived_at=arrived_at.timestamp())
        return robot_step(name=robot.name, now=sent_at + timedelta(seconds=after))

    first = resend(60)  # committed, never published: the outbox holds 0 (published) and 1 on each topic
    assert sorted(on_the_wire(first)) == [(Topic.INSTANT_ACTIONS, 1), (Topic.ORDER, 1)]

    livestate.client().delete(livestate.robot_key(robot.name))  # a Redis restart
    outcome = resend(120)

    assert sorted(on_the_wire(outcome)[:2]) == [(Topic.INSTANT_ACTIONS, 1), (Topic.ORDER, 1)]
    assert outcome.wire[:2] == sorted(
        first.wire, key=lambda m: [w.topic for w in outcome.wire].index(m.topic)
    )
    assert sorted(on_the_wire(outcome)[2:]) == [(Topic.INSTANT_ACTIONS, 2), (Topic.ORDER, 2)]


def test_an_offline_robot_keeps_its_mission_queued_and_gets_nothing(robot: Robot) -> None:
    Robot.objects.filter(name=robot.name).update(online=False)
    create("m1", robot)

    outcome = step(robot)

    mission = Mission.objects.get(name="m1")
    assert (mission.state, mission.waiting_reason) == (MissionState.PENDING, "Robot is offline")
    assert outcome.messages == []


def test_a_stored_state_that_no_longer_parses_counts_as_no_state(robot: Robot) -> None:
    pipe = livestate.client().pipeline()
    digest = state_digest(robot_state())
    livestate.store_state(
        pipe,
        name=robot.name,
        payload=b"{}",
        timestamp_ms=10**13,
        header_id=1,
        digest=digest,
        arrived_at=time.time(),
    )
    livestate.execute(pipe)
    create("m1", robot)

    step(robot)

    assert Mission.objects.get(name="m1").waiting_reason == "Robot is offline"


def test_the_queue_runs_fifo_as_missions_end(robot: Robot) -> None:
    for name in ("m1", "m2", "m3"):
        create(name, robot)
    [first] = orders(step(robot))

    put_state(robot, header_id=2, state=finished(first))
    outcome = step(robot, after=1.0)

    assert [m.name for m in outcome.finished] == ["m1"]
    assert [o.order_id for o in orders(outcome)] == ["m2-n0-r0"]
    states = dict(Mission.objects.values_list("name", "state"))
    assert states == {"m1": MissionState.COMPLETED, "m2": MissionState.RUNNING, "m3": MissionState.PENDING}
    assert Robot.objects.get(name=robot.name).state == RobotState.ON_TASK

    [second] = orders(outcome)
    put_state(robot, header_id=3, state=finished(second))
    outcome = step(robot, after=2.0)
    assert [o.order_id for o in orders(outcome)] == ["m3-n0-r0"]


def test_missions_that_end_without_starting_let_the_next_one_start_in_the_same_step(robot: Robot) -> None:
    first = create("m1", robot)
    Mission.objects.filter(name=first.name).update(deadline=NOW - timedelta(seconds=1))
    create("m2", robot)

    outcome = step(robot)

    assert [(m.name, m.state, m.failure_category) for m in outcome.finished] == [
        ("m1", MissionState.FAILED, FailureCategory.DEADLINE)
    ]
    assert [o.order_id for o in orders(outcome)] == ["m2-n0-r0"]


def test_a_canceled_running_mission_gets_a_cancel_order_then_ends_canceled(robot: Robot) -> None:
    create("m1", robot)
    [order] = orders(step(robot))
    put_state(robot, header_id=2, state=on_order(order, 0))
    step(robot, after=1.0)
    mission_cancel(actor=TEST_ACTOR, mission=Mission.objects.get(name="m1"))

    outcome = step(robot, after=2.0)

    [cancel] = InstantAction.objects.filter(robot=robot, action_type="cancelOrder")
    assert (cancel.mission, cancel.status, cancel.send_count) == ("m1", None, 1)
    assert cancel.sent_at == NOW + timedelta(seconds=2)
    assert [(a.action_type, a.action_id) for a in instant_actions(outcome)] == [
        ("cancelOrder", cancel.action_id)
    ]
    assert Mission.objects.get(name="m1").state == MissionState.RUNNING

    confirmed = on_order(order, 0, extra_actions=[(cancel.action_id, ActionStatus.FINISHED)])
    put_state(robot, header_id=3, state=confirmed.model_copy(update={"node_states": [], "edge_states": []}))
    step(robot, after=3.0)

    mission = Mission.objects.get(name="m1")
    assert (mission.state, mission.failure_category) == (MissionState.CANCELED, FailureCategory.CANCELED)
    assert InstantAction.objects.get(action_id=cancel.action_id).status == ActionStatus.FINISHED
    assert Robot.objects.get(name=robot.name).state == RobotState.IDLE


def test_a_running_mission_deleted_is_canceled_then_removed_and_the_next_one_starts(robot: Robot) -> None:
    create("m1", robot)
    create("m2", robot)
    [order] = orders(step(robot))
    put_state(robot, header_id=2, state=on_order(order, 0))
    assert (
        mission_delete(actor=TEST_ACTOR, mission=Mission.objects.get(name="m1")).lifecycle
        == Lifecycle.PENDING_DELETE
    )
    step(robot, after=1.0)
    [cancel] = InstantAction.objects.filter(robot=robot, action_type="cancelOrder")

    confirmed = on_order(order, 0, extra_actions=[(cancel.action_id, ActionStatus.FINISHED)])
    put_state(robot, header_id=3, state=confirmed.model_copy(update={"node_states": [], "edge_states": []}))
    outcome = step(robot, after=2.0)

    assert not Mission.objects.filter(name="m1").exists()
    assert [o.order_id for o in orders(outcome)] == ["m2-n0-r0"]


def two_routes(name: str, robot: Robot) -> Mission:
    waypoint = {"theta": 0.0, "map_id": "map"}
    return create(
        name,
        robot,
        {"name": "r1", "route": {"waypoints": [{"x": 5.0, "y": 2.0, **waypoint}]}},
        {"name": "r2", "route": {"waypoints": [{"x": 5.0, "y": 6.0, **waypoint}]}},
    )


def test_a_route_certain_to_follow_goes_out_right_behind_the_first_order_as_its_update(robot: Robot) -> None:
    InstantAction.objects.filter(robot=robot).update(status=ActionStatus.FINISHED)  # no factsheet request
    two_routes("m1", robot)

    outcome = step(robot)

    first, update = orders(outcome)
    assert header_ids(outcome) == [(Topic.ORDER, 0), (Topic.ORDER, 1)]
    assert (update.order_id, update.order_update_id, update.nodes[0]) == (first.order_id, 1, first.nodes[-1])
    mission = Mission.objects.get(name="m1")
    assert mission.order == stitch(first, update).model_dump(mode="json", by_alias=True, exclude_none=True)
    assert (mission.order_accepted, mission.attempts) == (False, {"r1": 1, "r2": 1})
    assert (mission.node_status["r1"]["state"], mission.node_status["r2"]["state"]) == ("RUNNING", "PENDING")
    assert [(m.topic, m.header_id) for m in outcome.wire] == [(Topic.ORDER, 0), (Topic.ORDER, 1)]


def test_the_robot_passing_the_end_of_the_first_route_runs_the_second_in_a_two_round_trip_step(
    robot: Robot, tmp_path: Path
) -> None:
    """Leaf by leaf, as before, and no dearer: the step reads and writes as a step always does."""
    InstantAction.objects.filter(robot=robot).update(status=ActionStatus.FINISHED)  # no factsheet request
    two_routes("m1", robot)
    first, update = orders(step(robot))
    held = stitch(first, update)
    put_state(robot, header_id=2, state=on_order(held, 2, driving=True))

    with protocol_trace(tmp_path / "trace") as trace:
        outcome = step(robot, after=1.0)

    assert round_trips(trace.read_text()) == 2
    assert outcome.messages == []
    mission = Mission.objects.get(name="m1")
    assert (mission.node_status["r1"]["state"], mission.node_status["r2"]["state"]) == (
        "COMPLETED",
        "RUNNING",
    )
    assert (mission.current_node, mission.order_accepted) == (1, True)
    assert mission.order == update.model_dump(mode="json", by_alias=True, exclude_none=True)

    put_state(robot, header_id=3, state=finished(held))
    step(robot, after=2.0)
    assert Mission.objects.get(name="m1").state == MissionState.COMPLETED


def test_a_route_sent_ahead_that_ran_and_ended_within_one_step_is_seen_running(robot: Robot) -> None:
    """Each leaf has its RUNNING line in the change feed (the watch streams), as with an order per leaf."""
    two_routes("m1", robot)
    first, update = orders(step(robot))
    put_state(robot, header_id=2, state=finished(stitch(first, update)))

    step(robot, after=1.0)

    images = [c.image for c in Change.objects.filter(kind=ChangeKind.MISSION, name="m1").order_by("id")]
    leaf_states = [(i["node_status"]["r1"]["state"], i["node_status"]["r2"]["state"]) for i in images]
    assert leaf_states[-2:] == [("COMPLETED", "RUNNING"), ("COMPLETED", "COMPLETED")]
    assert Mission.objects.get(name="m1").state == MissionState.COMPLETED


def test_a_mission_canceled_in_the_middle_of_an_extended_order_cancels_it_all(robot: Robot) -> None:
    two_routes("m1", robot)
    first, update = orders(step(robot))
    held = stitch(first, update)
    put_state(robot, header_id=2, state=on_order(held, 0, driving=True))
    step(robot, after=1.0)
    mission_cancel(actor=TEST_ACTOR, mission=Mission.objects.get(name="m1"))

    outcome = step(robot, after=2.0)

    [cancel] = InstantAction.objects.filter(robot=robot, action_type="cancelOrder")
    assert cancel.action_id.startswith(f"{first.order_id}-cancel")
    assert orders(outcome) == []
    confirmed = on_order(held, 0, extra_actions=[(cancel.action_id, ActionStatus.FINISHED)])
    put_state(robot, header_id=3, state=confirmed.model_copy(update={"node_states": [], "edge_states": []}))
    step(robot, after=3.0)
    mission = Mission.objects.get(name="m1")
    assert mission.state == MissionState.CANCELED
    assert (mission.node_status["r1"]["state"], mission.node_status["r2"]["state"]) == ("CANCELED", "PENDING")


def test_a_robot_deleted_during_a_mission_fails_it_and_is_removed_with_its_live_state(robot: Robot) -> None:
    create("m1", robot)
    step(robot)
    robot_delete(actor=TEST_ACTOR, robot=Robot.objects.get(name=robot.name))

    outcome = step(robot, after=1.0)

    mission = Mission.objects.get(name="m1")
    assert (mission.state, mission.failure_category) == (MissionState.FAILED, FailureCategory.ROBOT_APP)
    assert not Robot.objects.filter(name=robot.name).exists()
    assert livestate.latest_state(robot.name).payload is None
    assert outcome.messages == []


def test_a_step_that_deletes_the_robot_sends_nothing_it_had_due(robot: Robot) -> None:
    """The unanswered factsheet request and order are due again, but the robot and its headerIds are gone."""
    create("m1", robot)
    step(robot)
    put_state(robot, header_id=2, arrived_at=(NOW + timedelta(seconds=30)).timestamp())
    robot_delete(actor=TEST_ACTOR, robot=Robot.objects.get(name=robot.name))

    outcome = step(robot, after=60.0)

    assert (outcome.messages, outcome.header_ids) == ([], [])
    assert Mission.objects.get(name="m1").state == MissionState.FAILED
    assert not Robot.objects.filter(name=robot.name).exists()


@contextmanager
def protocol_trace(path: Path) -> Iterator[Path]:
    """libpq's trace of the messages this test's connection exchanges with PostgreSQL, written to `path`."""
    connection.ensure_connection()
    pgconn = connection.connection.pgconn
    with path.open("w") as trace:
        pgconn.trace(trace.fileno())
        try:
            yield path
        finally:
            pgconn.untrace()


def round_trips(trace: str) -> int:
    """The times the client waited for the server: each turn from its messages to the server's.

    A message starts a line: time, F (client) or B (server), length, type, its contents (which may span
    lines, as SQL does). The server answers nothing until the client syncs or flushes."""
    senders = [fields[1] for fields in (line.split("\t") for line in trace.splitlines()) if len(fields) >= 4]
    return sum(1 for turn in pairwise(senders) if turn == ("F", "B"))


def test_a_step_that_starts_a_mission_costs_two_round_trips_to_postgresql(
    robot: Robot, tmp_path: Path
) -> None:
    """BEGIN with the locking reads, the writes with COMMIT: under load each round trip waits for the CPU."""
    InstantAction.objects.filter(robot=robot).update(status=ActionStatus.FINISHED)  # no factsheet request
    create("m1", robot)

    with protocol_trace(tmp_path / "trace") as trace:
        outcome = step(robot)

    assert round_trips(trace.read_text()) == 2
    assert header_ids(outcome) == [(Topic.ORDER, 0)]  # drawn in the second
    assert Mission.objects.get(name="m1").state == MissionState.RUNNING  # committed
    assert connection.get_autocommit() and not connection.in_atomic_block


def test_a_step_that_ends_the_robots_last_mission_looks_at_the_queue_again_in_the_commits_round_trip(
    robot: Robot, tmp_path: Path
) -> None:
    """BEGIN with the locking reads, then the writes, the queue lock, the look at the queue and COMMIT, in
    one round trip: the queue is not read again once the mission ended, as the first read held all of it
    (and a fleet of named missions tries no claim of an unbound one)."""
    InstantAction.objects.filter(robot=robot).update(status=ActionStatus.FINISHED)  # no factsheet request
    robot_step_module._unbound_seen.clear()
    create("m1", robot)
    [order] = orders(step(robot))
    put_state(robot, header_id=2, state=finished(order))

    with protocol_trace(tmp_path / "trace") as trace:
        outcome = step(robot, after=1.0)

    statements = trace.read_text()
    assert round_trips(statements) == 2
    assert "pg_advisory_xact_lock(" in statements and "SELECT EXISTS" in statements  # the look was made
    assert statements.index("SELECT EXISTS") < statements.index("COMMIT")  # sent inside the transaction
    assert [m.name for m in outcome.finished] == ["m1"]
    assert outcome.messages == []
    assert connection.get_autocommit() and not connection.in_atomic_block


@pytest.mark.parametrize("mission", [False, True], ids=["idle_robot", "mission_running"])
def test_a_step_that_ends_no_mission_takes_no_queue_lock(robot: Robot, tmp_path: Path, mission: bool) -> None:
    """Nothing a creation relies on changes in such a step: the look under the lock is for steps that end
    the robot's last mission."""
    InstantAction.objects.filter(robot=robot).update(status=ActionStatus.FINISHED)  # no factsheet request
    if mission:
        create("m1", robot)
        assert len(orders(step(robot))) == 1

    with protocol_trace(tmp_path / "trace") as trace:
        outcome = step(robot, after=1.0)

    statements = trace.read_text()
    assert "FOR UPDATE" in statements  # the step ran its transaction
    assert "pg_advisory" not in statements
    assert outcome.finished == [] and outcome.messages == []


def test_a_step_of_an_unknown_robot_does_nothing(db: None) -> None:
    outcome = robot_step(name="nobody-here", now=NOW)

    assert (outcome.address, outcome.messages) == (None, [])


def test_the_highest_priority_queued_mission_starts_first_and_equals_in_fifo_order(robot: Robot) -> None:
    """A robot's queue by priority (issue 41): default-priority missions keep the reference's FIFO."""
    route = {"name": "r", "route": {"waypoints": [{"x": 5.0, "y": 6.0, "theta": 0.0, "map_id": "map"}]}}
    for name, priority in (("low", 0), ("high-1", 3), ("high-2", 3)):
        spec = {"robot": robot.name, "mission_tree": [route], "priority": priority}
        mission_create(actor=TEST_ACTOR, name=name, prefix=None, spec=spec)
    Robot.objects.filter(name=robot.name).update(online=False)
    step(robot)  # offline: nothing starts
    Robot.objects.filter(name=robot.name).update(online=True)

    [order] = orders(step(robot))

    assert order.order_id.startswith("high-1-")
    assert Mission.objects.get(name="high-1").state == MissionState.RUNNING
    assert {Mission.objects.get(name=n).state for n in ("low", "high-2")} == {MissionState.PENDING}

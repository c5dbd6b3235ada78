"""The bridge's message handling against the real PostgreSQL and Redis (MQTT is bypassed: batches are handed
to `Bridge.handle` as the processing thread would)."""

import threading
import time
from collections.abc import Callable
from typing import Any

import orjson
import pytest
from django.db import connection
from django.test.utils import CaptureQueriesContext

from missions.models import Mission
from robots import livestate
from robots.choices import AgvClass
from robots.models import InstantAction, Robot
from robots.services import FACTSHEET_REQUEST
from robots.status import robot_check_heartbeats
from tests.dispatch.builders import error
from tests.vda5050.samples import full_factsheet
from tests.workers.bridge.messages import (
    connection_message,
    factsheet_message,
    running_order,
    state_message,
    step_requested,
    steps_queued,
    visualization_message,
)
from tests.workers.bridge.rows import held
from vda5050.models import ActionStatus, ConnectionState, ErrorLevel, InfoLevel, Information
from workers import metrics, tuning
from workers.bridge.loop import Bridge

MakeRobot = Callable[..., Robot]


def _reload(robot: Robot) -> Robot:
    return Robot.objects.get(name=robot.name)


def _counter(name: str, **labels: str) -> int:
    field = name + "".join(f"|{key}={value}" for key, value in sorted(labels.items()))
    return int(livestate.client().hget(metrics.COUNTERS, field) or 0)


def _flush_statements(bridge: Bridge) -> list[str]:
    """The SQL statements a flush runs, without the savepoint around them (the test's transaction holds
    the flush's own)."""
    with CaptureQueriesContext(connection) as queries:
        bridge.status_writer.flush()
    return [q["sql"] for q in queries if not q["sql"].startswith(("SAVEPOINT", "RELEASE SAVEPOINT"))]


def _waiting_factsheet_requests(robot: Robot) -> int:
    return InstantAction.objects.filter(
        robot=robot, action_type=FACTSHEET_REQUEST, status__isnull=True
    ).count()


# --- states ----------------------------------------------------------------------------------------------


def test_a_first_state_is_stored_and_brings_the_robot_online_with_a_step_and_a_factsheet_request(
    bridge: Bridge, robot: Robot
) -> None:
    message = state_message(robot, battery=55.0)

    bridge.handle([message])

    assert livestate.latest_state(robot.name).payload == message[1]
    assert _reload(robot).online is True
    assert livestate.client().sismember(livestate.ONLINE_SET, robot.name)
    assert livestate.last_seen([robot.name])[robot.name] is not None
    assert step_requested(robot)
    assert _waiting_factsheet_requests(robot) == 1


def test_a_robot_that_stays_online_is_not_asked_for_its_factsheet_again(bridge: Bridge, robot: Robot) -> None:
    bridge.handle([state_message(robot, header_id=1, at=0.0)])
    InstantAction.objects.filter(robot=robot).update(status=ActionStatus.FINISHED.value)

    bridge.handle([state_message(robot, header_id=2, at=1.0, order_id="o-n0-r0")])

    assert _waiting_factsheet_requests(robot) == 0


def test_robots_coming_online_together_are_marked_and_asked_for_factsheets_in_one_transaction(
    bridge: Bridge, make_robot: MakeRobot
) -> None:
    """A fleet (re)connecting at once must not cost the bridge's thread a transaction per robot."""
    answered, waiting, third = make_robot(), make_robot(), make_robot()
    InstantAction.objects.filter(robot__in=[answered, third]).update(status=ActionStatus.FINISHED.value)
    bridge.directory.reload()

    with CaptureQueriesContext(connection) as queries:
        bridge.handle([state_message(robot, header_id=1) for robot in (answered, waiting, third)])

    assert [_waiting_factsheet_requests(r) for r in (answered, waiting, third)] == [1, 1, 1]
    assert all(_reload(r).online for r in (answered, waiting, third))
    assert steps_queued([answered, waiting, third]) == {answered.name, waiting.name, third.name}
    statements = [q["sql"].split(" ", 1)[0] for q in queries]
    assert statements.count("INSERT") == 1 and statements.count("UPDATE") == 1


def test_a_repeated_state_with_nothing_new_for_the_engine_requests_no_step(
    bridge: Bridge, robot: Robot
) -> None:
    bridge.handle([state_message(robot, header_id=1, at=0.0)])
    assert step_requested(robot)
    later = state_message(robot, header_id=2, at=1.0, pose=(4.0, 5.0, 1.0, "map"), velocity=(0.4, 0.0, 0.0))

    bridge.handle([later])

    assert livestate.latest_state(robot.name).payload == later[1]  # stored all the same: the pose is newer
    assert not step_requested(robot)


def test_a_state_with_changed_order_progress_requests_a_step(bridge: Bridge, robot: Robot) -> None:
    bridge.handle([state_message(robot, header_id=1, order_id="m-n0-r0", node_states=[2, 4])])
    assert step_requested(robot)

    bridge.handle(
        [
            state_message(
                robot, header_id=2, at=1.0, order_id="m-n0-r0", last_node_sequence_id=2, node_states=[4]
            )
        ]
    )

    assert step_requested(robot)


@pytest.mark.parametrize(
    "change",
    [
        pytest.param({"action_states": [("a1", ActionStatus.FINISHED)]}, id="action-state"),
        pytest.param({"errors": [error("blocked", ErrorLevel.FATAL)]}, id="error"),
        pytest.param({"battery": 79.0}, id="battery-percent"),
        pytest.param({"charging": True}, id="charging"),
    ],
)
def test_a_state_with_anything_else_the_engine_reads_requests_a_step(
    bridge: Bridge, robot: Robot, change: dict
) -> None:
    bridge.handle([state_message(robot, header_id=1, battery=80.0)])
    step_requested(robot)

    bridge.handle([state_message(robot, header_id=2, at=1.0, **{"battery": 80.0, **change})])

    assert step_requested(robot)


def test_a_robot_that_only_took_its_order_needs_no_step_and_the_flush_marks_the_order_accepted(
    bridge: Bridge, robot: Robot
) -> None:
    order_id = running_order(bridge, robot)

    bridge.handle([state_message(robot, header_id=2, at=1.0, order_id=order_id, node_states=[2])])

    assert not step_requested(robot)
    assert not Mission.objects.get(robot=robot.name).order_accepted  # written by the flush, not per state
    bridge.status_writer.flush()
    assert Mission.objects.get(robot=robot.name).order_accepted


def test_a_robot_that_took_its_order_dropping_a_finished_instant_action_needs_no_step(
    bridge: Bridge, robot: Robot
) -> None:
    """As a robot does when it takes an order: the instant action that finished before it (the factsheet
    request every robot gets when it comes online) is gone from its state."""
    order_id = running_order(bridge, robot)
    finished = [("factsheet-1", ActionStatus.FINISHED)]
    bridge.handle([state_message(robot, header_id=2, at=1.0, action_states=finished)])
    assert step_requested(robot)  # the action finished: its step records that

    bridge.handle([state_message(robot, header_id=3, at=2.0, order_id=order_id, node_states=[2])])

    assert not step_requested(robot)
    bridge.status_writer.flush()
    assert Mission.objects.get(robot=robot.name).order_accepted


def test_a_state_stored_before_finished_actions_were_kept_apart_leaves_the_next_state_its_step(
    bridge: Bridge, robot: Robot
) -> None:
    """A bridge of the version before kept no finished actions apart: what it stored cannot tell whether
    an action finished since, so taking the order gets a step, as it did then."""
    order_id = running_order(bridge, robot)
    livestate.client().hdel(livestate.robot_key(robot.name), "finished")

    bridge.handle([state_message(robot, header_id=2, at=1.0, order_id=order_id, node_states=[2])])

    assert step_requested(robot)


def test_an_order_the_robot_took_from_elsewhere_is_not_marked_accepted(bridge: Bridge, robot: Robot) -> None:
    running_order(bridge, robot)

    bridge.handle([state_message(robot, header_id=2, at=1.0, order_id="someone-else", node_states=[2])])
    bridge.status_writer.flush()

    assert not Mission.objects.get(robot=robot.name).order_accepted


def test_a_robot_that_took_its_order_with_an_error_gets_a_step(bridge: Bridge, robot: Robot) -> None:
    order_id = running_order(bridge, robot)
    blocked = [error("blocked", ErrorLevel.WARNING)]

    bridge.handle(
        [state_message(robot, header_id=2, at=1.0, order_id=order_id, node_states=[2], errors=blocked)]
    )

    assert step_requested(robot)


@pytest.mark.parametrize(
    ("header_id", "at"),
    [
        pytest.param(5, 0.0, id="duplicate"),
        pytest.param(9, -1.0, id="older-timestamp"),
        pytest.param(4, 0.0, id="same-time-lower-header-id"),
    ],
)
def test_a_stale_state_is_ignored(bridge: Bridge, robot: Robot, header_id: int, at: float) -> None:
    current = state_message(robot, header_id=5, at=0.0)
    bridge.handle([current])
    step_requested(robot)

    bridge.handle([state_message(robot, header_id=header_id, at=at, order_id="late-n0-r0", node_states=[2])])

    assert livestate.latest_state(robot.name).payload == current[1]
    assert not step_requested(robot)


def test_a_state_with_the_same_timestamp_and_a_higher_header_id_is_newer(
    bridge: Bridge, robot: Robot
) -> None:
    bridge.handle([state_message(robot, header_id=5, at=0.0)])
    newer = state_message(robot, header_id=6, at=0.0, order_id="m-n0-r0", node_states=[2])

    bridge.handle([newer])

    assert livestate.latest_state(robot.name).payload == newer[1]


def test_a_batch_keeps_the_newest_state_whatever_the_arrival_order(bridge: Bridge, robot: Robot) -> None:
    newest = state_message(robot, header_id=3, at=2.0, order_id="m-n0-r0")

    bridge.handle(
        [state_message(robot, header_id=2, at=1.0), newest, state_message(robot, header_id=1, at=0.0)]
    )

    assert livestate.latest_state(robot.name).payload == newest[1]


def test_a_stale_state_does_not_overwrite_the_status_written_to_the_database(
    bridge: Bridge, robot: Robot
) -> None:
    bridge.handle([state_message(robot, header_id=2, at=1.0, battery=50.0, pose=(3.0, 3.0, 0.0, "map"))])

    bridge.handle([state_message(robot, header_id=1, at=0.0, battery=90.0, pose=(0.0, 0.0, 0.0, "map"))])
    bridge.status_writer.flush()

    stored = _reload(robot)
    assert (stored.battery_level, stored.pose_x) == (50.0, 3.0)


def test_states_are_stored_and_robots_come_online_after_redis_lost_the_scripts_and_counted_once(
    bridge: Bridge, make_robot: MakeRobot
) -> None:
    """A Redis restart forgets loaded scripts: the bridge loads them again, stores the batch's states and
    brings its robots online; the counters that went out in the same round trip are not added twice."""
    robots = [make_robot(), make_robot()]
    bridge.directory.reload()
    messages = [state_message(robot, battery=41.0) for robot in robots]
    counted_before = _counter(metrics.MESSAGES_IN, topic="state")
    livestate.client().script_flush()

    bridge.handle(messages)

    assert [livestate.latest_state(robot.name).payload for robot in robots] == [
        payload for _, payload in messages
    ]
    assert all(_reload(robot).online for robot in robots)
    assert steps_queued(robots) == {robot.name for robot in robots}
    assert _counter(metrics.MESSAGES_IN, topic="state") == counted_before + 2


@pytest.mark.django_db(transaction=True)  # run_once closes the connection a test transaction holds
def test_a_backlog_is_handled_a_batch_at_a_time_each_batch_requesting_its_steps_before_the_next_is_read(
    bridge: Bridge, make_robot: MakeRobot, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(tuning, "BATCH_LIMIT", 2)
    robots = [make_robot() for _ in range(3)]
    bridge.directory.reload()
    for robot in robots:
        step_requested(robot)  # the creation's
        bridge.inbox.put((*state_message(robot), time.time()))

    bridge.run_once(timeout=0)

    assert steps_queued(robots) == {robots[0].name, robots[1].name}
    assert livestate.latest_state(robots[2].name).payload is None
    bridge.run_once(timeout=0)
    assert step_requested(robots[2])


@pytest.mark.django_db(transaction=True)  # run_once closes the connection a test transaction holds
def test_a_batch_takes_what_arrives_within_its_window_after_its_first_message(
    bridge: Bridge, make_robot: MakeRobot, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(tuning, "BATCH_WINDOW_SECONDS", 0.5)
    first, second = make_robot(), make_robot()
    bridge.directory.reload()
    step_requested(first), step_requested(second)  # the creations'
    bridge.inbox.put((*state_message(first), time.time()))
    later = threading.Timer(0.05, lambda: bridge.inbox.put((*state_message(second), time.time())))
    later.start()

    bridge.run_once(timeout=0)

    later.join()
    assert steps_queued([first, second]) == {first.name, second.name}


@pytest.mark.django_db(transaction=True)
@pytest.mark.parametrize(
    ("limit", "window", "waited"),
    [
        pytest.param(2, 10.0, 0.0, id="full-batch"),
        pytest.param(100, 10.0, 10.0, id="first-message-waited-the-window"),
        pytest.param(100, 0.1, -3600.0, id="clock-stepped-back-an-hour"),
    ],
)
def test_a_batch_waits_no_longer_than_its_window_and_not_once_full_or_once_its_first_message_waited_it(
    bridge: Bridge,
    make_robot: MakeRobot,
    monkeypatch: pytest.MonkeyPatch,
    limit: int,
    window: float,
    waited: float,
) -> None:
    monkeypatch.setattr(tuning, "BATCH_LIMIT", limit)
    monkeypatch.setattr(tuning, "BATCH_WINDOW_SECONDS", window)
    robots = [make_robot(), make_robot()]
    bridge.directory.reload()
    for robot in robots:
        bridge.inbox.put((*state_message(robot), time.time() - waited))
    started = time.monotonic()

    bridge.run_once(timeout=0)

    assert time.monotonic() - started < 5.0  # a wrong wait here is 10 s or an hour
    assert steps_queued(robots) == {robot.name for robot in robots}


# --- status written to PostgreSQL ------------------------------------------------------------------------


def test_pose_and_battery_reach_the_database_only_on_flush(bridge: Bridge, robot: Robot) -> None:
    bridge.handle(
        [
            state_message(
                robot,
                battery=42.5,
                pose=(3.5, -1.25, 0.75, "floor2"),
                errors=[error("lowBattery", ErrorLevel.WARNING, "charge soon", nodeId="n1")],
            )
        ]
    )
    assert (_reload(robot).battery_level, _reload(robot).pose_x) == (0.0, 0.0)

    bridge.status_writer.flush()

    stored = _reload(robot)
    assert (stored.battery_level, stored.pose_x, stored.pose_y, stored.pose_theta) == (42.5, 3.5, -1.25, 0.75)
    assert (stored.pose_map_id, stored.position_initialized, stored.last_state_at is not None) == (
        "floor2",
        True,
        True,
    )
    assert stored.hardware_version == {"manufacturer": "RobotCompany", "serial_number": robot.serial_number}
    assert stored.errors == {
        "lowBattery": {"level": "WARNING", "description": "charge soon", "references": {"nodeId": "n1"}}
    }


@pytest.mark.django_db(transaction=True)  # autocommit, as the bridge runs: a refused row aborts no batch
def test_a_status_the_database_refuses_is_dropped_and_the_other_robots_are_written(
    bridge: Bridge, make_robot: MakeRobot
) -> None:
    refused, healthy = make_robot(), make_robot()
    bridge.directory.reload()
    failed_before = _counter(metrics.STATUS_WRITES_FAILED)
    bridge.handle([state_message(refused), state_message(healthy, pose=(4.0, 5.0, 1.0, "map"))])
    # The bridge drops messages holding a NUL (test_hostile.py), but whatever PostgreSQL refuses is dropped
    # here too: jsonb cannot hold a NUL.
    bridge.status_writer.pending(refused.name)["errors"] = {"blocked": {"description": "stuck\x00here"}}

    bridge.status_writer.flush()

    assert _reload(healthy).pose_x == 4.0
    assert (_reload(refused).pose_x, _reload(refused).errors) == (0.0, {})
    assert _counter(metrics.STATUS_WRITES_FAILED) == failed_before + 1


def test_user_info_becomes_the_robots_info_messages(bridge: Bridge, robot: Robot) -> None:
    topic_name, payload = state_message(robot)
    message = orjson.loads(payload)
    info = Information(info_type="user_info", info_description='{"shelf": 4}', info_level=InfoLevel.INFO)
    message["information"] = [info.model_dump(mode="json", by_alias=True, exclude_none=True)]

    bridge.handle([(topic_name, orjson.dumps(message))])
    bridge.status_writer.flush()

    assert _reload(robot).info_messages == {"shelf": 4}


def test_one_flush_locks_and_writes_all_changed_robots_in_one_statement(
    bridge: Bridge, make_robot: MakeRobot
) -> None:
    robots = [make_robot(), make_robot(), make_robot()]
    bridge.directory.reload()
    bridge.handle([state_message(r, battery=30.0 + i) for i, r in enumerate(robots)])

    assert len(_flush_statements(bridge)) == 1

    assert [_reload(r).battery_level for r in robots] == [30.0, 31.0, 32.0]


def test_a_flush_with_nothing_changed_writes_nothing(
    bridge: Bridge, robot: Robot, django_assert_num_queries
) -> None:
    bridge.handle([state_message(robot, header_id=1, battery=30.0)])
    bridge.status_writer.flush()
    bridge.handle([state_message(robot, header_id=2, at=1.0, battery=30.0)])

    with django_assert_num_queries(0):
        bridge.status_writer.flush()


def test_a_flush_writes_only_the_robots_that_changed(bridge: Bridge, make_robot: MakeRobot) -> None:
    moving, parked = make_robot(), make_robot()
    bridge.directory.reload()
    bridge.handle([state_message(moving, header_id=1), state_message(parked, header_id=1)])
    bridge.status_writer.flush()
    Robot.objects.filter(name=parked.name).update(battery_level=-1.0)  # would be overwritten if written

    bridge.handle(
        [
            state_message(moving, header_id=2, at=1.0, pose=(9.0, 9.0, 0.0, "map")),
            state_message(parked, header_id=2, at=1.0),
        ]
    )
    assert len(_flush_statements(bridge)) == 1

    assert (_reload(moving).pose_x, _reload(parked).battery_level) == (9.0, -1.0)


def _age(bridge: Bridge, seconds: float) -> None:
    """As if `seconds` had passed since each robot was last written and heard."""
    for status in bridge.status_writer.statuses.values():
        status.written_at -= seconds
        status.heard_at -= seconds


def test_an_unchanged_status_rewrites_only_a_newer_last_state_time_once_its_period_is_up(
    bridge: Bridge, make_robot: MakeRobot
) -> None:
    heard, silent = make_robot(), make_robot()
    bridge.directory.reload()
    bridge.handle([state_message(heard, header_id=1), state_message(silent, header_id=1)])
    bridge.status_writer.flush()
    written = _reload(heard).last_state_at
    Robot.objects.filter(name=silent.name).update(last_state_at=None)  # would be set again if rewritten
    bridge.handle([state_message(heard, header_id=2, at=1.0)])

    bridge.status_writer.flush()
    assert _reload(heard).last_state_at == written  # its period is not up

    _age(bridge, tuning.LAST_STATE_AT_PERIOD)
    bridge.status_writer.flush()
    assert _reload(heard).last_state_at > written
    assert _reload(silent).last_state_at is None  # nothing newer to write


def test_robots_heard_together_rewrite_their_last_state_times_at_different_moments(
    bridge: Bridge, make_robot: MakeRobot
) -> None:
    """A fleet that came online together must not write every unchanged status in the same flush."""
    robots = [make_robot() for _ in range(20)]
    bridge.directory.reload()
    bridge.handle([state_message(r, header_id=1) for r in robots])
    bridge.status_writer.flush()
    Robot.objects.filter(name__in=[r.name for r in robots]).update(last_state_at=None)
    bridge.handle([state_message(r, header_id=2, at=1.0) for r in robots])

    _age(bridge, 0.75 * tuning.LAST_STATE_AT_PERIOD)
    bridge.status_writer.flush()

    written = Robot.objects.filter(name__in=[r.name for r in robots], last_state_at__isnull=False).count()
    assert 0 < written < len(robots)


def test_a_robot_silent_for_long_is_forgotten_and_written_in_full_when_heard_again(
    bridge: Bridge, robot: Robot
) -> None:
    bridge.handle([state_message(robot, header_id=1, battery=40.0)])
    bridge.status_writer.flush()
    _age(bridge, tuning.FORGET_STATUS_SECONDS)

    bridge.status_writer.flush()
    assert robot.name not in bridge.status_writer.statuses

    Robot.objects.filter(name=robot.name).update(battery_level=-1.0)
    bridge.handle([state_message(robot, header_id=2, at=1.0, battery=40.0)])
    bridge.status_writer.flush()
    assert _reload(robot).battery_level == 40.0


def test_visualization_updates_the_pose_without_a_step(bridge: Bridge, robot: Robot) -> None:
    bridge.handle([state_message(robot)])
    bridge.status_writer.flush()
    step_requested(robot)

    bridge.handle([visualization_message(robot, 6.0, 7.0, -0.5, at=0.5)])
    bridge.status_writer.flush()

    stored = _reload(robot)
    assert (stored.pose_x, stored.pose_y, stored.pose_theta) == (6.0, 7.0, -0.5)
    assert not step_requested(robot)


def test_a_visualization_before_any_state_keeps_the_last_state_time(bridge: Bridge, robot: Robot) -> None:
    before_restart = Bridge()
    before_restart.directory.reload()
    before_restart.handle([state_message(robot)])
    before_restart.status_writer.flush()
    assert _reload(robot).last_state_at is not None

    bridge.handle([visualization_message(robot, 6.0, 7.0, -0.5)])  # e.g. after a bridge restart
    bridge.status_writer.flush()

    stored = _reload(robot)
    assert (stored.pose_x, stored.last_state_at is not None) == (6.0, True)


# --- connection ------------------------------------------------------------------------------------------


@pytest.mark.parametrize("connection_state", [ConnectionState.CONNECTIONBROKEN, ConnectionState.OFFLINE])
def test_a_lost_connection_marks_the_robot_offline_at_once_and_requests_a_step(
    bridge: Bridge, robot: Robot, connection_state: ConnectionState
) -> None:
    bridge.handle([state_message(robot)])
    step_requested(robot)

    bridge.handle([connection_message(robot, connection_state)])

    assert _reload(robot).online is False
    assert not livestate.client().sismember(livestate.ONLINE_SET, robot.name)
    assert step_requested(robot)


def test_a_connection_online_message_changes_nothing(bridge: Bridge, robot: Robot) -> None:
    bridge.handle([connection_message(robot, ConnectionState.ONLINE)])

    assert _reload(robot).online is False
    assert not step_requested(robot)


def test_a_robot_that_lost_its_connection_comes_back_with_its_next_state(
    bridge: Bridge, robot: Robot
) -> None:
    bridge.handle([state_message(robot, header_id=1)])
    bridge.handle([connection_message(robot, ConnectionState.CONNECTIONBROKEN)])
    step_requested(robot)

    bridge.handle([state_message(robot, header_id=2, at=5.0)])

    assert _reload(robot).online is True
    assert step_requested(robot)


def test_a_state_after_a_connection_loss_in_the_same_batch_leaves_the_robot_online(
    bridge: Bridge, robot: Robot
) -> None:
    bridge.handle([state_message(robot, header_id=1)])

    bridge.handle(
        [
            connection_message(robot, ConnectionState.CONNECTIONBROKEN),
            state_message(robot, header_id=2, at=5.0),
        ]
    )

    assert _reload(robot).online is True


# --- factsheet -------------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("agv_class", "stored_class"),
    [
        ("FORKLIFT", AgvClass.FORKLIFT),
        ("CARRIER", AgvClass.CARRIER),
        ("MANIPULATOR", AgvClass.MANIPULATOR),
        ("HUMANOID", AgvClass.HUMANOID),
        ("SPACESHIP", AgvClass.CARRIER),
    ],
)
def test_a_factsheet_is_stored_whole_with_class_and_top_speed(
    bridge: Bridge, robot: Robot, agv_class: str, stored_class: AgvClass
) -> None:
    factsheet = full_factsheet()
    factsheet.type_specification.agv_class = agv_class
    factsheet.physical_parameters.speed_max = 2.25
    message = factsheet_message(robot, factsheet)

    bridge.handle([message])

    stored = _reload(robot)
    assert stored.factsheet == orjson.loads(message[1])
    assert (stored.agv_class, stored.speed_max) == (stored_class, 2.25)


# --- heartbeats ------------------------------------------------------------------------------------------


def test_robot_check_heartbeats_marks_silent_robots_offline(
    bridge: Bridge, make_robot: MakeRobot, django_capture_on_commit_callbacks: Any
) -> None:
    silent, talking, unheard = (make_robot(heartbeat_timeout=5.0) for _ in range(3))
    bridge.directory.reload()
    now = time.time()
    bridge.handle([state_message(silent)], received_at=now - 6.0)
    bridge.handle([state_message(talking)], received_at=now - 4.0)
    Robot.objects.filter(name=unheard.name).update(online=True)  # online in the database, never seen
    for robot in (silent, talking, unheard):
        step_requested(robot)

    with django_capture_on_commit_callbacks(execute=True):  # its steps are asked for once its writes commit
        offline = robot_check_heartbeats(now=now)

    assert sorted(offline) == sorted([silent.name, unheard.name])
    assert [_reload(r).online for r in (silent, talking, unheard)] == [False, True, False]
    assert not livestate.client().sismember(livestate.ONLINE_SET, silent.name)
    assert [step_requested(r) for r in (silent, talking, unheard)] == [True, False, True]


def test_robot_check_heartbeats_marks_a_robot_heard_but_stored_offline_online(
    bridge: Bridge, make_robot: MakeRobot, django_capture_on_commit_callbacks: Any
) -> None:
    """A bridge killed between marking a robot online in Redis and in PostgreSQL: the robot publishes,
    Redis knows it, its row says offline. The heartbeat check puts that right, whatever the set holds."""
    in_set, not_in_set = make_robot(heartbeat_timeout=5.0), make_robot(heartbeat_timeout=5.0)
    bridge.directory.reload()
    bridge.handle([state_message(in_set), state_message(not_in_set)])
    Robot.objects.filter(name__in=[in_set.name, not_in_set.name]).update(online=False)
    livestate.client().srem(livestate.ONLINE_SET, not_in_set.name)
    InstantAction.objects.filter(robot_id__in=[in_set.name, not_in_set.name]).delete()
    for robot in (in_set, not_in_set):
        step_requested(robot)

    with django_capture_on_commit_callbacks(execute=True):
        changed = robot_check_heartbeats(now=time.time())

    assert sorted(changed) == sorted([in_set.name, not_in_set.name])
    assert [_reload(r).online for r in (in_set, not_in_set)] == [True, True]
    assert livestate.client().smismember(livestate.ONLINE_SET, [in_set.name, not_in_set.name]) == [1, 1]
    assert [step_requested(r) for r in (in_set, not_in_set)] == [True, True]
    assert InstantAction.objects.filter(robot_id=in_set.name, action_type=FACTSHEET_REQUEST).count() == 1
    assert robot_check_heartbeats(now=time.time()) == []  # nothing left to put right


def test_a_robot_that_said_it_is_offline_stays_offline_until_heard_again(
    bridge: Bridge, make_robot: MakeRobot
) -> None:
    robot = make_robot(heartbeat_timeout=5.0)
    bridge.directory.reload()
    bridge.handle([state_message(robot, header_id=1)])
    assert _reload(robot).online is True

    bridge.handle([connection_message(robot, ConnectionState.OFFLINE)])
    assert robot_check_heartbeats(now=time.time()) == []  # heard 0 s ago, but said so since

    assert _reload(robot).online is False
    bridge.handle([state_message(robot, header_id=2)])
    assert _reload(robot).online is True


@pytest.mark.django_db(transaction=True)  # the other connection sees the robots only once they are committed
def test_a_robot_a_step_holds_is_skipped_by_the_flush_and_written_by_the_next(
    bridge: Bridge, make_robot: MakeRobot
) -> None:
    busy, free = make_robot(), make_robot()
    bridge.directory.reload()
    bridge.handle([state_message(busy, battery=21.0), state_message(free, battery=22.0)])

    with held("SELECT 1 FROM robots_robot WHERE name = %s FOR UPDATE", [busy.name]):
        started = time.monotonic()
        bridge.status_writer.flush()
        assert time.monotonic() - started < 1
    assert (_reload(busy).battery_level, _reload(free).battery_level) == (0.0, 22.0)

    bridge.status_writer.flush()

    assert _reload(busy).battery_level == 21.0


@pytest.mark.django_db(transaction=True)
def test_a_deleted_robot_is_not_written_again_and_again(bridge: Bridge, make_robot: MakeRobot) -> None:
    gone = make_robot()
    bridge.directory.reload()
    bridge.handle([state_message(gone, battery=21.0)])
    Robot.objects.filter(name=gone.name).delete()

    bridge.status_writer.flush()

    with CaptureQueriesContext(connection) as queries:
        bridge.status_writer.flush()
    assert len(queries) == 0


@pytest.mark.django_db(transaction=True)
def test_an_order_acceptance_of_a_mission_a_step_holds_is_dropped_without_waiting(
    bridge: Bridge, robot: Robot
) -> None:
    order_id = running_order(bridge, robot)
    bridge.handle([state_message(robot, header_id=2, at=1.0, order_id=order_id, node_states=[2])])

    with held("SELECT 1 FROM missions_mission WHERE robot = %s FOR UPDATE", [robot.name]):
        started = time.monotonic()
        bridge.status_writer.flush()
        assert time.monotonic() - started < 1

    assert not Mission.objects.get(robot=robot.name).order_accepted


@pytest.mark.django_db(transaction=True)  # the writer's and the other connection see committed robots only
def test_a_flush_waiting_for_the_database_does_not_hold_up_the_states_that_arrive_meanwhile(
    bridge: Bridge, robot: Robot, settings: Any
) -> None:
    settings.BRIDGE_STATUS_FLUSH_SECONDS = 0  # a flush is due at every iteration
    bridge.status_writer.start()
    try:
        _handle_while_a_flush_waits(bridge, robot)
    finally:
        bridge.status_writer.stop()


def _handle_while_a_flush_waits(bridge: Bridge, robot: Robot) -> None:
    bridge.inbox.put((*state_message(robot, header_id=1, battery=30.0), time.time()))
    bridge.run_once(timeout=0)  # online, and its first status written
    assert _wait_written(bridge)
    # Every write waits for the lock; a write in this thread (not the writer's) would fail the test.
    with held(f"LOCK TABLE {Robot._meta.db_table} IN EXCLUSIVE MODE", []):
        bridge.inbox.put((*state_message(robot, header_id=2, at=1.0, battery=31.0), time.time()))
        bridge.run_once(timeout=0)  # its flush goes to the writer, which waits for the lock
        later = state_message(robot, header_id=3, at=2.0, battery=32.0)
        bridge.inbox.put((*later, time.time()))

        bridge.run_once(timeout=0)

        assert livestate.latest_state(robot.name).payload == later[1]
        assert not bridge.status_writer._written.is_set()
    assert _wait_written(bridge)
    assert _reload(robot).battery_level == 31.0
    bridge.run_once(timeout=0)  # the next flush, with what arrived meanwhile
    assert _wait_written(bridge)
    assert _reload(robot).battery_level == 32.0


def _wait_written(bridge: Bridge) -> bool:
    return bridge.status_writer._written.wait(timeout=10)

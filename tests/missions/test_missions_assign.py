"""`missions.services.missions_assign`: unbound missions bound to free capable robots in PostgreSQL, and the
step giving back a mission whose robot cannot take it (issue 41). Real PostgreSQL and Redis, outside a
test transaction, as the workers run; the robots' rows are written as the bridge writes them."""

import threading
from datetime import timedelta
from typing import Any

import pytest
from django.db import connection, transaction
from django.utils import timezone
from pytest_django.fixtures import Settings

from changes.models import Change
from dispatch.assignment import ALL_BUSY, NO_LABELS, NONE_ONLINE, NOT_YET_ASSIGNED
from missions import robot_step as robot_step_module
from missions import services
from missions.choices import MissionState
from missions.models import Mission
from missions.robot_step import robot_step
from missions.services import mission_claim, mission_create, missions_assign
from robots.models import Robot
from robots.services import robot_delete
from tests.dispatch.builders import finished
from tests.factories import TEST_ACTOR, RobotFactory
from tests.missions.test_robot_step import orders, put_state

pytestmark = pytest.mark.django_db(transaction=True)


@pytest.fixture(autouse=True)
def bind_at_once(settings: Settings) -> None:
    """Missions created just now are bound at once: the burst hold has tests of its own below."""
    settings.ASSIGNMENT_QUIET_SECONDS = 0.0


def robot(name: str, *, x: float = 0.0, y: float = 0.0, labels: tuple[str, ...] = (), **fields: Any) -> Robot:
    """An online, charged, idle robot at (x, y) on "map"."""
    values = dict(
        online=True,
        battery_level=80.0,
        pose_x=x,
        pose_y=y,
        pose_map_id="map",
        last_state_at=timezone.now(),
        labels=list(labels),
    )
    return RobotFactory(name=name, **{**values, **fields})


def unbound(name: str, *, x: float = 0.0, y: float = 0.0, **spec: Any) -> Mission:
    route = {"route": {"waypoints": [{"x": x, "y": y, "map_id": "map"}]}}
    return mission_create(actor=TEST_ACTOR, name=name, prefix=None, spec={"mission_tree": [route], **spec})


def robot_of(name: str) -> str | None:
    return Mission.objects.get(name=name).robot


def test_the_nearest_free_robot_is_bound_and_the_binding_recorded() -> None:
    robot("far", x=50.0)
    robot("near", x=2.0)
    unbound("m1", x=1.0)

    assert missions_assign().bound == {"m1": "near"}

    mission = Mission.objects.get(name="m1")
    assert (mission.robot, mission.waiting_reason, mission.state) == ("near", None, MissionState.PENDING)
    [binding] = mission.assignment
    assert binding["robot"] == "near" and binding["released_at"] is None and binding["reason"] is None
    assert binding["bound_at"].endswith("Z")


def test_a_mission_nobody_can_do_waits_with_its_reason_until_a_robot_qualifies() -> None:
    robot("plain")
    unbound("m1", robot_selector={"labels": ["forklift"]})

    assert missions_assign().bound == {}
    assert Mission.objects.get(name="m1").waiting_reason == NO_LABELS.format(labels="forklift")
    assert robot_of("m1") is None

    Robot.objects.filter(name="plain").update(labels=["forklift"])
    assert missions_assign().bound == {"m1": "plain"}


def test_reasons_follow_the_robots_state() -> None:
    robot("r1", online=False)
    unbound("m1")
    missions_assign()
    assert Mission.objects.get(name="m1").waiting_reason == NONE_ONLINE

    Robot.objects.filter(name="r1").update(online=True)
    own = {"robot": "r1", "mission_tree": [{"route": {"waypoints": [{"x": 0, "y": 0}]}}]}
    mission_create(actor=TEST_ACTOR, name="own", prefix=None, spec=own)
    Mission.objects.filter(name="own").update(state=MissionState.RUNNING)
    missions_assign()
    assert Mission.objects.get(name="m1").waiting_reason == ALL_BUSY


def test_a_robot_with_a_bound_mission_not_yet_started_gets_no_second_one() -> None:
    robot("r1")
    unbound("m1")
    unbound("m2", priority=5)
    assert missions_assign().bound == {"m2": "r1"}

    assert missions_assign().bound == {}
    assert robot_of("m1") is None


def test_a_robots_own_queue_head_runs_before_younger_unbound_missions_of_its_priority() -> None:
    robot("r1")
    robot("r2", x=100.0)
    route = {"route": {"waypoints": [{"x": 0, "y": 0, "map_id": "map"}]}}
    mission_create(actor=TEST_ACTOR, name="own", prefix=None, spec={"robot": "r1", "mission_tree": [route]})
    unbound("m1")

    assert missions_assign().bound == {"m1": "r2"}


def test_many_runs_at_once_never_bind_a_mission_twice_nor_a_robot_twice() -> None:
    for index in range(12):
        robot(f"r{index:02d}", x=float(index))
    for index in range(30):
        unbound(f"m{index:02d}", x=float(index % 7), priority=index % 3)
    barrier = threading.Barrier(6)
    results: list[dict[str, str]] = []
    errors: list[BaseException] = []

    def run() -> None:
        try:
            barrier.wait()
            for _ in range(3):
                results.append(missions_assign().bound)
        except BaseException as error:  # reported below
            errors.append(error)
        finally:
            connection.close()

    threads = [threading.Thread(target=run) for _ in range(6)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()

    assert not errors
    claimed = [(mission, robot) for result in results for mission, robot in result.items()]
    assert len({mission for mission, _ in claimed}) == len(claimed)  # no mission bound by two runs
    assert len({robot for _, robot in claimed}) == len(claimed) == 12  # no robot given two; all used
    bound = Mission.objects.exclude(robot=None)
    assert sorted(bound.values_list("robot", flat=True)) == [f"r{index:02d}" for index in range(12)]
    assert all(len(mission.assignment) == 1 for mission in bound)
    # The 12 bound are the highest priorities first.
    assert min(bound.values_list("priority", flat=True)) >= 1


def test_a_step_gives_back_a_bound_mission_its_robot_cannot_start(make_robot) -> None:
    created = make_robot(prefix="give", labels=["forklift"])
    Robot.objects.filter(name=created.name).update(
        online=True, battery_level=80.0, last_state_at=timezone.now()
    )
    put_state(created, header_id=1, battery=5.0)  # below the critical level, as the step sees it
    unbound("m1", robot_selector={"labels": ["forklift"]})
    assert missions_assign().bound == {"m1": created.name}

    outcome = robot_step(name=created.name)

    assert outcome.released == ["m1"]
    mission = Mission.objects.get(name="m1")
    assert (mission.robot, mission.state) == (None, MissionState.PENDING)
    [binding] = mission.assignment
    assert binding["robot"] == created.name
    assert binding["released_at"] is not None and "Battery" in binding["reason"]


def test_a_named_mission_is_not_given_back_by_its_robot(make_robot) -> None:
    created = make_robot(prefix="keep")
    Robot.objects.filter(name=created.name).update(online=True)
    put_state(created, header_id=1, battery=5.0)
    route = {"route": {"waypoints": [{"x": 0, "y": 0}]}}
    spec = {"robot": created.name, "mission_tree": [route]}
    mission_create(actor=TEST_ACTOR, name="m1", prefix=None, spec=spec)

    assert robot_step(name=created.name).released == []
    assert robot_of("m1") == created.name


def test_missions_bound_to_a_deleted_robot_go_back_to_the_pool() -> None:
    doomed = robot("doomed")
    unbound("m1")
    assert missions_assign().bound == {"m1": "doomed"}

    robot_delete(actor=TEST_ACTOR, robot=doomed)
    missions_assign()

    mission = Mission.objects.get(name="m1")
    assert mission.robot is None
    assert mission.assignment[-1]["reason"] == "Robot was deleted"


def test_an_unbound_mission_past_its_deadline_fails_and_is_never_bound() -> None:
    robot("r1")
    unbound("late", deadline=timezone.now() - timedelta(seconds=1))

    assert missions_assign().bound == {}

    mission = Mission.objects.get(name="late")
    assert (mission.state, mission.failure_category, mission.robot) == (MissionState.FAILED, "DEADLINE", None)
    assert mission.node_status["root"]["state"] == MissionState.FAILED


def claim(robot: str, *, hold: threading.Barrier | None = None) -> str | None:
    """The mission `mission_claim` chooses, in a transaction of its own as the step's (which binds it), held
    open until `hold` lets it go."""
    with transaction.atomic():
        claimed = mission_claim(robot=robot)
        if hold is not None:
            hold.wait()
        return None if claimed is None else claimed.name


def created_ago(name: str, seconds: float) -> None:
    Mission.objects.filter(name=name).update(created_at=timezone.now() - timedelta(seconds=seconds))


def test_a_burst_still_arriving_is_held_while_free_robots_outnumber_it(settings: Settings) -> None:
    settings.ASSIGNMENT_QUIET_SECONDS, settings.ASSIGNMENT_HOLD_SECONDS = 5.0, 60.0
    for index in range(3):
        robot(f"r{index}", x=float(index))
    unbound("m1")
    unbound("m2")

    run = missions_assign()
    assert run.bound == {}
    assert run.hold is not None and 4.0 < run.hold <= 5.0
    assert robot_of("m1") is None

    created_ago("m1", 6.0)  # the burst paused: the newest is older than the quiet time
    created_ago("m2", 5.5)
    run = missions_assign()
    assert (run.hold, sorted(run.bound)) == (None, ["m1", "m2"])


def test_a_burst_is_bound_at_once_when_it_has_as_many_missions_as_free_robots(
    settings: Settings,
) -> None:
    settings.ASSIGNMENT_QUIET_SECONDS = 5.0
    robot("r0")
    robot("r1", x=1.0)
    robot("busy", x=2.0, online=False)  # not free: does not count
    unbound("m1")
    unbound("m2")

    assert sorted(missions_assign().bound) == ["m1", "m2"]


def test_a_stream_that_never_pauses_is_bound_once_its_oldest_waited_the_longest_hold(
    settings: Settings,
) -> None:
    settings.ASSIGNMENT_QUIET_SECONDS, settings.ASSIGNMENT_HOLD_SECONDS = 5.0, 10.0
    for index in range(3):
        robot(f"r{index}", x=float(index))
    unbound("m1")
    unbound("m2")
    created_ago("m1", 11.0)  # m2 just came, but m1 waited long enough

    assert sorted(missions_assign().bound) == ["m1", "m2"]


def test_a_run_without_reasons_reads_only_free_robots_and_leaves_the_reasons(
    settings: Settings,
) -> None:
    robot("plain")
    unbound("m1", robot_selector={"labels": ["lift"]})

    assert missions_assign(with_reasons=False).bound == {}
    assert Mission.objects.get(name="m1").waiting_reason == NOT_YET_ASSIGNED

    assert missions_assign(with_reasons=True).bound == {}
    assert Mission.objects.get(name="m1").waiting_reason == NO_LABELS.format(labels="lift")


def test_a_robot_fallen_free_claims_the_oldest_of_the_highest_priority_it_can_do() -> None:
    robot("r1", labels=("lift",))
    robot("r2", x=100.0)  # also free: a claim is for its robot alone
    unbound("old")
    unbound("urgent_lift", priority=5, robot_selector={"labels": ["lift"]})
    unbound("urgent_other", priority=5, robot_selector={"labels": ["crane"]})
    for name in ("old", "urgent_lift", "urgent_other"):
        created_ago(name, 1.0)

    assert claim("r1") == "urgent_lift"
    assert robot_of("urgent_lift") is None  # its step binds it, in the write that starts it


def test_a_claim_whose_choices_went_to_others_meanwhile_reads_the_pool_again(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    robot("r1")
    robot("r2", x=5.0)
    unbound("m1")
    unbound("m2")
    for name in ("m1", "m2"):
        created_ago(name, 1.0)
    monkeypatch.setattr(services, "CLAIM_PAGE", 1)
    read = services.claim_inputs

    def read_then_lose_it(**kwargs: Any) -> Any:
        """The page read, then its mission bound by another robot's claim before this one locks it."""
        inputs = read(**kwargs)
        if inputs.missions and inputs.missions[0].name == "m1":
            Mission.objects.filter(name="m1").update(robot="r2")
        return inputs

    monkeypatch.setattr(services, "claim_inputs", read_then_lose_it)

    assert claim("r1") == "m2"


def test_a_claim_leaves_missions_younger_than_the_quiet_time_to_the_run(settings: Settings) -> None:
    settings.ASSIGNMENT_QUIET_SECONDS = 5.0
    robot("r1")
    unbound("fresh")

    assert claim("r1") is None
    created_ago("fresh", 6.0)
    assert claim("r1") == "fresh"


def test_a_robot_that_may_not_work_claims_nothing() -> None:
    robot("manual", operating_mode="MANUAL")
    robot("low", battery_level=5.0)
    unbound("m1")
    created_ago("m1", 1.0)

    assert claim("manual") is None
    assert claim("low") is None
    assert claim("ghost") is None
    assert robot_of("m1") is None


def test_a_robot_in_a_mode_that_takes_no_orders_is_not_free() -> None:
    robot("manual", operating_mode="MANUAL")
    robot("service", x=5.0, operating_mode="SERVICE")
    robot("auto", x=50.0, operating_mode="AUTOMATIC")
    unbound("m1")

    assert missions_assign().bound == {"m1": "auto"}


def test_equally_near_robots_go_to_the_longest_idle() -> None:
    now = timezone.now()
    robot("recent", x=1.0, state_since=now - timedelta(seconds=5))
    robot("longest", x=-1.0, state_since=now - timedelta(minutes=5))
    robot("never_changed", y=1.0)  # no state change seen: counts as the most recently idle
    unbound("m1")

    assert missions_assign().bound == {"m1": "longest"}


@pytest.mark.parametrize("seen_before", [True, False], ids=["unbound_seen", "first_seen"])
def test_a_robot_that_ends_its_last_mission_starts_an_unbound_one_in_the_same_step(
    make_robot, seen_before: bool
) -> None:
    """Once its process has seen unbound missions (a step's look at the queue after its commit): the
    first step to see them leaves the mission to the run it asks for."""
    if seen_before:
        robot_step_module._unbound_seen.set()
    else:
        robot_step_module._unbound_seen.clear()
    created = make_robot(prefix="claim")
    Robot.objects.filter(name=created.name).update(
        online=True, battery_level=80.0, last_state_at=timezone.now()
    )
    put_state(created, header_id=1)
    route = {"route": {"waypoints": [{"x": 0, "y": 0, "map_id": "map"}]}}
    spec = {"robot": created.name, "mission_tree": [route]}
    mission_create(actor=TEST_ACTOR, name="own", prefix=None, spec=spec)
    [first] = orders(robot_step(name=created.name))
    unbound("next")

    put_state(created, header_id=2, state=finished(first))
    outcome = robot_step(name=created.name)

    assert [mission.name for mission in outcome.finished] == ["own"]
    mission = Mission.objects.get(name="next")
    if not seen_before:
        assert (orders(outcome), mission.robot) == ([], None)
        assert robot_step_module._unbound_seen.is_set()  # the next step that ends a mission claims
        return
    assert [order.order_id for order in orders(outcome)] == ["next-n0-r0"]
    assert (mission.robot, mission.state, mission.waiting_reason) == (
        created.name,
        MissionState.RUNNING,
        None,
    )
    [binding] = mission.assignment
    assert (binding["robot"], binding["released_at"]) == (created.name, None)
    # Bound and started in one write: the change feed has one image for both, none of it bound but queued.
    images = [change.image for change in Change.objects.filter(kind="mission", name="next").order_by("id")]
    assert [(image["robot"], image["state"]) for image in images] == [
        (None, MissionState.PENDING),
        (created.name, MissionState.RUNNING),
    ]


def test_robots_falling_free_together_claim_different_missions_the_best_ones() -> None:
    robots = [f"r{index}" for index in range(6)]
    for index, name in enumerate(robots):
        robot(name, x=float(index))
    for index in range(10):
        unbound(f"m{index}", priority=1 if index >= 7 else 0)
        created_ago(f"m{index}", 10.0 - index / 10)  # m0 the oldest
    barrier = threading.Barrier(len(robots))
    held = threading.Barrier(len(robots))  # no claim's transaction ends before every robot has claimed
    claimed: dict[str, str | None] = {}
    errors: list[BaseException] = []

    def claim_together(name: str) -> None:
        try:
            barrier.wait()
            claimed[name] = claim(name, hold=held)
        except BaseException as error:  # reported below
            errors.append(error)
        finally:
            connection.close()

    threads = [threading.Thread(target=claim_together, args=(name,)) for name in robots]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()

    assert not errors
    assert None not in claimed.values()  # none came away empty for another's lock
    assert sorted(claimed.values()) == ["m0", "m1", "m2", "m7", "m8", "m9"]  # priority 1 first, then oldest

"""The fault suite's checks on small hand-made recordings: each passes a good one, fails a bad one."""

from __future__ import annotations

import itertools
import random
from typing import Any

from simulator.config import spread_robots
from tests.faults import checks
from tests.faults.checks import (
    HttpAttempt,
    PostedMission,
    ProcessExit,
    ServiceEvent,
    StationSample,
    Window,
    WireMessage,
)
from tests.faults.load import ZONE, PlannedMission, plan_missions
from tests.faults.runner import KINDS, plan_faults
from vda5050.polygons import contains

PREFIX = "uagv/v2/RobotCompany"


def order(t: float, serial: str, order_id: str, header_id: int, update: int = 0, **extra: Any) -> WireMessage:
    data = {
        "headerId": header_id,
        "timestamp": f"2026-01-01T00:00:{t:06.3f}Z",
        "version": "2.0.0",
        "manufacturer": "RobotCompany",
        "serialNumber": serial,
        "orderId": order_id,
        "orderUpdateId": update,
        "nodes": [{"nodeId": f"{order_id}-s0", "sequenceId": 0, "released": True, "actions": []}],
        "edges": [],
        **extra,
    }
    return WireMessage(t, f"{PREFIX}/{serial}/order", data)


def instant(t: float, serial: str, header_id: int, action_id: str) -> WireMessage:
    data = {
        "headerId": header_id,
        "timestamp": f"2026-01-01T00:00:{t:06.3f}Z",
        "actions": [{"actionType": "factsheetRequest", "actionId": action_id, "blockingType": "NONE"}],
    }
    return WireMessage(t, f"{PREFIX}/{serial}/instantActions", data)


def state(t: float, serial: str, order_id: str = "", *, busy: bool = False, action: str | None = None):
    data = {
        "headerId": int(t * 10),
        "orderId": order_id,
        "nodeStates": [{"nodeId": f"{order_id}-s2", "sequenceId": 2}] if busy else [],
        "edgeStates": [],
        "actionStates": [{"actionId": "a", "actionStatus": action}] if action else [],
    }
    return WireMessage(t, f"{PREFIX}/{serial}/state", data)


def mission_object(state_: str, nodes: dict[str, str], start: float = 0.0, end: float = 100.0) -> dict:
    def stamp(t: float) -> str:
        return f"1970-01-01T00:{int(t // 60):02d}:{t % 60:06.3f}Z"

    return {
        "status": {
            "state": state_,
            "node_status": {name: {"state": s, "error_msg": None} for name, s in nodes.items()},
            "start_timestamp": stamp(start),
            "end_timestamp": stamp(end),
            "failure_reason": None,
            "failure_category": None,
            "waiting_reason": None,
            "current_node": 1,
        }
    }


M1 = PostedMission("m1", "r1", ((0, "a"), (1, "b")), ("a", "b"))
DONE = {"root": "COMPLETED", "a": "COMPLETED", "b": "COMPLETED"}


# --- helpers ------------------------------------------------------------------------------------------


def test_parse_order_id_and_busy():
    assert checks.parse_order_id("fm0001-x-n2-r0") == ("fm0001-x", 2, 0)
    assert checks.parse_order_id("something") is None
    assert not checks.busy({"nodeStates": [], "actionStates": [{"actionStatus": "FINISHED"}]})
    assert checks.busy({"nodeStates": [{"nodeId": "x"}]})
    assert checks.busy({"actionStates": [{"actionStatus": "RUNNING"}]})


def test_wire_message_from_a_payload_that_is_not_json():
    assert WireMessage.from_payload(1.0, f"{PREFIX}/r1/state", b"\xff").data is None
    message = WireMessage.from_payload(1.0, f"{PREFIX}/r1/state", b'{"headerId": 3}')
    assert (message.serial, message.kind, message.data) == ("r1", "state", {"headerId": 3})


# --- 1. missions --------------------------------------------------------------------------------------


def test_missions_all_completed_pass():
    assert checks.check_missions([M1], {"m1": mission_object("COMPLETED", DONE)}, waited=10).ok


def test_missions_lost_failed_or_stuck_fail():
    m2, m3 = PostedMission("m2", "r1", ()), PostedMission("m3", "r2", ())
    result = checks.check_missions(
        [M1, m2, m3],
        {"m1": None, "m2": mission_object("FAILED", {}), "m3": mission_object("RUNNING", {})},
        waited=120,
        robots={"r2": {"status": {"state": "ON_TASK", "online": False}}},
        unposted=["m4"],
    )
    text = "\n".join(result.problems)
    assert len(result.problems) == 4, text
    assert "m1 (robot r1) was posted but is gone" in text
    assert "m2 (robot r1) ended FAILED" in text
    assert "m3 (robot r2) still RUNNING 120 s" in text and "online False" in text
    assert "m4 could not be posted" in text


def test_a_mission_failed_by_a_robot_restart_during_an_action_passes_only_then():
    failed = mission_object("FAILED", {}, start=10, end=20)
    failed["status"]["failure_reason"] = (
        "Robot no longer holds order m1-n0-r0 (it may have restarted); the action may or may not have run"
    )
    other = mission_object("FAILED", {}, start=10, end=20)
    other["status"]["failure_reason"] = "Action failure"

    def check(mission: dict, *restarts: Window) -> checks.CheckResult:
        return checks.check_missions([M1], {"m1": mission}, waited=10, restarts=restarts)

    restart = Window(15, 17, "simulator")
    assert check(failed, restart).ok
    assert "1 FAILED as their robot restarted during an action" in check(failed, restart).notes
    assert not check(failed).ok  # no restart
    assert not check(failed, Window(30, 31, "simulator")).ok  # a restart after it ended
    assert not check(other, restart).ok  # another failure


# --- 2. order copies ----------------------------------------------------------------------------------


def test_order_resent_identically_passes():
    messages = [order(1, "r1", "m1-n0-r0", 0), order(2, "r1", "m1-n0-r0", 1), order(3, "r1", "m1-n0-r0", 2)]
    result = checks.check_order_copies(messages)
    assert result.ok, result.problems
    assert "2 re-sent copies" in result.notes[0]


def test_order_resent_with_other_content_fails():
    messages = [order(1, "r1", "m1-n0-r0", 0), order(2, "r1", "m1-n0-r0", 1, nodes=[])]
    result = checks.check_order_copies(messages)
    assert len(result.problems) == 1
    assert "robot r1: order m1-n0-r0 update 0 re-sent with different ['nodes']" in result.problems[0]


def test_order_updates_are_not_copies():
    messages = [order(1, "r1", "m1-n0-r0", 0), order(2, "r1", "m1-n0-r0", 1, update=1, nodes=[])]
    assert checks.check_order_copies(messages).ok


# --- 3. no new order to a busy robot ------------------------------------------------------------------


def test_new_order_after_an_idle_state_passes():
    messages = [
        state(1, "r1", "m1-n0-r0", busy=True),
        order(1.5, "r1", "m1-n0-r0", 1),  # a resend while busy with it: not a new order
        state(2, "r1", "m1-n0-r0", action="FINISHED"),
        order(3, "r1", "m1-n1-r0", 2),
    ]
    result = checks.check_no_order_while_busy(messages, [])
    assert result.ok, result.problems


def test_new_order_to_a_busy_robot_fails():
    messages = [
        state(1, "r1", "m1-n0-r0"),
        order(1.5, "r1", "m1-n0-r0", 0),
        state(2, "r1", "m1-n0-r0", action="RUNNING"),
        order(3, "r1", "m1-n1-r0", 1),
    ]
    result = checks.check_no_order_while_busy(messages, [])
    assert len(result.problems) == 1
    assert "robot r1: new order m1-n1-r0" in result.problems[0]
    assert "busy with order m1-n0-r0" in result.problems[0]


def test_busy_state_from_before_the_observer_looked_away_is_not_evidence():
    messages = [state(1, "r1", "m1-n0-r0", busy=True), order(5, "r1", "m1-n1-r0", 1)]
    result = checks.check_no_order_while_busy(messages, [Window(2, 3)])
    assert result.ok and "1 without a known latest state" in result.notes[0]


# --- 4. leaves in order, never twice ------------------------------------------------------------------


def test_leaves_in_order_pass():
    messages = [
        order(1, "r1", "m1-n0-r0", 0),
        order(2, "r1", "m1-n0-r0", 1),
        order(3, "r1", "m1-n1-r0", 2),
    ]
    final = {"m1": mission_object("COMPLETED", DONE)}
    result = checks.check_leaves([M1], final, messages, [])
    assert result.ok, result.problems


def test_leaf_after_a_later_one_or_twice_fails():
    messages = [
        order(1, "r1", "m1-n0-r0", 0),
        order(2, "r1", "m1-n1-r0", 1),
        order(3, "r1", "m1-n0-r1", 2),
    ]
    final = {"m1": mission_object("COMPLETED", DONE)}
    result = checks.check_leaves([M1], final, messages, [])
    text = "\n".join(result.problems)
    assert "order m1-n0-r1 for leaf a came after an order for the later leaf n1" in text
    assert "leaf a reached 2 times, orders ['m1-n0-r0', 'm1-n0-r1']" in text


def test_a_leaf_resumed_after_its_robot_restarted_is_not_reached_twice():
    messages = [
        order(1, "r1", "m1-n0-r0", 0),
        order(5, "r1", "m1-n0-r1", 1),  # the rest of the route, from where the restarted robot stood
        order(8, "r1", "m1-n1-r0", 2),
    ]
    final = {"m1": mission_object("COMPLETED", DONE)}

    result = checks.check_leaves([M1], final, messages, [], restarts=[Window(3, 4, "simulator")])
    assert result.ok, result.problems
    assert "1 leaves resumed after their robot restarted" in result.notes
    assert not checks.check_leaves([M1], final, messages, [], restarts=[Window(6, 7, "simulator")]).ok


def test_a_leaf_ordered_while_its_robot_was_down_then_again_is_resumed_not_reached_twice():
    """The first order went out while the simulator was being restarted: the fresh robot never had it."""
    messages = [order(2, "r1", "m1-n0-r0", 0), order(5, "r1", "m1-n0-r1", 1), order(8, "r1", "m1-n1-r0", 2)]
    final = {"m1": mission_object("COMPLETED", DONE)}

    assert checks.check_leaves([M1], final, messages, [], restarts=[Window(1, 3, "simulator")]).ok
    assert not checks.check_leaves([M1], final, messages, [], restarts=[Window(0.5, 1.5, "simulator")]).ok


def test_a_leaf_resumed_after_its_robot_restarted_may_follow_the_next_leaf_sent_ahead():
    messages = [
        order(1, "r1", "m1-n0-r0", 0),
        ahead(2, "r1", "m1-n0-r0", 1, "m1-n1-r0"),
        taken(2.5, "r1", "m1-n0-r0", 1),
        order(5, "r1", "m1-n0-r1", 2),  # restarted before the end of the first route: its rest
        order(8, "r1", "m1-n1-r1", 3),  # the next route, its own order
    ]
    final = {"m1": mission_object("COMPLETED", DONE)}

    assert checks.check_leaves([M1], final, messages, [], restarts=[Window(3, 4, "simulator")]).ok
    text = "\n".join(checks.check_leaves([M1], final, messages, []).problems)
    assert "order m1-n0-r1 for leaf a came after an order for the later leaf n1" in text


def ahead(t: float, serial: str, order_id: str, header_id: int, leaf: str, update: int = 1) -> WireMessage:
    """An order update carrying the leaf `leaf` (`<mission>-n<index>-r<attempt>`) sent ahead."""
    nodes = [
        {"nodeId": f"{order_id}-s2", "sequenceId": 2, "released": True, "actions": []},
        {"nodeId": f"{leaf}-s4", "sequenceId": 4, "released": True, "actions": []},
    ]
    return order(t, serial, order_id, header_id, update, nodes=nodes)


def taken(t: float, serial: str, order_id: str, update: int) -> WireMessage:
    message = state(t, serial, order_id, busy=True)
    return WireMessage(message.t, message.topic, {**message.data, "orderUpdateId": update})


def test_a_leaf_sent_ahead_and_taken_counts_as_reached():
    messages = [order(1, "r1", "m1-n0-r0", 0), ahead(1.1, "r1", "m1-n0-r0", 1, "m1-n1-r0")]
    final = {"m1": mission_object("COMPLETED", DONE)}

    assert "no order was seen for leaves ['b']" in "\n".join(
        checks.check_leaves([M1], final, messages, []).problems
    )
    result = checks.check_leaves([M1], final, [*messages, taken(2, "r1", "m1-n0-r0", 1)], [])
    assert result.ok, result.problems


def test_a_leaf_sent_ahead_never_taken_then_ordered_on_its_own_is_reached_once():
    messages = [
        order(1, "r1", "m1-n0-r0", 0),
        ahead(1.1, "r1", "m1-n0-r0", 1, "m1-n1-r0"),
        taken(2, "r1", "m1-n0-r0", 0),
        order(3, "r1", "m1-n0-r0", 2),  # the robot lacked the first order: sent again
        order(4, "r1", "m1-n1-r1", 3),
    ]
    final = {"m1": mission_object("COMPLETED", DONE)}
    result = checks.check_leaves([M1], final, messages, [])
    assert result.ok, result.problems


def test_an_order_and_its_update_re_sent_after_the_robot_took_both_go_back_to_no_leaf():
    messages = [
        order(1, "r1", "m1-n0-r0", 0),
        ahead(1.1, "r1", "m1-n0-r0", 1, "m1-n1-r0"),
        order(5, "r1", "m1-n0-r0", 2),  # re-sent, the first sending still on its way
        ahead(5.1, "r1", "m1-n0-r0", 3, "m1-n1-r0"),
        taken(6, "r1", "m1-n0-r0", 1),
    ]
    final = {"m1": mission_object("COMPLETED", DONE)}
    result = checks.check_leaves([M1], final, messages, [])
    assert result.ok, result.problems


def test_a_leaf_sent_ahead_and_taken_then_ordered_again_is_reached_twice():
    messages = [
        order(1, "r1", "m1-n0-r0", 0),
        ahead(1.1, "r1", "m1-n0-r0", 1, "m1-n1-r0"),
        taken(2, "r1", "m1-n0-r0", 1),
        order(4, "r1", "m1-n1-r1", 2),
    ]
    final = {"m1": mission_object("COMPLETED", DONE)}
    text = "\n".join(checks.check_leaves([M1], final, messages, []).problems)
    assert "leaf b reached 2 times, orders ['m1-n1-r0', 'm1-n1-r1']" in text


def test_completed_mission_with_a_leaf_not_completed_or_never_ordered_fails():
    final = {"m1": mission_object("COMPLETED", {**DONE, "b": "PENDING"})}
    result = checks.check_leaves([M1], final, [order(1, "r1", "m1-n0-r0", 0)], [])
    text = "\n".join(result.problems)
    assert "m1 (robot r1) COMPLETED with nodes ['b=PENDING']" in text
    assert "no order was seen for leaves ['b']" in text


def test_leaf_never_ordered_while_the_observer_looked_away_is_excused():
    final = {"m1": mission_object("COMPLETED", DONE, start=0, end=100)}
    result = checks.check_leaves([M1], final, [order(1, "r1", "m1-n0-r0", 0)], [Window(50, 52)])
    assert result.ok, result.problems


def test_order_of_an_unknown_mission_or_non_leaf_fails():
    messages = [order(1, "r1", "other-n0-r0", 0), order(2, "r1", "m1-n5-r0", 1)]
    result = checks.check_leaves([M1], {"m1": None}, messages, [])
    text = "\n".join(result.problems)
    assert "order other-n0-r0 of no posted mission" in text
    assert "order m1-n5-r0 for node 5, which is not a leaf" in text


# --- 5. headerIds -------------------------------------------------------------------------------------


def test_header_ids_consecutive_pass():
    messages = [
        order(1, "r1", "m1-n0-r0", 0),
        instant(1.5, "r1", 0, "f1"),
        order(3, "r1", "m1-n0-r0", 2),  # arrived before 1: two processes published them
        order(2, "r1", "m1-n0-r0", 1),
        order(2.5, "r1", "m1-n0-r0", 1),  # the same message twice (timestamp may differ)
        order(1, "r2", "m2-n0-r0", 0),
    ]
    result = checks.check_header_ids(messages, [], since=0)
    assert result.ok, result.problems


def test_header_id_gap_fails():
    messages = [order(1, "r1", "m1-n0-r0", 0), order(2, "r1", "m1-n0-r0", 3)]
    events = [ServiceEvent(1.5, "bridge", "down")]
    result = checks.check_header_ids(messages, [], since=0, events=events)
    assert len(result.problems) == 1
    assert "robot r1 order: headerIds 1..2 never seen between 0" in result.problems[0]
    assert "faults in between: bridge down" in result.problems[0]


def test_header_ids_not_starting_at_zero_fail():
    result = checks.check_header_ids([instant(1, "r1", 1, "f1")], [], since=0)
    assert "robot r1 instantActions: headerIds 0 never seen" in result.problems[0]


def test_header_id_gap_across_a_broker_outage_is_excused():
    messages = [order(1, "r1", "m1-n0-r0", 0), order(9, "r1", "m1-n0-r0", 3)]
    result = checks.check_header_ids(messages, [Window(4, 5, "broker")], since=0)
    assert result.ok and "1 gaps excused" in result.notes[0]


def test_header_id_gap_before_a_broker_outage_is_not_excused():
    messages = [order(1, "r1", "m1-n0-r0", 0), order(2, "r1", "m1-n0-r0", 2), order(9, "r1", "m1-n0-r0", 3)]
    result = checks.check_header_ids(messages, [Window(4, 5, "broker")], since=0)
    assert len(result.problems) == 1 and "headerIds 1 never seen" in result.problems[0]


def test_header_id_reused_for_another_message_fails():
    messages = [order(1, "r1", "m1-n0-r0", 0), order(2, "r1", "m1-n1-r0", 0)]
    result = checks.check_header_ids(messages, [], since=0)
    assert len(result.problems) == 1
    assert "robot r1 order: headerId 0 carried two different messages" in result.problems[0]


# --- 6. HTTP ------------------------------------------------------------------------------------------


def attempt(start: float, status: int | None, method: str = "POST", **extra: Any) -> HttpAttempt:
    error = None if status is not None else "connection: refused"
    return HttpAttempt(start, start + 0.1, method, "/mission", status, error, **extra)


def test_errors_during_faults_are_excused():
    events = [
        ServiceEvent(10, "postgres", "down"),
        ServiceEvent(12, "postgres", "up"),
        ServiceEvent(20, "api", "down"),
        ServiceEvent(21, "api", "up"),
    ]
    attempts = [
        attempt(1, 200),
        attempt(11, 500),
        attempt(13.5, 503),  # within the grace after PostgreSQL came back
        attempt(20.5, None),
        attempt(21.5, 500),
        attempt(22, 400, exists_after_retry=True),
        attempt(30, 404, method="GET"),
    ]
    result = checks.check_http(attempts, events, grace=2)
    assert result.ok, result.problems


def test_5xx_while_everything_is_up_fails():
    events = [ServiceEvent(10, "redis", "down"), ServiceEvent(11, "redis", "up")]
    attempts = [
        attempt(14, 500),
        attempt(15, None),
        attempt(16, 400, body="Object mission ... already exists"),
    ]
    result = checks.check_http(attempts, events, grace=2)
    assert len(result.problems) == 3, result.problems
    assert "POST /mission" in result.problems[0] and "answered 500" in result.problems[0]
    assert "failed: connection: refused" in result.problems[1]
    assert "answered 400" in result.problems[2]


def test_a_service_never_back_excuses_everything_after():
    windows = checks.impaired_windows([ServiceEvent(5, "redis", "down")], grace=2)
    assert windows == [Window(5, float("inf"), "redis")]
    assert checks.check_http([attempt(100, 500)], [ServiceEvent(5, "redis", "down")], grace=2).ok


def test_broker_outage_does_not_excuse_a_5xx():
    events = [ServiceEvent(10, "broker", "down"), ServiceEvent(12, "broker", "up")]
    assert not checks.check_http([attempt(11, 500)], events, grace=2).ok


# --- 7. processes -------------------------------------------------------------------------------------


def test_processes_all_running_pass():
    assert checks.check_processes([], {"bridge": True, "api": True}).ok


def test_process_exit_or_not_running_fails():
    result = checks.check_processes([ProcessExit("beat", 5.0, 1, "Traceback ...")], {"api": False})
    assert len(result.problems) == 2
    assert "beat exited by itself" in result.problems[0] and "Traceback" in result.problems[0]
    assert "api is not running" in result.problems[1]


# --- the plans ----------------------------------------------------------------------------------------


def test_fault_plan_is_a_function_of_the_seed():
    plan = plan_faults(7, 180)
    assert plan == plan_faults(7, 180) and plan != plan_faults(8, 180)
    assert 5 <= plan[0].at <= 15
    assert all(5 <= b.at - a.at <= 15 for a, b in itertools.pairwise(plan))
    assert all(f.kind in KINDS and 0 <= f.downtime <= 5 and f.at < 180 for f in plan)
    assert 180 / 15 - 1 <= len(plan) <= 180 / 5


def test_missions_plan_leaves_that_never_fail():
    robots = spread_robots(4, "r")
    planned = plan_missions(random.Random(1), robots, 40)
    assert len({m.name for m in planned}) == 40
    assert {m.robot for m in planned} == {r.name for r in robots}
    for mission in planned:
        routes = [n for n in mission.tree if "route" in n]
        actions = [n for n in mission.tree if "action" in n]
        assert 1 <= len(routes) <= 3 and len(actions) <= 2
        assert all(n["action"]["action_parameters"]["should_fail"] == 0 for n in actions)
        assert [i for i, _ in mission.posted().leaves] == list(range(len(mission.tree)))


def binding(robot: str, released: bool = False) -> dict[str, Any]:
    return {
        "robot": robot,
        "bound_at": "2026-01-01T00:00:01.000000Z",
        "released_at": "2026-01-01T00:00:02.000000Z" if released else None,
        "reason": "Robot is offline" if released else None,
    }


def test_bindings_pass_for_a_mission_bound_given_back_and_bound_again():
    posted = [checks.PostedMission("m1", checks.UNBOUND, ((0, "r"),)), checks.PostedMission("m2", "b", ())]
    final = {
        "m1": {"robot": "b", "status": {"assignment": [binding("a", released=True), binding("b")]}},
        "m2": {"robot": "b", "status": {"assignment": []}},
    }
    messages = [order(1.0, "b", "m1-n0-r0", 0)]

    assert checks.check_bindings(posted, final, messages).ok


def test_bindings_fail_for_two_at_once_a_stranger_robot_or_a_named_mission_bound():
    posted = [checks.PostedMission("m1", checks.UNBOUND, ((0, "r"),)), checks.PostedMission("m2", "b", ())]
    final = {
        "m1": {"robot": "b", "status": {"assignment": [binding("a"), binding("b")]}},
        "m2": {"robot": "b", "status": {"assignment": [binding("b")]}},
    }
    messages = [order(1.0, "c", "m1-n0-r0", 0)]

    problems = checks.check_bindings(posted, final, messages).problems

    assert len(problems) == 3
    assert any("2 robots at once" in p for p in problems)
    assert any("never bound: {'c'}" in p for p in problems)
    assert any("m2 of b was bound" in p for p in problems)


def test_a_share_of_the_planned_missions_is_unbound():
    robots = spread_robots(4, "r")
    planned = plan_missions(random.Random(1), robots, 200, unbound_share=0.25)

    unbound = [m for m in planned if m.robot is None]
    assert 20 < len(unbound) < 80
    assert all(m.body()["robot"] is None and m.posted().robot == checks.UNBOUND for m in unbound)
    assert [m.robot for m in plan_missions(random.Random(1), robots, 20)] == [
        m.robot for m in plan_missions(random.Random(1), robots, 20, unbound_share=0.0)
    ]


def station(
    name: str, *holders: str, t: float = 1.0, capacity: int = 1, kind: str = "CHARGER"
) -> StationSample:
    return StationSample(t, name, kind, capacity, holders)


def test_stations_within_capacity_and_each_robot_at_one_pass():
    samples = [station("c1", "r1", t=1), station("c2", t=1), station("c1", t=2), station("c2", "r1", t=2)]

    assert checks.check_station_capacity(samples).ok


def test_a_station_over_capacity_or_a_robot_at_two_fails():
    over = checks.check_station_capacity([station("c1", "r1", "r2", capacity=1)])
    twice = checks.check_station_capacity([station("c1", "r1"), station("p1", "r1", kind="PARKING")])

    assert len(over.problems) == 1 and "c1 held 2 robots (r1, r2) of its capacity 1" in over.problems[0]
    assert len(twice.problems) == 1 and "['r1'] held two stations" in twice.problems[0]


def low_robot(level: float, *, online: bool = True, minimum: float | None = 30.0) -> dict[str, Any]:
    return {
        "battery": {"critical_level": 10.0, "recommended_minimum": minimum},
        "status": {"online": online, "battery_level": level, "charging_waiting_reason": "no free charger"},
    }


def test_low_robots_holding_chargers_or_with_none_free_pass():
    robots = {
        "r1": low_robot(20),
        "r2": low_robot(25),
        "ok": low_robot(80),
        "away": low_robot(5, online=False),
    }

    assert checks.check_low_robots_charge(robots, [station("c1", "r1")]).ok  # r2 waits: c1 is full
    assert checks.check_low_robots_charge({"r1": low_robot(20)}, [station("c1", "r1", capacity=2)]).ok


def test_a_low_robot_without_a_charger_while_one_is_free_fails():
    robots = {
        "r1": low_robot(20),
        "critical": low_robot(9, minimum=None),
        "above": low_robot(11, minimum=None),
    }

    result = checks.check_low_robots_charge(robots, [station("c1"), station("p1", kind="PARKING")])

    assert [problem.split(" at ")[0] for problem in result.problems] == ["robot critical", "robot r1"]
    assert "['c1'] have room" in result.problems[0]


ZONES = {"crossing": ZONE}


def at(t: float, serial: str, x: float, y: float) -> WireMessage:
    """A state putting the robot at (x, y)."""
    return WireMessage(
        t, f"{PREFIX}/{serial}/state", {"headerId": int(t * 10), "agvPosition": {"x": x, "y": y}}
    )


def test_robots_taking_turns_through_a_zone_pass():
    messages = [at(1, "a", 1, 1), at(2, "b", 0, 1), at(3, "a", 2, 1), at(4, "b", 1, 1), at(5, "b", 1, 3)]

    assert checks.check_zone_capacity(messages, ZONES, []).ok


def test_two_robots_inside_a_zone_at_once_fail_once_per_pair():
    messages = [at(1, "a", 1, 1), at(2, "b", 1.4, 1.4), at(3, "b", 1.2, 1), at(4, "a", 3, 3)]

    problems = checks.check_zone_capacity(messages, ZONES, []).problems

    assert len(problems) == 1 and "robots a, b inside zone crossing together" in problems[0]


def test_a_3_0_robots_position_counts_as_a_2_x_robots():
    position = {"mobileRobotPosition": {"x": 1.4, "y": 1.4}}
    in_3_0 = WireMessage(2, f"{PREFIX}/b/state", {"headerId": 20, **position})

    problems = checks.check_zone_capacity([at(1, "a", 1, 1), in_3_0], ZONES, []).problems

    assert len(problems) == 1 and "robots a, b inside zone crossing together" in problems[0]


def test_a_stay_in_a_zone_over_a_simulator_restart_is_left_out():
    """Restarted, robot a was offline and held nothing: b may have been let in before a reported again."""
    messages = [at(1, "a", 1, 1), at(5, "a", 1, 1), at(6, "b", 1, 1), at(7, "b", 3, 3)]

    assert checks.check_zone_capacity(messages, ZONES, [Window(2, 4, "simulator")]).ok
    assert not checks.check_zone_capacity(messages, ZONES, [Window(8, 9, "simulator")]).ok


def waypoints(planned: list[PlannedMission]) -> list[tuple[float, float]]:
    return [
        (w["x"], w["y"]) for m in planned for n in m.tree if "route" in n for w in n["route"]["waypoints"]
    ]


def test_planned_waypoints_avoid_the_zone():
    robots = spread_robots(4, "r")

    avoiding = waypoints(plan_missions(random.Random(1), robots, 200, avoid=ZONE))

    assert not any(contains(ZONE, point) for point in avoiding)
    assert any(contains(ZONE, point) for point in waypoints(plan_missions(random.Random(1), robots, 200)))

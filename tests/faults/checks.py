"""The fault suite's checks: pure functions over what a run recorded, no I/O.

A run records the MQTT traffic an observer saw (`WireMessage`, in arrival order), the windows in which that
traffic may be incomplete (`Window`: broker outages, the observer reconnecting), every HTTP request the load
made (`HttpAttempt`), when the fault injector took a service down and when it was back (`ServiceEvent`),
processes that exited without being killed (`ProcessExit`), the missions it posted (`PostedMission`) and
the API's final mission objects. Each check returns a `CheckResult` whose problems name the robot or mission
concerned; `tests/faults/test_checks.py` runs each on small hand-made recordings.
"""

from __future__ import annotations

import re
import time
from collections import defaultdict
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from datetime import datetime
from typing import Any

import orjson

from vda5050.polygons import Polygon, contains

TERMINAL = frozenset({"COMPLETED", "FAILED", "CANCELED"})
FINAL_ACTION_STATUSES = frozenset({"FINISHED", "FAILED"})
ORDER_ID = re.compile(r"(?P<mission>.+)-n(?P<node>\d+)-r(?P<attempt>\d+)")
# Topics the server publishes on, whose headerIds it numbers (per robot and topic).
SERVER_TOPICS = ("order", "instantActions")
# Why a leaf fails when its robot restarts during an action (dispatch.faults.lost_reason): the one failure
# a robot restart (the fault kind "simulator") legitimately causes in the load.
LOST_ORDER = "no longer holds order"


# --- recorded data -----------------------------------------------------------------------------------


@dataclass(frozen=True)
class WireMessage:
    """One MQTT message as the observer received it: arrival time (epoch s), topic and parsed payload."""

    t: float
    topic: str
    data: dict[str, Any] | None  # None if the payload was not a JSON object

    @property
    def serial(self) -> str:
        """The robot: the topic's serial-number level (`interface/version/manufacturer/serial/topic`)."""
        levels = self.topic.split("/")
        return levels[3] if len(levels) == 5 else self.topic

    @property
    def kind(self) -> str:
        return self.topic.rsplit("/", 1)[-1]

    @classmethod
    def from_payload(cls, t: float, topic: str, payload: bytes) -> WireMessage:
        try:
            data = orjson.loads(payload)
        except orjson.JSONDecodeError:
            data = None
        return cls(t, topic, data if isinstance(data, dict) else None)


@dataclass(frozen=True)
class Window:
    """A time interval (epoch s) in which recorded traffic may be incomplete or a service was impaired."""

    start: float
    end: float
    label: str = ""

    def overlaps(self, lo: float, hi: float) -> bool:
        return self.start <= hi and lo <= self.end


@dataclass(frozen=True)
class HttpAttempt:
    """One HTTP request of the load: `status` None when there was no answer (`error` says why)."""

    start: float
    end: float
    method: str
    path: str
    status: int | None
    error: str | None = None
    body: str = ""
    # A POST answered "already exists" after an earlier attempt with the same name got no clean answer:
    # that attempt created the object, which is what the retry wanted.
    exists_after_retry: bool = False


@dataclass(frozen=True)
class ServiceEvent:
    """The fault injector took `component` down (`kind` "down") or saw it serving again ("up")."""

    t: float
    component: str
    kind: str


@dataclass(frozen=True)
class ProcessExit:
    """A process of the stack that ended without the fault injector killing it."""

    name: str
    t: float
    returncode: int | None
    tail: str = ""


# A PostedMission's robot when the load posted it without one (assignment binds it).
UNBOUND = "(unbound)"


@dataclass(frozen=True)
class PostedMission:
    """A mission the load posted: its robot and its leaves as (index in mission_tree, name)."""

    name: str
    robot: str
    leaves: tuple[tuple[int, str], ...]
    nodes: tuple[str, ...] = ()  # every node name of the tree (leaves and composites)


@dataclass
class CheckResult:
    name: str
    problems: list[str] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)  # what the check looked at, or had to leave out

    @property
    def ok(self) -> bool:
        return not self.problems


# --- helpers ------------------------------------------------------------------------------------------


def excused(windows: Iterable[Window], lo: float, hi: float) -> Window | None:
    """The first window overlapping [lo, hi], if any."""
    lo, hi = min(lo, hi), max(lo, hi)
    return next((w for w in windows if w.overlaps(lo, hi)), None)


def parse_order_id(order_id: str) -> tuple[str, int, int] | None:
    """Mission, node index and attempt of one of the engine's orderIds (`<mission>-n<index>-r<attempt>`)."""
    match = ORDER_ID.fullmatch(order_id)
    if match is None:
        return None
    return match["mission"], int(match["node"]), int(match["attempt"])


def carried_leaf(order: Mapping[str, Any]) -> str:
    """The leaf an order message carries, as `<mission>-n<index>-r<attempt>`: a new order's orderId, or,
    for an order update (a route the engine sent ahead), the key its new nodes are named after."""
    order_id = str(order.get("orderId"))
    nodes = order.get("nodes") or ()
    if not int(order.get("orderUpdateId") or 0) or len(nodes) < 2:
        return order_id
    return str(nodes[-1].get("nodeId")).rpartition("-s")[0] or order_id


def updates_taken(messages: Sequence[WireMessage]) -> dict[tuple[str, str], int]:
    """(robot, orderId) -> the highest orderUpdateId the robot's states showed for that order."""
    taken: dict[tuple[str, str], int] = {}
    for message in messages:
        if message.kind == "state" and message.data is not None:
            key = (message.serial, str(message.data.get("orderId")))
            taken[key] = max(taken.get(key, 0), int(message.data.get("orderUpdateId") or 0))
    return taken


def busy(state: Mapping[str, Any]) -> bool:
    """A VDA 5050 state shows the robot busy: nodes or edges left, or an action not FINISHED/FAILED."""
    return bool(
        state.get("nodeStates")
        or state.get("edgeStates")
        or any(a.get("actionStatus") not in FINAL_ACTION_STATUSES for a in state.get("actionStates") or ())
    )


def _without(data: Mapping[str, Any], *keys: str) -> bytes:
    return orjson.dumps({k: v for k, v in data.items() if k not in keys}, option=orjson.OPT_SORT_KEYS)


def _epoch(timestamp: str | None) -> float | None:
    if not timestamp:
        return None
    return datetime.fromisoformat(timestamp.replace("Z", "+00:00")).timestamp()


def _at(t: float, origin: float | None) -> str:
    """A time as an offset from `origin` (the fault phase's start) and as the wall clock of the logs."""
    clock = time.strftime("%H:%M:%S", time.localtime(t)) + f".{int(t % 1 * 1000):03d}"
    return f"t={t - origin:+.1f}s {clock}" if origin is not None else clock


def _events_between(events: Sequence[ServiceEvent], lo: float, hi: float, origin: float | None) -> str:
    inside = [f"{e.component} {e.kind} {_at(e.t, origin)}" for e in events if lo <= e.t <= hi]
    return f"; faults in between: {', '.join(inside)}" if inside else ""


# --- 1. no mission lost -------------------------------------------------------------------------------


def check_missions(
    posted: Sequence[PostedMission],
    final: Mapping[str, Mapping[str, Any] | None],
    *,
    waited: float,
    robots: Mapping[str, Mapping[str, Any]] | None = None,
    unposted: Sequence[str] = (),
    restarts: Sequence[Window] = (),
) -> CheckResult:
    """Every posted mission exists and COMPLETED (nothing in the load may fail) within `waited` seconds
    after the faults stopped. `final` maps a mission name to the API's object (None: 404). `robots`, the
    API's robot objects by name, only add the robot's status to a problem. `unposted`: missions the load
    gave up posting (the API never took them). `restarts`: when the robots restarted; a mission that
    FAILED because its robot no longer held the order of a running action (`LOST_ORDER`) while one
    happened is what the README promises, not a problem."""
    result = CheckResult("no mission lost")
    lost_in_restart = 0
    for name in unposted:
        result.problems.append(f"mission {name} could not be posted: the API never accepted it")
    states: dict[str, int] = defaultdict(int)
    for mission in posted:
        obj = final.get(mission.name)
        if obj is None:
            result.problems.append(f"mission {mission.name} (robot {mission.robot}) was posted but is gone")
            continue
        status = obj.get("status") or {}
        state = status.get("state")
        states[str(state)] += 1
        if state == "COMPLETED":
            continue
        if state == "FAILED" and _failed_in_restart(status, restarts):
            lost_in_restart += 1
            continue
        robot = (robots or {}).get(mission.robot)
        robot_status = ""
        if robot is not None:
            rs = robot.get("status") or {}
            robot_status = f"; robot {mission.robot} state {rs.get('state')} online {rs.get('online')}"
        if state in TERMINAL:
            result.problems.append(
                f"mission {mission.name} (robot {mission.robot}) ended {state}: "
                f"{status.get('failure_category')} {status.get('failure_reason')!r}{robot_status}"
            )
        else:
            result.problems.append(
                f"mission {mission.name} (robot {mission.robot}) still {state} {waited:.0f} s after the "
                f"faults stopped (current_node {status.get('current_node')}, waiting_reason "
                f"{status.get('waiting_reason')!r}){robot_status}"
            )
    result.notes.append(f"{len(posted)} missions posted; final states {dict(sorted(states.items()))}")
    if lost_in_restart:
        result.notes.append(f"{lost_in_restart} FAILED as their robot restarted during an action")
    return result


def _failed_in_restart(status: Mapping[str, Any], restarts: Sequence[Window]) -> bool:
    start, end = _epoch(status.get("start_timestamp")), _epoch(status.get("end_timestamp"))
    return (
        LOST_ORDER in (status.get("failure_reason") or "")
        and start is not None
        and excused(restarts, start, end if end is not None else time.time()) is not None
    )


# --- 2. no order re-sent with different content -------------------------------------------------------


def check_order_copies(messages: Sequence[WireMessage], origin: float | None = None) -> CheckResult:
    """Every copy of an order (orderId, orderUpdateId) on the wire has the same content but for
    `headerId` and `timestamp`."""
    result = CheckResult("order re-sends identical")
    first: dict[tuple[str, int], WireMessage] = {}
    copies = 0
    for message in messages:
        if message.kind != "order" or message.data is None:
            continue
        key = (str(message.data.get("orderId")), int(message.data.get("orderUpdateId") or 0))
        seen = first.get(key)
        if seen is None:
            first[key] = message
            continue
        copies += 1
        assert seen.data is not None
        if _without(seen.data, "headerId", "timestamp") != _without(message.data, "headerId", "timestamp"):
            changed = sorted(
                k
                for k in set(seen.data) | set(message.data)
                if k not in ("headerId", "timestamp") and seen.data.get(k) != message.data.get(k)
            )
            result.problems.append(
                f"robot {message.serial}: order {key[0]} update {key[1]} re-sent with different {changed} "
                f"(headerId {seen.data.get('headerId')} at {_at(seen.t, origin)} vs "
                f"{message.data.get('headerId')} at {_at(message.t, origin)})"
            )
    result.notes.append(f"{len(first)} orders, {copies} re-sent copies compared")
    return result


# --- 3. no new order to a busy robot ------------------------------------------------------------------


def check_no_order_while_busy(
    messages: Sequence[WireMessage], blind: Sequence[Window], origin: float | None = None
) -> CheckResult:
    """No new orderId goes to a robot whose latest state before it (in the observer's arrival order)
    showed it busy with another order. A state with a `blind` window (the observer away) between it and
    the order may not be the latest, so such orders are left out, as are orders with no state of their
    robot before them."""
    result = CheckResult("no new order to a busy robot")
    latest: dict[str, WireMessage] = {}
    orders_seen: dict[str, set[str]] = defaultdict(set)
    checked = unknown = 0
    for message in messages:
        if message.data is None:
            continue
        if message.kind == "state":
            latest[message.serial] = message
            continue
        if message.kind != "order":
            continue
        order_id = str(message.data.get("orderId"))
        if order_id in orders_seen[message.serial]:
            continue  # a re-send or an update of an order the robot was sent before
        orders_seen[message.serial].add(order_id)
        state = latest.get(message.serial)
        if state is None or excused(blind, state.t, message.t):
            unknown += 1
            continue
        checked += 1
        assert state.data is not None
        if state.data.get("orderId") == order_id:
            continue  # the robot has it already: a re-send whose first copy the observer missed
        if busy(state.data):
            running = [
                f"{a.get('actionId')}={a.get('actionStatus')}"
                for a in state.data.get("actionStates") or ()
                if a.get("actionStatus") not in FINAL_ACTION_STATUSES
            ]
            result.problems.append(
                f"robot {message.serial}: new order {order_id} (headerId {message.data.get('headerId')}, "
                f"{_at(message.t, origin)}) while its latest state (headerId {state.data.get('headerId')}, "
                f"{_at(state.t, origin)}) showed it busy with order {state.data.get('orderId')}: "
                f"{len(state.data.get('nodeStates') or ())} node states, actions {running}"
            )
    result.notes.append(f"{checked} new orders checked, {unknown} without a known latest state")
    return result


# --- 4. leaves in order, never twice ------------------------------------------------------------------


def check_leaves(
    posted: Sequence[PostedMission],
    final: Mapping[str, Mapping[str, Any] | None],
    messages: Sequence[WireMessage],
    blind: Sequence[Window],
    origin: float | None = None,
    restarts: Sequence[Window] = (),
    trips: frozenset[str] = frozenset(),
) -> CheckResult:
    """Each mission's leaves are reached in order and never twice (`trips`: the charging and parking
    missions the dispatch core made, whose orders are left out).

    API: a COMPLETED mission has every node (and root) COMPLETED in node_status. Wire: in arrival order,
    a mission's orders never go back to an earlier leaf, each leaf has a single orderId (a second attempt
    is the leaf run again), every order belongs to a leaf of a posted mission, and a COMPLETED mission
    during which the observer never looked away had an order on the wire for each of its leaves. A leaf
    sent ahead in an order update (`carried_leaf`) counts only if the robot's states show it took that
    update: one it never took (lost, refused) ran nothing, and the leaf gets an order of its own. A leaf's
    next attempt sent after its robot restarted (a `restarts` window overlaps the time from the leaf's
    previous order to that one: the robot went down after the previous order, or the previous order went
    out while it was down and never reached the fresh robot) is the rest of its route resumed: not the
    leaf run twice, nor a step back from the next leaf if that one had only been sent ahead."""
    result = CheckResult("leaves in order, never twice")
    resumed = 0
    by_name = {m.name: m for m in posted}
    taken = updates_taken(messages)
    wire: dict[str, list[tuple[int, str, WireMessage]]] = defaultdict(list)
    sent_before: set[tuple[str, str, int]] = set()
    for message in messages:
        if message.kind != "order" or message.data is None:
            continue
        order_id = carried_leaf(message.data)
        parsed = parse_order_id(order_id)
        if parsed is not None and parsed[0] in trips:
            continue
        if parsed is None or parsed[0] not in by_name:
            result.problems.append(f"robot {message.serial}: order {order_id} of no posted mission")
            continue
        update = int(message.data.get("orderUpdateId") or 0)
        if update and taken.get((message.serial, str(message.data.get("orderId"))), 0) < update:
            continue
        sending = (message.serial, str(message.data.get("orderId")), update)
        if sending in sent_before:
            continue  # a resend (check 2 compares its content), not a step back to its leaf
        sent_before.add(sending)
        wire[parsed[0]].append((parsed[1], order_id, message))
    for mission in posted:
        leaf_names = dict(mission.leaves)
        obj = final.get(mission.name)
        status = (obj or {}).get("status") or {}
        if status.get("state") == "COMPLETED":
            node_status = status.get("node_status") or {}
            expected = set(mission.nodes or leaf_names.values()) | {"root"}
            not_completed = sorted(
                f"{name}={(node_status.get(name) or {}).get('state')}"
                for name in expected
                if (node_status.get(name) or {}).get("state") != "COMPLETED"
            )
            if not_completed:
                result.problems.append(
                    f"mission {mission.name} (robot {mission.robot}) COMPLETED with nodes {not_completed}"
                )
        highest = -1
        ids_per_leaf: dict[int, list[str]] = defaultdict(list)
        sent_at: dict[int, float] = {}  # when the leaf's latest orderId was first seen
        for index, order_id, message in wire.get(mission.name, ()):
            if index not in leaf_names:
                result.problems.append(
                    f"mission {mission.name} (robot {mission.robot}): order {order_id} for node {index}, "
                    f"which is not a leaf (leaves {sorted(leaf_names)})"
                )
                continue
            ids = ids_per_leaf[index]
            resuming = (
                order_id not in ids
                and bool(ids)
                and any(w.overlaps(sent_at[index], message.t) for w in restarts)
            )
            if index < highest and not resuming:  # resuming: the later leaf had only gone ahead
                result.problems.append(
                    f"mission {mission.name} (robot {mission.robot}): order {order_id} for leaf "
                    f"{leaf_names[index]} came after an order for the later leaf n{highest} "
                    f"({_at(message.t, origin)})"
                )
            highest = max(highest, index)
            if order_id in ids:
                continue
            if resuming:
                resumed += 1
                ids[-1] = order_id  # the rest of the leaf, resumed: it stands for the leaf
            else:
                ids.append(order_id)
            sent_at[index] = message.t
        for index, ids in sorted(ids_per_leaf.items()):
            if len(ids) > 1:
                result.problems.append(
                    f"mission {mission.name} (robot {mission.robot}): leaf {leaf_names[index]} reached "
                    f"{len(ids)} times, orders {ids}"
                )
        start, end = _epoch(status.get("start_timestamp")), _epoch(status.get("end_timestamp"))
        if status.get("state") == "COMPLETED" and start is not None and end is not None:
            if excused(blind, start, end):
                continue
            missing = [name for index, name in mission.leaves if index not in ids_per_leaf]
            if missing:
                result.problems.append(
                    f"mission {mission.name} (robot {mission.robot}) COMPLETED, but no order was seen for "
                    f"leaves {missing} (the observer saw all traffic from {_at(start, origin)} to "
                    f"{_at(end, origin)})"
                )
    result.notes.append(f"{sum(len(v) for v in wire.values())} order messages of {len(wire)} missions")
    if resumed:
        result.notes.append(f"{resumed} leaves resumed after their robot restarted")
    return result


# --- 5. headerIds -------------------------------------------------------------------------------------


def check_bindings(
    posted: Sequence[PostedMission],
    final: Mapping[str, Mapping[str, Any] | None],
    messages: Sequence[WireMessage],
) -> CheckResult:
    """None bound twice (issue 41): a mission posted without a robot has at most one binding not given
    back, its robot is its latest binding's, and its orders went only to robots it was bound to; a
    mission posted with its robot was never bound by assignment. (A robot's one mission at a time is
    check 3's.)"""
    result = CheckResult("none bound twice")
    robots_of_orders: dict[str, set[str]] = defaultdict(set)
    for message in messages:
        if message.kind == "order" and message.data is not None:
            parsed = parse_order_id(carried_leaf(message.data))
            if parsed is not None:
                robots_of_orders[parsed[0]].add(message.serial)
    unbound = 0
    for mission in posted:
        obj = final.get(mission.name) or {}
        bindings = (obj.get("status") or {}).get("assignment") or []
        if mission.robot != UNBOUND:
            if bindings:
                result.problems.append(f"mission {mission.name} of {mission.robot} was bound: {bindings}")
            continue
        unbound += 1
        held = [binding for binding in bindings if binding.get("released_at") is None]
        if len(held) > 1:
            result.problems.append(f"mission {mission.name} is bound to {len(held)} robots at once: {held}")
        if obj.get("robot") is not None and (not bindings or bindings[-1]["robot"] != obj["robot"]):
            result.problems.append(f"mission {mission.name}: robot {obj['robot']} is not its last binding")
        strangers = robots_of_orders[mission.name] - {binding["robot"] for binding in bindings}
        if strangers:
            result.problems.append(f"mission {mission.name}: orders went to robots never bound: {strangers}")
    result.notes.append(f"{unbound} missions posted without a robot")
    return result


def check_header_ids(
    messages: Sequence[WireMessage],
    excuses: Sequence[Window],
    *,
    since: float,
    topics: Sequence[str] = SERVER_TOPICS,
    origin: float | None = None,
    events: Sequence[ServiceEvent] = (),
) -> CheckResult:
    """Per robot and server topic, the distinct headerIds run from 0 without gaps (+1); every copy of a
    headerId is the same message but for `timestamp`. A gap whose neighbours straddle one of `excuses`
    (broker outages, the observer reconnecting) is not counted: those messages never reached the observer.
    `since` is when the observer started listening, before the robots existed; `events` (the faults) only
    add context to a problem."""
    result = CheckResult("headerIds without gaps or reuse")
    copies: dict[tuple[str, str], dict[int, list[WireMessage]]] = defaultdict(lambda: defaultdict(list))
    for message in messages:
        if message.kind not in topics or message.data is None:
            continue
        header_id = message.data.get("headerId")
        if not isinstance(header_id, int):
            result.problems.append(f"robot {message.serial} {message.kind}: no integer headerId")
            continue
        copies[(message.serial, message.kind)][header_id].append(message)
    excused_gaps = 0
    for (serial, topic), by_id in sorted(copies.items()):
        for header_id, same in sorted(by_id.items()):
            reference = same[0].data
            assert reference is not None
            for other in same[1:]:
                assert other.data is not None
                if _without(reference, "timestamp") != _without(other.data, "timestamp"):
                    result.problems.append(
                        f"robot {serial} {topic}: headerId {header_id} carried two different messages "
                        f"({_describe(reference)} at {_at(same[0].t, origin)}, {_describe(other.data)} "
                        f"at {_at(other.t, origin)})"
                    )
        previous_id, previous_t = -1, since
        for header_id, same in sorted(by_id.items()):
            t = same[0].t
            if header_id > previous_id + 1:
                window = excused(excuses, previous_t, t)
                if window is not None:
                    excused_gaps += 1
                else:
                    missing = (
                        f"{previous_id + 1}"
                        if header_id == previous_id + 2
                        else f"{previous_id + 1}..{header_id - 1}"
                    )
                    result.problems.append(
                        f"robot {serial} {topic}: headerIds {missing} never seen between {previous_id} "
                        f"({_at(previous_t, origin)}) and {header_id} ({_at(t, origin)}: "
                        f"{_describe(same[0].data)}), with no broker outage in between"
                        + _events_between(events, previous_t, t, origin)
                    )
            previous_id, previous_t = header_id, t
    result.notes.append(
        f"{len(copies)} robot topics, {excused_gaps} gaps excused by broker outages or observer reconnects"
    )
    return result


def _describe(data: Mapping[str, Any] | None) -> str:
    if data is None:
        return "?"
    if "orderId" in data:
        return f"order {data.get('orderId')} update {data.get('orderUpdateId')}"
    actions = data.get("actions", data.get("instantActions")) or ()
    return "instant actions " + ",".join(str(a.get("actionType")) for a in actions if isinstance(a, dict))


# --- 6. no 5xx while PostgreSQL and Redis are up ------------------------------------------------------


IMPAIRING = ("api", "postgres", "redis")


def impaired_windows(
    events: Sequence[ServiceEvent], *, grace: float, components: Sequence[str] = IMPAIRING
) -> list[Window]:
    """Per component, from each "down" to the next "up" plus `grace` (to the end of time if never up)."""
    windows = []
    down: dict[str, float] = {}
    for event in sorted(events, key=lambda e: e.t):
        if event.component not in components:
            continue
        if event.kind == "down":
            down.setdefault(event.component, event.t)
        elif event.kind == "up" and event.component in down:
            windows.append(Window(down.pop(event.component), event.t + grace, event.component))
    windows += [Window(t, float("inf"), component) for component, t in down.items()]
    return windows


def check_http(
    attempts: Sequence[HttpAttempt],
    events: Sequence[ServiceEvent],
    *,
    grace: float,
    origin: float | None = None,
) -> CheckResult:
    """No 5xx, timeout or refused connection while the API process ran (and had been serving for `grace`
    seconds since a restart) and PostgreSQL and Redis were up (for `grace` seconds since their restart);
    no 4xx to a POST of the load (whose bodies are valid), except "already exists" for a retried POST."""
    result = CheckResult("no 5xx while PostgreSQL and Redis are up")
    windows = impaired_windows(events, grace=grace)
    failed = excused_count = 0
    for attempt in attempts:
        what = f"{attempt.method} {attempt.path} ({_at(attempt.start, origin)}..{_at(attempt.end, origin)})"
        if attempt.status is not None and 400 <= attempt.status < 500:
            if attempt.method == "POST" and not attempt.exists_after_retry:
                result.problems.append(f"{what} answered {attempt.status}: {attempt.body[:300]}")
            continue
        if attempt.status is not None and attempt.status < 500:
            continue
        failed += 1
        if excused(windows, attempt.start, attempt.end) is not None:
            excused_count += 1
            continue
        answer = f"answered {attempt.status}" if attempt.status is not None else f"failed: {attempt.error}"
        result.problems.append(
            f"{what} {answer} while the API, PostgreSQL and Redis were up: {attempt.body[:300]}"
        )
    result.notes.append(
        f"{len(attempts)} requests, {failed} 5xx/errors, "
        f"{excused_count} of them during a fault (+{grace:g} s)"
    )
    return result


# --- 7. no unexpected process exit --------------------------------------------------------------------


def check_processes(
    exits: Sequence[ProcessExit], running_at_end: Mapping[str, bool], origin: float | None = None
) -> CheckResult:
    """No process of the stack exited by itself during the run, and all of them run at its end."""
    result = CheckResult("no unexpected process exit")
    for process in exits:
        result.problems.append(
            f"{process.name} exited by itself at {_at(process.t, origin)} with code {process.returncode}"
            + (f"; its log ends: {process.tail}" if process.tail else "")
        )
    for name, running in sorted(running_at_end.items()):
        if not running:
            result.problems.append(f"{name} is not running at the end of the run")
    result.notes.append(f"{len(running_at_end)} processes watched")
    return result


# --- 9. stations (issue 44) ------------------------------------------------------------------------------


@dataclass(frozen=True)
class StationSample:
    """A station as GET /station showed it at `t`: the robots holding it, of its capacity."""

    t: float
    name: str
    kind: str
    capacity: int
    reservations: tuple[str, ...]


def check_station_capacity(samples: Sequence[StationSample], origin: float | None = None) -> CheckResult:
    """No station ever held more robots than its capacity, and no robot held two stations at once, in any
    answer of GET /station (one answer is one snapshot of every station)."""
    result = CheckResult("no station over capacity")
    by_time: dict[float, list[StationSample]] = defaultdict(list)
    for sample in samples:
        by_time[sample.t].append(sample)
        if len(sample.reservations) > sample.capacity:
            result.problems.append(
                f"station {sample.name} held {len(sample.reservations)} robots "
                f"({', '.join(sample.reservations)}) of its capacity {sample.capacity} "
                f"at {_at(sample.t, origin)}"
            )
    for t, snapshot in sorted(by_time.items()):
        holders = [robot for sample in snapshot for robot in sample.reservations]
        twice = sorted({robot for robot in holders if holders.count(robot) > 1})
        if twice:
            result.problems.append(f"robots {twice} held two stations at once at {_at(t, origin)}")
    result.notes.append(f"{len(by_time)} snapshots of {len({sample.name for sample in samples})} stations")
    return result


def check_zone_capacity(
    messages: Sequence[WireMessage],
    zones: Mapping[str, Polygon],
    windows: Sequence[Window],
    origin: float | None = None,
) -> CheckResult:
    """Never two robots inside a capacity-1 RELEASE zone at once, from every recorded state's position
    replayed in arrival order (each robot where its latest state put it). A robot's stay in a zone that
    overlaps a window is left out: its simulator restarted (offline, it held nothing, and another robot
    may be let in before it reports again from inside), or the observer missed its states."""
    result = CheckResult("never two robots inside a capacity-1 zone")
    stays: dict[str, dict[str, float]] = {zone: {} for zone in zones}  # zone -> robot -> inside since
    reported: set[tuple[str, tuple[str, ...]]] = set()
    excused_stays: set[tuple[str, str, float]] = set()
    entered: set[tuple[str, str, float]] = set()
    states = 0
    for message in messages:
        data = (message.data or {}) if message.kind == "state" else {}
        position = data.get("agvPosition") or data.get("mobileRobotPosition")  # 2.x, 3.0
        if not isinstance(position, dict):
            continue
        states += 1
        for zone, polygon in zones.items():
            inside = stays[zone]
            if contains(polygon, (position["x"], position["y"])):
                inside.setdefault(message.serial, message.t)
            else:
                inside.pop(message.serial, None)
            counted = []
            entered.update((zone, robot, since) for robot, since in inside.items())
            for robot, since in inside.items():
                if excused(windows, since, message.t) is None:
                    counted.append(robot)
                else:
                    excused_stays.add((zone, robot, since))
            together = (zone, tuple(sorted(counted)))
            if len(counted) > 1 and together not in reported:
                reported.add(together)
                result.problems.append(
                    f"robots {', '.join(together[1])} inside zone {zone} together at {_at(message.t, origin)}"
                )
    result.notes.append(
        f"{states} states replayed; {len(entered)} stays in {len(zones)} zones, "
        f"{len(excused_stays)} of them overlapping a fault left out"
    )
    return result


def check_low_robots_charge(
    robots: Mapping[str, Mapping[str, Any]], stations: Sequence[StationSample]
) -> CheckResult:
    """At the end, no robot online at or below its minimum (its critical level where it has none) is left
    without a charger while a charger has room: each holds one (on its way or charging) or none is free.
    (The robots here may use every charger: one map, no robot types.)"""
    result = CheckResult("no low robot without a charger while one is free")
    chargers = [station for station in stations if station.kind == "CHARGER"]
    holding = {robot for station in chargers for robot in station.reservations}
    free = [station.name for station in chargers if len(station.reservations) < station.capacity]
    low = 0
    for name, robot in sorted(robots.items()):
        status, battery = robot.get("status") or {}, robot.get("battery") or {}
        minimum = battery.get("recommended_minimum")
        threshold = max(battery.get("critical_level") or 0.0, minimum if minimum is not None else 0.0)
        if not status.get("online") or status.get("battery_level", 100.0) > threshold:
            continue
        low += 1
        if name not in holding and free:
            result.problems.append(
                f"robot {name} at {status.get('battery_level')} % (minimum {threshold}) holds no charger "
                f"while {free} have room; it waits: {status.get('charging_waiting_reason')!r}"
            )
    result.notes.append(f"{low} robots low at the end, {len(chargers)} chargers")
    return result

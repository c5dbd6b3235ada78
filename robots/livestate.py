"""Robots' live state in Redis: the latest VDA 5050 state, who is online, when each robot was last heard.

The bridge writes here on every message (cheap, in memory); the dispatch step reads from here instead of
PostgreSQL, so the database sees a write only when something a user or the engine cares about changed.
"""

import hashlib
import threading
from dataclasses import dataclass
from datetime import UTC, datetime
from functools import cache
from typing import Any, NamedTuple

import redis
from django.conf import settings

from dispatch.held import HeldOrder, StateDigest
from kit import redis_wire

PREFIX = "fleet"
ONLINE_SET = f"{PREFIX}:online"
LAST_SEEN = f"{PREFIX}:last-seen"

# Stores a state unless an equal-or-newer one is already stored (reordered or duplicated messages are
# harmless), marks the robot heard and online, and says whether what steps read (its digest) changed.
# Messages are ordered by the robot's (timestamp, headerId); a restarted robot resets headerId, not time.
# A state not stored does not count as heard: a replayed one must not keep a silent robot online.
# KEYS: robot hash, LAST_SEEN, ONLINE_SET. ARGV: payload, timestamp (ms), headerId, the state's StateDigest's
# full, events, order_id, order_update_id and busy, when the state arrived (epoch s, the bridge's clock), the
# robot's name, the digest's finished_actions.
# Returns {outcome, came online (1/0)[, the replaced state's digest fields, in that order]}: outcome -1
# replayed (the stored state's timestamp and headerId), 0 stale (older), 1 same digest, 2 changed. A state
# stored by a bridge that did not record finished actions apart has '' for them (NO_FINISHED_ACTIONS).
_STORE_STATE = """
local old = redis.call('HMGET', KEYS[1], 'ts', 'hid', 'full', 'events', 'order_id', 'order_update_id', 'busy',
  'finished')
local ts, hid = tonumber(ARGV[2]), tonumber(ARGV[3])
if old[1] then
  local old_ts, old_hid = tonumber(old[1]), tonumber(old[2])
  if old_ts == ts and old_hid == hid then return {-1, 0} end
  if old_ts > ts or (old_ts == ts and old_hid > hid) then return {0, 0} end
end
redis.call('HSET', KEYS[1], 'state', ARGV[1], 'ts', ARGV[2], 'hid', ARGV[3],
  'full', ARGV[4], 'events', ARGV[5], 'order_id', ARGV[6], 'order_update_id', ARGV[7], 'busy', ARGV[8],
  'at', ARGV[9], 'finished', ARGV[11])
redis.call('ZADD', KEYS[2], ARGV[9], ARGV[10])
local came_online = redis.call('SADD', KEYS[3], ARGV[10])
if old[3] == ARGV[4] then return {1, came_online} end
if not old[3] then return {2, came_online} end
return {2, came_online, old[3], old[4], old[5], old[6], old[7], old[8] or ''}
"""

# Orders a robot's messages on another topic as states are ordered, by (timestamp, headerId): records the
# message's as the newest of its topic unless an equal or newer one is recorded.
# KEYS: robot hash. ARGV: topic, timestamp (ms), headerId. Returns -1 replayed, 0 stale, 1 newest.
_ORDER_MESSAGE = """
local ts_field, hid_field = 'ts:' .. ARGV[1], 'hid:' .. ARGV[1]
local old = redis.call('HMGET', KEYS[1], ts_field, hid_field)
local ts, hid = tonumber(ARGV[2]), tonumber(ARGV[3])
if old[1] then
  local old_ts, old_hid = tonumber(old[1]), tonumber(old[2])
  if old_ts == ts and old_hid == hid then return -1 end
  if old_ts > ts or (old_ts == ts and old_hid > hid) then return 0 end
end
redis.call('HSET', KEYS[1], ts_field, ARGV[2], hid_field, ARGV[3])
return 1
"""

# Claims the right to publish messages to a robot: each (field, headerId) in turn, if the field (the last
# headerId published on a topic) is below it, raises the field to it. Returns 1/0 per message: claimed or
# not (another step published it already). KEYS: robot hash. ARGV: field, headerId, field, headerId, ...
_CLAIM = """
local claimed = {}
for i = 1, #ARGV, 2 do
  local id = tonumber(ARGV[i + 1])
  if id > (tonumber(redis.call('HGET', KEYS[1], ARGV[i])) or -1) then
    redis.call('HSET', KEYS[1], ARGV[i], id)
    claimed[#claimed + 1] = 1
  else
    claimed[#claimed + 1] = 0
  end
end
return claimed
"""

# Gives a claim back: sets the field to ARGV[2] if it still holds ARGV[1] (nobody claimed past it since).
# KEYS: robot hash. ARGV: field, claimed headerId, headerId to go back to.
_UNCLAIM = """
if redis.call('HGET', KEYS[1], ARGV[1]) == ARGV[2] then redis.call('HSET', KEYS[1], ARGV[1], ARGV[3]) end
return 0
"""

# Scripts are called by their SHA, so a pipeline of them costs one round trip (`execute`).
_SCRIPTS = (_STORE_STATE, _ORDER_MESSAGE, _CLAIM, _UNCLAIM)
_STORE_STATE_SHA = hashlib.sha1(_STORE_STATE.encode()).hexdigest()
_ORDER_MESSAGE_SHA = hashlib.sha1(_ORDER_MESSAGE.encode()).hexdigest()
_CLAIM_SHA = hashlib.sha1(_CLAIM.encode()).hexdigest()
_UNCLAIM_SHA = hashlib.sha1(_UNCLAIM.encode()).hexdigest()

REPLAYED, STALE, UNCHANGED, CHANGED = -1, 0, 1, 2
NEWEST = 1  # an `order_message` result: the message is the newest of its topic

Command = redis_wire.Command  # a Redis command: its name, then its arguments


@dataclass(frozen=True)
class Stored:
    """What storing a state did: REPLAYED or STALE (not stored), UNCHANGED or CHANGED, and for CHANGED the
    digest it replaced (None: the first state); whether the robot was not online before."""

    outcome: int
    replaced: StateDigest | None = None
    came_online: bool = False


_client_lock = threading.Lock()


@cache
def _cached_client() -> redis.Redis:
    return redis.Redis.from_url(settings.REDIS_URL)


def client() -> redis.Redis:
    """One connection pool per process (redis-py pools are thread-safe and fork-aware).

    The lock makes the first call single: two threads must not each build a client, or the one thrown
    away closes connections the other is using."""
    with _client_lock:
        return _cached_client()


def robot_key(name: str) -> str:
    return f"{PREFIX}:robot:{name}"


def store_state(
    pipe: redis.client.Pipeline,
    *,
    name: str,
    payload: bytes,
    timestamp_ms: int,
    header_id: int,
    digest: StateDigest,
    arrived_at: float,
) -> None:
    """Queue the store on `pipe`, to run with `execute`; `stored` reads its result. A stored state marks the
    robot heard at `arrived_at` (epoch s, this host's clock) and online."""
    args = [payload, timestamp_ms, header_id, digest.full, digest.events, digest.order_id]
    args += [digest.order_update_id, int(digest.busy)]
    args += [repr(arrived_at), name, digest.finished_actions]
    pipe.evalsha(_STORE_STATE_SHA, 3, robot_key(name), LAST_SEEN, ONLINE_SET, *args)


def order_message(
    pipe: redis.client.Pipeline, *, name: str, topic: str, timestamp_ms: int, header_id: int
) -> None:
    """Queue on `pipe`: is this message of the robot on `topic` (not `state`: `store_state` orders states)
    newer than every one before? Its result: REPLAYED, STALE or NEWEST (then recorded as the newest)."""
    pipe.evalsha(_ORDER_MESSAGE_SHA, 1, robot_key(name), topic, timestamp_ms, header_id)


def execute(pipe: redis.client.Pipeline) -> list[Any]:
    """Run `pipe` in one round trip (`round_trip`), loading this module's scripts first only if Redis
    lacks them (a restart). Replies are Redis's own: redis-py's response callbacks do not run.

    redis-py's own script objects ask Redis whether it has the script before every pipeline: a round trip
    per batch of states on the bridge's hot path."""
    commands = [args for args, _ in pipe.command_stack]
    pipe.reset()
    if not commands:
        return []
    results = round_trip(commands)
    missing = [
        index for index, result in enumerate(results) if isinstance(result, redis.exceptions.NoScriptError)
    ]
    if missing:
        for script in _SCRIPTS:
            client().script_load(script)
        again = round_trip([commands[index] for index in missing])
        for index, result in zip(missing, again, strict=True):
            results[index] = result
    for result in results:
        if isinstance(result, Exception):
            raise result
    return results


def round_trip(commands: list[Command]) -> list[Any]:
    """Send `commands` at once on this thread's connection and read their replies, an error reply in its
    place (`kit.redis_wire`)."""
    return redis_wire.round_trip(client().connection_pool, commands)


def stored(result: list[Any]) -> Stored:
    """What a `store_state` did, from its result in the pipeline's results."""
    outcome, came_online, *digest = result
    if not digest:
        return Stored(outcome, None, bool(came_online))
    full, events, order_id, order_update_id, busy, finished_actions = (value.decode() for value in digest)
    replaced = StateDigest(full, events, finished_actions, order_id, int(order_update_id), busy == "1")
    return Stored(CHANGED, replaced, bool(came_online))


class LatestState(NamedTuple):
    """A robot's latest stored state (its JSON), when it arrived (None if not recorded), and the headerId
    last published to the robot on each topic (`mark_published`; a topic missing if not known)."""

    payload: bytes | None
    arrived_at: datetime | None
    published: dict[str, int]


def latest_state(name: str) -> LatestState:
    """The robot's latest state. One `round_trip`."""
    return _latest_state(name, [])


def states(names: list[str]) -> dict[str, bytes | None]:
    """The latest state of each robot (None if none is stored). One `round_trip`."""
    replies = round_trip([("HGET", robot_key(name), "state") for name in names]) if names else []
    return dict(zip(names, replies, strict=True))


def state_for_step(name: str) -> LatestState:
    """`latest_state`, as a step reads it: in the same round trip the robot's step stops counting as queued
    (`step_marker_key`), so a change stored from now on asks for another step, while one stored before is
    in what this returns. On every step's path: one `round_trip`."""
    return _latest_state(name, [("DEL", step_marker_key(name))])


def _latest_state(name: str, before: list[Command]) -> LatestState:
    fields = [_published_field(topic) for topic in PUBLISHED_TOPICS]
    *_, (payload, at, *published) = round_trip([*before, ("HMGET", robot_key(name), "state", "at", *fields)])
    return LatestState(
        payload,
        _arrival(at),
        {topic: int(hid) for topic, hid in zip(PUBLISHED_TOPICS, published, strict=True) if hid is not None},
    )


def step_marker_key(name: str) -> str:
    """Exists while a step of the robot is queued and has not read the robot's state yet (`state_for_step`)
    (`workers.step_requests.queue_steps` sets it): at most one queued step per robot."""
    return f"{PREFIX}:step-queued:{name}"


# The topics on which the server sends robots messages (vda5050.topics.Topic values).
PUBLISHED_TOPICS = ("order", "instantActions", "zoneSet", "responses")


def _published_field(topic: str) -> str:
    return f"published:{topic}"


def claim_published(name: str, messages: list[tuple[str, int]]) -> list[bool]:
    """For each (topic, headerId), in order, whether this caller is the one to publish it: the first to
    claim a headerId gets it, so a message two steps both hold goes out once. One round trip."""
    args = [value for topic, header_id in messages for value in (_published_field(topic), header_id)]
    pipe = client().pipeline(transaction=False)
    pipe.evalsha(_CLAIM_SHA, 1, robot_key(name), *args)
    return [bool(claimed) for claimed in execute(pipe)[0]]


def unclaim_published(pipe: redis.client.Pipeline, name: str, topic: str, claimed: int, back_to: int) -> None:
    """Queue on `pipe`: the messages after `back_to` on `topic` did not go out after all (claimed up to
    `claimed`), so that a later step sends them; unless another step has claimed past them meanwhile."""
    pipe.evalsha(_UNCLAIM_SHA, 1, robot_key(name), _published_field(topic), claimed, back_to)


def orders_held(names: list[str]) -> dict[str, HeldOrder | None]:
    """The order each robot's latest state holds, in one round trip; None for a robot without a state."""
    pipe = client().pipeline(transaction=False)
    for name in names:
        pipe.hmget(robot_key(name), "order_id", "order_update_id", "busy", "at")
    return {
        name: None
        if order_id is None
        else HeldOrder(order_id.decode(), int(update_id), busy == b"1", _arrival(at))
        for name, (order_id, update_id, busy, at) in zip(names, pipe.execute(), strict=True)
    }


def _arrival(at: bytes | None) -> datetime | None:
    """A state's stored arrival time (epoch s); states stored before it was recorded have none."""
    return None if at is None else datetime.fromtimestamp(float(at), UTC)


def mark_offline(name: str) -> bool:
    """True if the robot was online before. Its last heard time goes too: the robot said it is offline,
    or was silent too long, so only a message after this one may count as heard (`heard_within`)."""
    pipe = client().pipeline(transaction=True)
    pipe.srem(ONLINE_SET, name)
    pipe.zrem(LAST_SEEN, name)
    return bool(pipe.execute()[0])


def mark_online(names: list[str]) -> None:
    """Robots the online set lacks although they were heard (a bridge stopped between its two writes)."""
    if names:
        client().sadd(ONLINE_SET, *names)


def last_seen(names: list[str]) -> dict[str, float | None]:
    if not names:
        return {}
    return dict(zip(names, client().zmscore(LAST_SEEN, names), strict=True))


def forget(name: str) -> None:
    """Drop everything known about a deleted robot."""
    pipe = client().pipeline()
    pipe.delete(robot_key(name))
    pipe.srem(ONLINE_SET, name)
    pipe.zrem(LAST_SEEN, name)
    pipe.execute()

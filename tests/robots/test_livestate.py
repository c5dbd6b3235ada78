"""`livestate.round_trip`: the bridge's and the steps' Redis round trips on a thread's own connection."""

import multiprocessing
import multiprocessing.connection
import signal
import threading
import uuid
from collections.abc import Iterator

import pytest
import redis

from robots import livestate


@pytest.fixture
def key() -> Iterator[str]:
    name = f"{livestate.PREFIX}:test:{uuid.uuid4().hex}"
    yield name
    livestate.client().delete(name)


def _connection_id() -> int:
    [connection_id] = livestate.round_trip([("CLIENT", "ID")])
    return connection_id


def test_replies_come_raw_in_order_an_error_in_its_place_and_the_connection_stays_usable(
    key: str,
) -> None:
    replies = livestate.round_trip(
        [("SET", key, "text"), ("HINCRBY", key, "field", 1), ("GET", key), ("HMGET", key + ":none", "a", "b")]
    )

    assert replies[0] == b"OK"
    assert isinstance(replies[1], redis.exceptions.ResponseError)
    assert "WRONGTYPE" in str(replies[1])
    assert replies[2:] == [b"text", [None, None]]
    assert livestate.round_trip([("GET", key)]) == [b"text"]


def test_a_connection_redis_dropped_is_replaced_and_the_commands_sent_again(key: str) -> None:
    dropped = _connection_id()
    livestate.client().client_kill_filter(_id=dropped)

    assert livestate.round_trip([("SET", key, "after"), ("GET", key)]) == [b"OK", b"after"]
    assert _connection_id() != dropped


class Interrupted(Exception):
    pass


def _interrupt(signum: int, frame: object) -> None:
    raise Interrupted


def test_a_round_trip_interrupted_while_reading_leaves_no_reply_behind_for_the_next(key: str) -> None:
    """redis-py's read drops the connection it was interrupted in; `round_trip` drops it too (for an
    interruption between two reads, which a test cannot time). Either alone passes this test; with
    neither, the next round trip reads the BLPOP's reply as its first."""
    interrupted = _connection_id()
    previous = signal.signal(signal.SIGALRM, _interrupt)
    signal.setitimer(signal.ITIMER_REAL, 0.2)  # while Redis holds the BLPOP's reply back for 2 s
    try:
        with pytest.raises(Interrupted):
            livestate.round_trip([("BLPOP", key + ":empty", 2)])
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, previous)

    # On the interrupted connection the BLPOP's nil would be read as the SET's reply.
    assert livestate.round_trip([("SET", key, "after"), ("GET", key)]) == [b"OK", b"after"]
    assert _connection_id() != interrupted


def test_execute_runs_a_pipeline_in_one_round_trip_and_raises_its_first_error(key: str) -> None:
    pipe = livestate.client().pipeline(transaction=False)
    pipe.hincrby(key, "count", 2)
    pipe.hincrby(key, "count", 3)
    assert livestate.execute(pipe) == [2, 5]
    assert livestate.execute(pipe) == []  # the pipeline was emptied

    pipe.hincrby(key, "count", 1)
    pipe.get(key)  # WRONGTYPE: the key holds a hash
    with pytest.raises(redis.exceptions.ResponseError, match="WRONGTYPE"):
        livestate.execute(pipe)
    assert livestate.client().hget(key, "count") == b"6"  # the command before the error ran


def test_each_thread_has_a_connection_of_its_own() -> None:
    in_thread: list[int] = []
    thread = threading.Thread(target=lambda: in_thread.extend([_connection_id(), _connection_id()]))
    thread.start()
    thread.join()

    assert in_thread[0] == in_thread[1]
    assert _connection_id() == _connection_id() != in_thread[0]


def _report_connection_id(sender: multiprocessing.connection.Connection) -> None:
    sender.send(_connection_id())


def test_a_forked_child_opens_its_own_connection_and_leaves_the_parents_alone() -> None:
    parent = _connection_id()
    receiver, sender = multiprocessing.get_context("fork").Pipe(duplex=False)
    child = multiprocessing.get_context("fork").Process(target=_report_connection_id, args=(sender,))
    child.start()
    child_id = receiver.recv()
    child.join()

    assert child.exitcode == 0
    assert child_id != parent
    assert _connection_id() == parent  # the child's exit did not close the parent's socket

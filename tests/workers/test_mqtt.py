"""The server's MQTT clients (`workers.mqtt`) against the real broker."""

import socket
import threading
import uuid
from collections.abc import Iterator

import pytest
from django.conf import settings

import workers.mqtt
import workers.publish
from missions.robot_step import WireMessage
from robots import livestate
from tests.waiting import wait_for
from tests.workers.subscriber import subscribed
from vda5050.topics import RobotAddress, Topic
from workers.mqtt import Publisher, new_client


def test_a_server_client_sends_every_packet_at_once() -> None:
    client = new_client("test")
    connected = threading.Event()
    client.on_connect = lambda *args: connected.set()
    client.connect(settings.MQTT_HOST, settings.MQTT_PORT)
    client.loop_start()
    try:
        assert connected.wait(10)
        # Without TCP_NODELAY a small message waits for the ACK of the previous one (up to 40 ms).
        assert client.socket().getsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY) == 1
    finally:
        client.disconnect()
        client.loop_stop()


@pytest.fixture
def topic() -> str:
    return f"test/{uuid.uuid4().hex}"


@pytest.fixture
def received(topic: str) -> Iterator[list[bytes]]:
    """The payloads a subscriber to `topic` receives, in order."""
    with subscribed(topic) as payloads:
        yield payloads


@pytest.fixture
def publisher() -> Iterator[Publisher]:
    """A connected publisher of its own (not the process's, which other tests share)."""
    publisher = Publisher()
    assert publisher.wait_connected(10)
    yield publisher
    publisher._client.disconnect()
    publisher._client.loop_stop()


def test_the_publishing_thread_writes_its_message_itself(
    topic: str, received: list[bytes], publisher: Publisher
) -> None:
    """Not paho's network thread, which in a process busy with steps gets the interpreter lock late."""
    writers: list[str] = []
    sock_send = publisher._client._sock_send

    def recording_send(buf: bytes) -> int:
        writers.append(threading.current_thread().name)
        return sock_send(buf)

    publisher._client._sock_send = recording_send
    # Held, the client's write lock keeps the network thread (woken by each message) from writing, and lets
    # this thread's own writes through: a race the network thread wins on an idle machine cannot decide.
    with publisher._client._write_lock:
        for index in range(60):
            publisher.publish(topic, b"%d" % index)
        wait_for(lambda: len(received) == 60)

    assert set(writers) == {threading.current_thread().name}
    assert received == [b"%d" % index for index in range(60)]


def test_threads_publishing_at_once_send_every_message_whole_and_each_thread_s_in_order(
    topic: str, received: list[bytes], publisher: Publisher
) -> None:
    padding = b"x" * 3000  # messages larger than one small write, so pieces of two could interleave

    def publish_from(thread: int) -> None:
        for index in range(100):
            publisher.publish(topic, b"%d %d " % (thread, index) + padding)

    threads = [threading.Thread(target=publish_from, args=(thread,)) for thread in range(4)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    wait_for(lambda: len(received) == 400)

    by_thread: dict[int, list[int]] = {}
    for payload in received:
        thread, index, rest = payload.split(b" ", 2)
        assert rest == padding
        by_thread.setdefault(int(thread), []).append(int(index))
    assert by_thread == {thread: list(range(100)) for thread in range(4)}


def test_messages_the_broker_connection_dropped_do_not_count_as_published(
    settings, monkeypatch: pytest.MonkeyPatch
) -> None:
    """They go out again with the robot's next step (`missions.robot_step._wire_messages`)."""
    with socket.socket() as probe:  # a port nothing listens on: the broker is down
        probe.bind(("127.0.0.1", 0))
        settings.MQTT_PORT = probe.getsockname()[1]
    down = Publisher()
    monkeypatch.setattr(workers.publish, "publisher", lambda: down)
    name = f"dropped-{uuid.uuid4().hex[:8]}"
    address = RobotAddress("uagv", "RobotCompany", name)
    try:
        assert down.publish("test/dropped", b"{}") is False

        pipe = livestate.client().pipeline()
        workers.publish.publish(
            name=name, address=address, messages=[WireMessage(Topic.ORDER, 0, b"{}")], counters=pipe
        )
        pipe.execute()

        assert livestate.latest_state(name).published == {"order": -1}  # claimed, then given back
    finally:
        down._client.loop_stop()
        livestate.forget(name)


def test_a_processs_first_message_goes_out(monkeypatch: pytest.MonkeyPatch, topic: str, received) -> None:
    """Not dropped because the new publisher had not connected yet (a step worker's first order)."""
    monkeypatch.setattr(workers.mqtt, "_publisher", None)
    try:
        assert workers.mqtt.publisher().publish(topic, b"first") is True
        wait_for(lambda: received == [b"first"])
    finally:
        workers.mqtt.publisher()._client.loop_stop()

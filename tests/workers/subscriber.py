"""A subscriber on the real broker, for the workers' tests."""

import threading
from collections.abc import Iterator
from contextlib import contextmanager

from django.conf import settings

from workers.mqtt import new_client


@contextmanager
def subscribed(topic: str) -> Iterator[list[bytes]]:
    """The payloads a subscriber to `topic` receives while the block runs, in order."""
    payloads: list[bytes] = []
    ready = threading.Event()
    client = new_client("test-subscriber")
    client.on_message = lambda client, userdata, message: payloads.append(message.payload)
    client.on_subscribe = lambda *args: ready.set()
    client.on_connect = lambda client, *args: client.subscribe(topic)
    client.connect(settings.MQTT_HOST, settings.MQTT_PORT)
    client.loop_start()
    try:
        assert ready.wait(10)
        yield payloads
    finally:
        client.disconnect()
        client.loop_stop()

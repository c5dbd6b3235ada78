"""MQTT connections of the server processes: one long-lived client per process, never one per message."""

import logging
import os
import socket
import threading
import uuid

import paho.mqtt.client as mqtt
from django.conf import settings

logger = logging.getLogger(__name__)


def new_client(role: str) -> mqtt.Client:
    """A paho client configured from settings; the caller connects it and runs its loop."""
    client = mqtt.Client(
        mqtt.CallbackAPIVersion.VERSION2,
        client_id=f"fleet-{role}-{os.getpid()}-{uuid.uuid4().hex[:8]}",
        transport=settings.MQTT_TRANSPORT,
        reconnect_on_failure=True,
    )
    if settings.MQTT_TRANSPORT == "websockets":
        client.ws_set_options(path=settings.MQTT_WS_PATH)
    if settings.MQTT_USERNAME:
        client.username_pw_set(settings.MQTT_USERNAME, settings.MQTT_PASSWORD or None)
    client.on_socket_open = _no_delay
    client.reconnect_delay_set(min_delay=0.5, max_delay=5)
    client.max_queued_messages_set(100_000)
    return client


def _no_delay(client: mqtt.Client, userdata: object, sock: object) -> None:
    """Send each message at once: with Nagle's algorithm a small packet waits for the previous one's ACK,
    which the peer delays by up to 40 ms."""
    if isinstance(sock, socket.socket):  # a websocket transport wraps its socket
        sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)


class Publisher:
    """A process-wide publishing client. While the broker is unreachable, QoS 0 messages are dropped;
    the engine re-sends whatever the robot does not acknowledge."""

    def __init__(self) -> None:
        self._client = new_client("publisher")
        self._client.on_connect = self._on_connect
        self._client.connect_async(settings.MQTT_HOST, settings.MQTT_PORT, keepalive=30)
        self._client.loop_start()

    @staticmethod
    def _on_connect(
        client: mqtt.Client, userdata: object, flags: object, reason: object, props: object
    ) -> None:
        logger.info("publisher connected to MQTT broker: %s", reason)

    def publish(self, topic: str, payload: bytes, *, qos: int = 0) -> None:
        self._client.publish(topic, payload, qos=qos)


_publisher: Publisher | None = None
_publisher_pid: int | None = None
_publisher_lock = threading.Lock()


def publisher() -> Publisher:
    """The publisher of this process (created after a fork, never shared across processes)."""
    global _publisher, _publisher_pid
    with _publisher_lock:
        if _publisher is None or _publisher_pid != os.getpid():
            _publisher, _publisher_pid = Publisher(), os.getpid()
        return _publisher

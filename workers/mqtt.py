"""MQTT connections of the server processes: one long-lived client per process, never one per message."""

import logging
import os
import socket
import ssl
import threading
import uuid
from typing import Any

import paho.mqtt.client as mqtt
from django.conf import settings

from workers import tuning

logger = logging.getLogger(__name__)


class ServerClient(mqtt.Client):
    """paho's client, whose queued packets any thread may write (`write_queued`), one writer at a time.

    The only place that reaches into paho's internals (`_packet_write`, pinned paho 2.2)."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self._write_lock = threading.RLock()  # a callback paho calls while writing may publish

    def _packet_write(self) -> mqtt.MQTTErrorCode:
        # paho takes a packet off its queue and sends it in two steps: two writers could reorder packets,
        # or interleave the pieces of one that the socket took in part.
        with self._write_lock:
            return super()._packet_write()

    def write_queued(self) -> None:
        """Write the queued packets from this thread. A failed write leaves them queued for the network
        thread, which sees the broken connection too and handles it."""
        self._packet_write()


def new_client(role: str) -> ServerClient:
    """A paho client configured from settings; the caller connects it and runs its loop."""
    client = ServerClient(
        mqtt.CallbackAPIVersion.VERSION2,
        client_id=f"fleet-{role}-{os.getpid()}-{uuid.uuid4().hex[:8]}",
        transport=settings.MQTT_TRANSPORT,
        reconnect_on_failure=True,
    )
    if settings.MQTT_TRANSPORT == "websockets":
        client.ws_set_options(path=settings.MQTT_WS_PATH)
    if settings.MQTT_TLS:  # over websockets too: wss
        client.tls_set_context(tls_context())
    if settings.MQTT_USERNAME:
        client.username_pw_set(settings.MQTT_USERNAME, settings.MQTT_PASSWORD or None)
    client.on_socket_open = _no_delay
    client.reconnect_delay_set(min_delay=0.5, max_delay=5)
    client.max_queued_messages_set(100_000)
    return client


def tls_context() -> ssl.SSLContext:
    """The TLS settings of every server process's client: the broker must show a certificate from
    FLEET_MQTT_TLS_CA_FILE (else a CA the system trusts) issued for FLEET_MQTT_HOST, unless host names are
    not checked; a client certificate goes along if one is configured."""
    context = ssl.create_default_context(cafile=settings.MQTT_TLS_CA_FILE or None)
    context.check_hostname = settings.MQTT_TLS_CHECK_HOSTNAME
    if settings.MQTT_TLS_CERT_FILE:
        context.load_cert_chain(settings.MQTT_TLS_CERT_FILE, settings.MQTT_TLS_KEY_FILE or None)
    return context


def _no_delay(client: mqtt.Client, userdata: object, sock: object) -> None:
    """Send each message at once: with Nagle's algorithm a small packet waits for the previous one's ACK,
    which the peer delays by up to 40 ms."""
    if isinstance(sock, socket.socket):  # a websocket transport wraps its socket
        sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)


class Publisher:
    """A process-wide publishing client. While the broker is unreachable, QoS 0 messages are dropped;
    the engine re-sends whatever the robot does not acknowledge."""

    def __init__(self) -> None:
        self._connected = threading.Event()
        self._client = new_client("publisher")
        self._client.on_connect = self._on_connect
        self._client.connect_async(settings.MQTT_HOST, settings.MQTT_PORT, keepalive=30)
        self._client.loop_start()

    def wait_connected(self, timeout: float) -> bool:
        """Wait up to `timeout` s for the first connection: a message published before it is dropped."""
        return self._connected.wait(timeout)

    def _on_connect(
        self, client: mqtt.Client, userdata: object, flags: object, reason: object, props: object
    ) -> None:
        logger.info("publisher connected to MQTT broker: %s", reason)
        self._connected.set()

    def publish(self, topic: str, payload: bytes, *, qos: int = 0) -> bool:
        """Queue the message and write it from this thread; False if paho dropped it (no connection).

        paho's own network thread writes it only once it has woken up and taken the interpreter lock,
        which in a process busy with steps is milliseconds later (bench/HISTORY.md has the figures)."""
        info = self._client.publish(topic, payload, qos=qos)
        self._client.write_queued()
        return info.rc == mqtt.MQTT_ERR_SUCCESS


_publisher: Publisher | None = None
_publisher_pid: int | None = None
_publisher_lock = threading.Lock()


def publisher() -> Publisher:
    """The publisher of this process (created after a fork, never shared across processes), connected
    unless the broker did not answer within tuning.FIRST_CONNECT_SECONDS."""
    global _publisher, _publisher_pid
    with _publisher_lock:
        if _publisher is None or _publisher_pid != os.getpid():
            _publisher, _publisher_pid = Publisher(), os.getpid()
            _publisher.wait_connected(tuning.FIRST_CONNECT_SECONDS)
        return _publisher

"""A few MQTT connections shared by many fake robots, driven by the asyncio loop (no network threads).

paho's socket hooks put each client's socket into the event loop's selector, as ``simulator.runner``
does per robot; here one connection carries the traffic of hundreds of robots, so the broker and the
generator handle a handful of sockets instead of thousands.
"""

from __future__ import annotations

import asyncio
import logging
import socket
import ssl
import uuid
from collections.abc import Callable
from typing import Any

import paho.mqtt.client as mqtt
from paho.mqtt.enums import CallbackAPIVersion, MQTTProtocolVersion

from simulator.runner import BrokerSettings, read_available

logger = logging.getLogger(__name__)

KEEPALIVE = 30  # s
MISC_PERIOD = 1.0  # s between paho's keep-alive checks
TOPICS_PER_SUBSCRIBE = 100  # topic filters per SUBSCRIBE packet
RECONNECT_DELAY = 1.0  # s

MessageHandler = Callable[[str, bytes], None]


class Connection:
    """One paho client; ``publish`` only queues, the event loop writes when the socket is ready."""

    def __init__(
        self, name: str, broker: BrokerSettings, tls: ssl.SSLContext | None, on_message: MessageHandler
    ) -> None:
        self.name = name
        self.broker = broker
        self.loop = asyncio.get_running_loop()
        self.topics: list[str] = []
        self.disconnects = 0
        self._on_message_handler = on_message
        self._connected = asyncio.Event()
        self._pending_subacks: dict[int, asyncio.Future[None]] = {}
        self._closing = False
        client = mqtt.Client(
            CallbackAPIVersion.VERSION2,
            client_id=f"{name}-{uuid.uuid4().hex[:8]}",
            protocol=MQTTProtocolVersion.MQTTv311,
        )
        if tls is not None:
            client.tls_set_context(tls)
        if broker.username is not None:
            client.username_pw_set(broker.username, broker.password)
        client.on_connect = self._on_connect
        client.on_disconnect = self._on_disconnect
        client.on_subscribe = self._on_subscribe
        client.on_message = self._on_message
        client.on_socket_open = self._on_socket_open
        client.on_socket_close = lambda c, u, sock: self.loop.remove_reader(sock)
        client.on_socket_register_write = lambda c, u, sock: self.loop.add_writer(sock, c.loop_write)
        client.on_socket_unregister_write = lambda c, u, sock: self.loop.remove_writer(sock)
        self.client = client
        self._misc = self.loop.create_task(self._keepalive())

    async def connect(self, timeout: float) -> None:
        self.client.connect(self.broker.host, self.broker.port, keepalive=KEEPALIVE)
        await asyncio.wait_for(self._connected.wait(), timeout)

    async def subscribe(self, topics: list[str], timeout: float) -> None:
        """Subscribe (QoS 0) and wait for every SUBACK; the topics are subscribed again on reconnect."""
        self.topics.extend(topics)
        acks = [
            self._subscribe(topics[i : i + TOPICS_PER_SUBSCRIBE])
            for i in range(0, len(topics), TOPICS_PER_SUBSCRIBE)
        ]
        await asyncio.wait_for(asyncio.gather(*acks), timeout)

    def publish(self, topic: str, payload: bytes, qos: int = 0, retain: bool = False) -> None:
        self.client.publish(topic, payload, qos, retain)

    async def close(self, timeout: float) -> None:
        """Let queued messages leave (QoS 1 ones acknowledged), then disconnect cleanly."""
        deadline = self.loop.time() + timeout
        while self.client.want_write() or self.client._out_messages:  # QoS 1 ones wait for their PUBACK
            if self.loop.time() > deadline:
                logger.warning("%s: closing with messages still queued", self.name)
                break
            await asyncio.sleep(0.05)
        self._closing = True
        self.client.disconnect()
        self._misc.cancel()

    def _subscribe(self, topics: list[str]) -> asyncio.Future[None]:
        result, mid = self.client.subscribe([(topic, 0) for topic in topics])
        if result != mqtt.MQTT_ERR_SUCCESS:
            raise ConnectionError(f"SUBSCRIBE failed: {mqtt.error_string(result)}")
        ack: asyncio.Future[None] = self.loop.create_future()
        self._pending_subacks[mid] = ack
        return ack

    async def _keepalive(self) -> None:
        while True:
            await asyncio.sleep(MISC_PERIOD)
            self.client.loop_misc()

    # --- paho callbacks (called from loop_read/loop_write, i.e. on the event loop) ----------------------

    def _on_socket_open(self, client: mqtt.Client, userdata: Any, sock: Any) -> None:
        """Read on the event loop; write each message at once (no Nagle wait behind an unacked one)."""
        if isinstance(sock, socket.socket):
            sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        self.loop.add_reader(sock, read_available, client)

    def _on_connect(self, client: mqtt.Client, userdata: Any, flags: Any, reason: Any, props: Any) -> None:
        if reason.is_failure:
            logger.error("broker refused the connection: %s", reason)
            return
        if self._connected.is_set():  # a reconnect: the broker forgot our subscriptions
            for i in range(0, len(self.topics), TOPICS_PER_SUBSCRIBE):
                self._subscribe(self.topics[i : i + TOPICS_PER_SUBSCRIBE])
        self._connected.set()

    def _on_disconnect(self, client: mqtt.Client, userdata: Any, flags: Any, reason: Any, props: Any) -> None:
        if self._closing:
            return
        self.disconnects += 1
        logger.error("MQTT connection lost (%s), reconnecting", reason)
        self.loop.call_later(RECONNECT_DELAY, self._reconnect)

    def _reconnect(self) -> None:
        try:
            self.client.reconnect()
        except OSError as exc:
            logger.error("reconnect failed (%s), retrying", exc)
            self.loop.call_later(RECONNECT_DELAY, self._reconnect)

    def _on_subscribe(self, client: mqtt.Client, userdata: Any, mid: int, codes: Any, props: Any) -> None:
        ack = self._pending_subacks.pop(mid, None)
        if ack is None or ack.done():
            return
        if any(code.is_failure for code in codes):
            ack.set_exception(ConnectionError(f"broker refused a subscription: {codes}"))
        else:
            ack.set_result(None)

    def _on_message(self, client: mqtt.Client, userdata: Any, message: mqtt.MQTTMessage) -> None:
        self._on_message_handler(message.topic, message.payload)

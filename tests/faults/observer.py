"""The fault suite's MQTT observer: every order, instant action and state on the private broker, with
arrival times, and the windows in which it was not listening (it reconnects after broker restarts)."""

from __future__ import annotations

import threading
import time
import uuid
from typing import Any

import paho.mqtt.client as mqtt

from tests.faults.checks import Window, WireMessage

TOPICS = [("+/+/+/+/order", 0), ("+/+/+/+/instantActions", 0), ("+/+/+/+/state", 0)]


class Observer:
    """A paho client of its own on the stack's broker. `messages` are in arrival order (paho calls
    `on_message` from its one network thread); `blind` holds the intervals from a lost connection to the
    moment the broker confirmed the subscriptions again."""

    def __init__(self, port: int, host: str = "127.0.0.1") -> None:
        self.messages: list[WireMessage] = []
        self._poses: dict[str, tuple[float, float, float]] = {}  # serial -> the latest state's x, y, theta
        self._blind: list[Window] = []
        self._lost_at: float | None = None
        self._closing = False
        self._lock = threading.Lock()
        self._subscribed = threading.Event()
        self.started_at = time.time()
        self.client = mqtt.Client(
            mqtt.CallbackAPIVersion.VERSION2,
            client_id=f"fault-observer-{uuid.uuid4().hex[:8]}",
            reconnect_on_failure=True,
        )
        self.client.reconnect_delay_set(min_delay=0.1, max_delay=0.5)
        self.client.on_connect = self._on_connect
        self.client.on_subscribe = self._on_subscribe
        self.client.on_disconnect = self._on_disconnect
        self.client.on_message = self._on_message
        self.client.connect_async(host, port, keepalive=10)
        self.client.loop_start()

    def wait_subscribed(self, timeout: float = 30) -> None:
        if not self._subscribed.wait(timeout):
            raise RuntimeError("the MQTT observer could not subscribe on the stack's broker")

    def _on_connect(self, client: mqtt.Client, userdata: Any, flags: Any, reason: Any, props: Any) -> None:
        if not reason.is_failure:
            client.subscribe(TOPICS)

    def _on_subscribe(self, client: mqtt.Client, userdata: Any, mid: int, reasons: Any, props: Any) -> None:
        now = time.time()
        with self._lock:
            if self._lost_at is not None:
                self._blind.append(Window(self._lost_at, now, "observer reconnecting"))
                self._lost_at = None
        self._subscribed.set()

    def _on_disconnect(self, client: mqtt.Client, userdata: Any, flags: Any, reason: Any, props: Any) -> None:
        with self._lock:
            if self._lost_at is None and not self._closing:
                self._lost_at = time.time()

    def _on_message(self, client: mqtt.Client, userdata: Any, message: mqtt.MQTTMessage) -> None:
        record = WireMessage.from_payload(time.time(), message.topic, message.payload)
        position = (record.data or {}).get("agvPosition") if record.kind == "state" else None
        with self._lock:
            self.messages.append(record)
            if isinstance(position, dict):
                self._poses[record.serial] = (position["x"], position["y"], position.get("theta", 0.0))

    def blind(self) -> list[Window]:
        """The intervals without a subscription so far (one still open ends now)."""
        with self._lock:
            open_window = (
                [Window(self._lost_at, time.time(), "observer reconnecting")] if self._lost_at else []
            )
            return [*self._blind, *open_window]

    def poses(self) -> dict[str, tuple[float, float, float]]:
        """Where each robot's latest state put it: a restarted robot starts there (fault kind "simulator")."""
        with self._lock:
            return dict(self._poses)

    def snapshot(self) -> list[WireMessage]:
        with self._lock:
            return list(self.messages)

    def close(self) -> None:
        with self._lock:
            self._closing = True
        self.client.disconnect()
        self.client.loop_stop()

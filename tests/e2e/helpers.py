"""Small helpers for end-to-end tests: the public REST API, waiting, and recording status sequences."""

from __future__ import annotations

import threading
import time
import uuid
from collections import defaultdict
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import Any

import orjson
import paho.mqtt.client as mqtt
from django.conf import settings
from rest_framework.test import APIClient

from tests.waiting import wait_for

DONE = {"COMPLETED", "FAILED", "CANCELED"}


def order_contents(orders: list[dict[str, Any]]) -> dict[tuple[str, int], set[bytes]]:
    """(orderId, orderUpdateId) -> the contents sent under it, header aside (a resend repeats one)."""
    contents: dict[tuple[str, int], set[bytes]] = defaultdict(set)
    for order in orders:
        body = {key: value for key, value in order.items() if key not in ("headerId", "timestamp")}
        contents[order["orderId"], order["orderUpdateId"]].add(
            orjson.dumps(body, option=orjson.OPT_SORT_KEYS)
        )
    return contents


def route(name: str, *points: tuple[float, float], parent: str = "root", **extra: Any) -> dict[str, Any]:
    waypoints = [{"x": x, "y": y, "theta": 0, "map_id": "map", **extra} for x, y in points]
    return {"name": name, "parent": parent, "route": {"waypoints": waypoints}}


def action(
    name: str, action_type: str = "dummy_action", parent: str = "root", **params: Any
) -> dict[str, Any]:
    return {
        "name": name,
        "parent": parent,
        "action": {"action_type": action_type, "action_parameters": params},
    }


def composite(name: str, kind: str, parent: str = "root") -> dict[str, Any]:
    return {"name": name, "parent": parent, kind: {}}


def create_robot(api: APIClient, name: str, **spec: Any) -> dict[str, Any]:
    response = api.post("/robot", {"name": name, **spec}, format="json")
    assert response.status_code == 200, response.content
    return response.json()


def post_mission(
    api: APIClient, name: str, robot: str, tree: list[dict[str, Any]], **spec: Any
) -> dict[str, Any]:
    body = {"name": name, "robot": robot, "mission_tree": tree, "timeout": 120, **spec}
    response = api.post("/mission", body, format="json")
    assert response.status_code == 200, response.content
    return response.json()


def get(api: APIClient, kind: str, name: str) -> dict[str, Any]:
    response = api.get(f"/{kind}/{name}")
    assert response.status_code == 200, response.content
    return response.json()


def mission_state(api: APIClient, name: str) -> str:
    return get(api, "mission", name)["status"]["state"]


def wait_mission(
    api: APIClient, name: str, states: set[str] | None = None, timeout: float = 60
) -> dict[str, Any]:
    """The mission once it is in one of `states` (default: any finished state)."""
    wanted = states or DONE
    return wait_mission_where(
        api,
        name,
        lambda status: status["state"] in wanted,
        timeout,
        f"mission {name} to reach {sorted(wanted)}",
    )


def wait_mission_where(
    api: APIClient,
    name: str,
    predicate: Callable[[dict[str, Any]], bool],
    timeout: float = 60,
    message: str = "",
) -> dict[str, Any]:
    """The mission once `predicate` holds for its status."""

    def check() -> dict[str, Any] | None:
        mission = get(api, "mission", name)
        return mission if predicate(mission["status"]) else None

    return wait_for(check, timeout=timeout, message=message or f"mission {name}")


def wait_robot(api: APIClient, name: str, **expected: Any) -> dict[str, Any]:
    def matches() -> dict[str, Any] | None:
        robot = get(api, "robot", name)
        return robot if all(robot["status"].get(k) == v for k, v in expected.items()) else None

    return wait_for(matches, message=f"robot {name} status {expected}")


class StatusRecorder:
    """Polls a mission and keeps each distinct (state, current_node) in order, to check status sequences."""

    def __init__(self, api: APIClient, name: str, period: float = 0.02) -> None:
        self.api, self.name, self.period = api, name, period
        self.sequence: list[tuple[str, int]] = []
        self.snapshots: list[dict[str, Any]] = []
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)
        self._thread.start()

    def _run(self) -> None:
        from django.db import connection

        try:
            while not self._stop.is_set():
                response = self.api.get(f"/mission/{self.name}")
                if response.status_code == 200:
                    status = response.json()["status"]
                    key = (status["state"], status["current_node"])
                    if not self.sequence or self.sequence[-1] != key:
                        self.sequence.append(key)
                        self.snapshots.append(status)
                    if status["state"] in DONE:
                        return
                time.sleep(self.period)
        finally:
            connection.close()

    def stop(self) -> list[tuple[str, int]]:
        """The sequence once the recorder has seen the mission finish (or given up)."""
        self._thread.join(timeout=10)
        self._stop.set()
        self._thread.join(timeout=10)
        return self.sequence


class Tap:
    """A robot's orders, instant actions and states as the broker passed them on, in that order."""

    def __init__(self, serial: str) -> None:
        self.messages: list[tuple[str, dict[str, Any]]] = []
        self._lock = threading.Lock()
        ready = threading.Event()
        self.client = mqtt.Client(mqtt.CallbackAPIVersion.VERSION2, client_id=f"tap-{uuid.uuid4().hex[:8]}")
        topics = [(f"+/+/+/{serial}/{topic}", 0) for topic in ("order", "instantActions", "state")]
        self.client.on_connect = lambda client, *args: client.subscribe(topics)
        self.client.on_subscribe = lambda *args: ready.set()
        self.client.on_message = self._on_message
        self.client.connect(settings.MQTT_HOST, settings.MQTT_PORT)
        self.client.loop_start()
        assert ready.wait(10)

    def _on_message(self, client: mqtt.Client, userdata: Any, message: mqtt.MQTTMessage) -> None:
        with self._lock:
            self.messages.append((message.topic.rsplit("/", 1)[-1], orjson.loads(message.payload)))

    def of(self, kind: str) -> list[dict[str, Any]]:
        with self._lock:
            return [data for topic, data in self.messages if topic == kind]

    def seen(self) -> list[tuple[str, dict[str, Any]]]:
        with self._lock:
            return list(self.messages)

    def close(self) -> None:
        self.client.loop_stop()
        self.client.disconnect()


@contextmanager
def tapped(serial: str) -> Iterator[Tap]:
    tap = Tap(serial)
    try:
        yield tap
    finally:
        tap.close()

"""``python -m simulator.monitor``: watch a fleet's traffic and say whether every robot keeps up.

Counts, per robot, ``state`` messages and the longest silence between two of them, checks that
``headerId`` never skips (nothing lost), and how many robots' ``connection`` says ONLINE. Used for the
1,000-robot measurement in README.md.
"""

from __future__ import annotations

import argparse
import statistics
import threading
import time
from dataclasses import dataclass, field

import orjson
import paho.mqtt.client as mqtt
from paho.mqtt.enums import CallbackAPIVersion

from simulator.cli import add_broker_arguments, shared_broker_settings
from simulator.runner import BrokerSettings
from vda5050.topics import SINGLE_LEVEL_WILDCARD, Topic


@dataclass
class RobotTraffic:
    states: int = 0
    last_at: float | None = None
    longest_gap: float = 0.0
    last_header_id: int | None = None
    skipped_header_ids: int = 0


@dataclass
class FleetTraffic:
    robots: dict[str, RobotTraffic] = field(default_factory=dict)
    connection_states: dict[str, str] = field(default_factory=dict)
    lock: threading.Lock = field(default_factory=threading.Lock)

    def state_received(self, serial: str, header_id: int, at: float) -> None:
        with self.lock:
            traffic = self.robots.setdefault(serial, RobotTraffic())
            traffic.states += 1
            if traffic.last_at is not None:
                traffic.longest_gap = max(traffic.longest_gap, at - traffic.last_at)
            traffic.last_at = at
            if traffic.last_header_id is not None and header_id != traffic.last_header_id + 1:
                traffic.skipped_header_ids += max(0, header_id - traffic.last_header_id - 1)
            traffic.last_header_id = header_id

    def report(self, window: float) -> str:
        with self.lock:
            online = sum(state == "ONLINE" for state in self.connection_states.values())
            rates = [traffic.states / window for traffic in self.robots.values()]
            gaps = [traffic.longest_gap for traffic in self.robots.values()]
            skipped = sum(traffic.skipped_header_ids for traffic in self.robots.values())
        if not rates:
            return f"online {online}, no state messages"
        return (
            f"online {online}; {len(rates)} robots publishing state:"
            f" {min(rates):.2f}/{statistics.mean(rates):.2f}/{max(rates):.2f} per s (min/mean/max),"
            f" longest silence {max(gaps):.2f} s, skipped headerIds {skipped}"
        )


def watch(broker: BrokerSettings, interface_name: str, seconds: float) -> FleetTraffic:
    traffic = FleetTraffic()

    def on_message(client: mqtt.Client, userdata: object, message: mqtt.MQTTMessage) -> None:
        serial, kind = message.topic.split("/")[-2:]
        if not message.payload:
            return
        body = orjson.loads(message.payload)
        if kind == Topic.STATE:
            traffic.state_received(serial, body["headerId"], time.monotonic())
        elif kind == Topic.CONNECTION:
            with traffic.lock:
                traffic.connection_states[serial] = body["connectionState"]

    client = mqtt.Client(CallbackAPIVersion.VERSION2, transport=broker.transport)
    if broker.transport == "websockets":
        client.ws_set_options(path=broker.ws_path)
    if broker.username is not None:  # with the shipped ACL, the dispatcher's login reads every robot
        client.username_pw_set(broker.username, broker.password)
    tls = broker.tls_context()
    if tls is not None:
        client.tls_set_context(tls)
    client.on_message = on_message
    client.connect(broker.host, broker.port)
    levels = (interface_name, SINGLE_LEVEL_WILDCARD, SINGLE_LEVEL_WILDCARD, SINGLE_LEVEL_WILDCARD)
    client.subscribe([("/".join((*levels, topic)), 0) for topic in (Topic.STATE, Topic.CONNECTION)])
    client.loop_start()
    time.sleep(seconds)
    client.disconnect()
    client.loop_stop()
    return traffic


def main() -> None:
    parser = argparse.ArgumentParser(prog="python -m simulator.monitor", description=__doc__)
    add_broker_arguments(parser)
    parser.add_argument("--interface_name", default="+", help="first topic level to watch (default: all)")
    parser.add_argument("--seconds", type=float, default=60.0)
    args = parser.parse_args()
    try:
        broker = shared_broker_settings(args)
    except ValueError as error:
        parser.error(str(error))
    traffic = watch(broker, args.interface_name, args.seconds)
    print(traffic.report(args.seconds))


if __name__ == "__main__":
    main()

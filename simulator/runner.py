"""The MQTT side: one paho client per robot, all driven by one asyncio event loop.

paho's external-loop hooks (on_socket_open/close, on_socket_register/unregister_write) put every
client's socket into the asyncio selector, so a thousand robots need no thread each: one task ticks
all robot models in a batch, one keeps every client's keep-alive, and clients connect in waves so the
broker's listen backlog is never flooded.
"""

from __future__ import annotations

import asyncio
import logging
import resource
import ssl
import time
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, field
from typing import Any

import paho.mqtt.client as mqtt
from paho.mqtt.enums import CallbackAPIVersion, MQTTProtocolVersion

from simulator.config import Credentials
from simulator.outbox import Publication
from simulator.robot import SimulatedRobot
from vda5050.topics import Topic

logger = logging.getLogger(__name__)

CONNECT_WAVE = 50  # clients connecting at once; mosquitto's default listen backlog is 100
CONNECT_WAVE_TIMEOUT = 5.0  # s to wait for a wave's CONNACKs before starting the next wave
KEEPALIVE = 15  # s, as the document suggests
MISC_PERIOD = 1.0  # s between keep-alive checks (paho's loop_misc)
RECONNECT_DELAY_MIN = 1.0  # s
RECONNECT_DELAY_MAX = 30.0  # s
SHUTDOWN_TIMEOUT = 5.0  # s to wait for OFFLINE messages and DISCONNECTs to leave
FDS_PER_ROBOT = 2  # the client socket, plus slack for the selector and logging


@dataclass(frozen=True)
class BrokerSettings:
    host: str = "localhost"
    port: int = 1883
    transport: str = "tcp"  # or "websockets"
    ws_path: str = "/mqtt"
    username: str | None = None
    password: str | None = None
    credentials: Mapping[str, Credentials] = field(default_factory=dict)  # serial number -> its own login
    tls: bool = False
    ca_file: str | None = None  # None: the CAs the system trusts
    check_hostname: bool = True
    cert_file: str | None = None  # a client certificate, for brokers that require one
    key_file: str | None = None

    def login(self, serial_number: str) -> Credentials | None:
        """The robot's own credentials if it has some, else the shared ones (if any)."""
        own = self.credentials.get(serial_number)
        if own is not None:
            return own
        return None if self.username is None else Credentials(self.username, self.password)

    def tls_context(self) -> ssl.SSLContext | None:
        """One context for every client of the process (None without TLS): the broker must show a
        certificate from ``ca_file`` issued for ``host``, unless host names are not checked."""
        if not self.tls:
            return None
        context = ssl.create_default_context(cafile=self.ca_file)
        context.check_hostname = self.check_hostname
        if self.cert_file:
            context.load_cert_chain(self.cert_file, self.key_file)
        return context


@dataclass
class TickStats:
    """How well the tick loop keeps up (reported at shutdown; the benchmark's main figure)."""

    ticks: int = 0
    late_ticks: int = 0  # a tick that started more than one tick period after it was due
    max_lag: float = 0.0  # s
    busy_time: float = 0.0  # s spent inside ticks


class RobotLink:
    """One robot's MQTT client, its socket hooked into the event loop."""

    def __init__(self, robot: SimulatedRobot, broker: BrokerSettings, fleet: Fleet) -> None:
        self.robot = robot
        self.broker = broker
        self.fleet = fleet
        self.online = False
        self.closed = asyncio.Event()
        self.closed.set()
        self._reconnect_delay = RECONNECT_DELAY_MIN
        address = robot.topic_address
        client_id = f"sim-{address.interface_name}-{address.manufacturer}-{address.serial_number}"
        client = mqtt.Client(
            CallbackAPIVersion.VERSION2,
            client_id=client_id,
            protocol=MQTTProtocolVersion.MQTTv311,
            transport=broker.transport,
        )
        if broker.transport == "websockets":
            client.ws_set_options(path=broker.ws_path)
        if fleet.tls_context is not None:
            client.tls_set_context(fleet.tls_context)
        login = broker.login(address.serial_number)
        if login is not None:
            client.username_pw_set(login.username, login.password)
        client.on_connect = self._on_connect
        client.on_disconnect = self._on_disconnect
        client.on_message = self._on_message
        client.on_socket_open = self._on_socket_open
        client.on_socket_close = self._on_socket_close
        client.on_socket_register_write = self._on_socket_register_write
        client.on_socket_unregister_write = self._on_socket_unregister_write
        self.client = client

    def connect(self) -> None:
        """Start connecting (the TCP connect itself blocks briefly); failures retry with backoff."""
        will = self.robot.last_will(self.fleet.clock())
        self.client.will_set(will.topic, will.payload, will.qos, will.retain)
        try:
            if self.client.host:
                self.client.reconnect()
            else:
                self.client.connect(self.broker.host, self.broker.port, keepalive=KEEPALIVE)
        except OSError as exc:
            logger.warning(
                "%s: cannot connect to %s:%s (%s)", self.name, self.broker.host, self.broker.port, exc
            )
            self._schedule_reconnect()
            return
        self.closed.clear()

    def publish(self, messages: Iterable[Publication]) -> None:
        if not self.online:
            return
        for message in messages:
            self.client.publish(message.topic, message.payload, message.qos, message.retain)

    def go_offline(self) -> None:
        """Clean shutdown: OFFLINE (retained), then DISCONNECT, so the broker drops the last will."""
        if self.online:
            self.publish([self.robot.going_offline(self.fleet.clock())])
            self.online = False
        self.client.disconnect()

    @property
    def name(self) -> str:
        return self.robot.config.name

    # --- paho callbacks ----------------------------------------------------------------------------

    def _on_connect(
        self, client: mqtt.Client, userdata: Any, flags: Any, reason_code: Any, properties: Any
    ) -> None:
        if reason_code.is_failure:
            logger.warning("%s: broker refused the connection: %s", self.name, reason_code)
            return
        self._reconnect_delay = RECONNECT_DELAY_MIN
        client.subscribe([(topic, 0) for topic in self.robot.subscriptions()])
        self.online = True
        self.publish(self.robot.connected(self.fleet.clock()))
        self.fleet.connack_received()

    def _on_disconnect(
        self, client: mqtt.Client, userdata: Any, flags: Any, reason_code: Any, properties: Any
    ) -> None:
        self.online = False
        if not self.fleet.stopping:
            logger.warning("%s: connection lost (%s), reconnecting", self.name, reason_code)
            self._schedule_reconnect()

    def _on_message(self, client: mqtt.Client, userdata: Any, message: mqtt.MQTTMessage) -> None:
        kind = Topic(message.topic.rsplit("/", 1)[-1])
        self.publish(self.robot.receive(kind, message.payload, self.fleet.clock()))

    def _on_socket_open(self, client: mqtt.Client, userdata: Any, sock: Any) -> None:
        self.closed.clear()
        self.fleet.loop.add_reader(sock, read_available, client)

    def _on_socket_close(self, client: mqtt.Client, userdata: Any, sock: Any) -> None:
        self.fleet.loop.remove_reader(sock)
        self.closed.set()

    def _on_socket_register_write(self, client: mqtt.Client, userdata: Any, sock: Any) -> None:
        self.fleet.loop.add_writer(sock, client.loop_write)

    def _on_socket_unregister_write(self, client: mqtt.Client, userdata: Any, sock: Any) -> None:
        self.fleet.loop.remove_writer(sock)

    def _schedule_reconnect(self) -> None:
        self.closed.set()
        self.fleet.loop.call_later(self._reconnect_delay, self._reconnect)
        self._reconnect_delay = min(self._reconnect_delay * 2, RECONNECT_DELAY_MAX)

    def _reconnect(self) -> None:
        if not self.fleet.stopping and not self.online:
            self.connect()


class Fleet:
    """Every robot of this process, their clients and the loops that drive them."""

    def __init__(
        self,
        robots: list[SimulatedRobot],
        broker: BrokerSettings,
        tick_period: float,
        clock: Callable[[], float] = time.time,
    ) -> None:
        self.robots = robots
        self.broker = broker
        self.tick_period = tick_period
        self.clock = clock
        self.stopping = False
        self.stats = TickStats()
        self.loop = asyncio.get_running_loop()
        self._connacks = asyncio.Event()
        self.tls_context = broker.tls_context()
        self.links = [RobotLink(robot, broker, self) for robot in robots]

    async def run(self, stop: asyncio.Event) -> None:
        """Connect, tick until ``stop`` is set, then go offline cleanly."""
        raise_file_limit(len(self.links))
        misc = asyncio.create_task(self._keepalive_loop())
        ticks = asyncio.create_task(self._tick_loop())
        connecting = asyncio.create_task(self._connect_in_waves())
        await stop.wait()
        self.stopping = True
        for task in (connecting, ticks, misc):
            task.cancel()
        await self._shut_down()
        logger.info(
            "stopped: %d ticks, %d late, max lag %.3f s, %.1f%% of the time ticking",
            self.stats.ticks,
            self.stats.late_ticks,
            self.stats.max_lag,
            100 * self.stats.busy_time / max(self.stats.ticks * self.tick_period, 1e-9),
        )

    def connack_received(self) -> None:
        self._connacks.set()

    @property
    def online_count(self) -> int:
        return sum(link.online for link in self.links)

    async def _connect_in_waves(self) -> None:
        for start in range(0, len(self.links), CONNECT_WAVE):
            wave = self.links[start : start + CONNECT_WAVE]
            for link in wave:
                link.connect()
            deadline = self.loop.time() + CONNECT_WAVE_TIMEOUT
            while not all(link.online for link in wave) and self.loop.time() < deadline:
                self._connacks.clear()
                try:
                    await asyncio.wait_for(self._connacks.wait(), deadline - self.loop.time())
                except TimeoutError:
                    break
        logger.info("%d of %d robots online", self.online_count, len(self.links))

    async def _tick_loop(self) -> None:
        """Tick every robot each period; if a batch overruns, the next one starts at once."""
        due = self.loop.time()
        while True:
            started = self.loop.time()
            lag = started - due
            self.stats.max_lag = max(self.stats.max_lag, lag)
            if lag > self.tick_period:
                self.stats.late_ticks += 1
                due = started
            now = self.clock()
            for link in self.links:
                if link.online:
                    link.publish(link.robot.tick(now))
                else:
                    link.robot.advance(now)
            self.stats.ticks += 1
            self.stats.busy_time += self.loop.time() - started
            due += self.tick_period
            await asyncio.sleep(max(0.0, due - self.loop.time()))

    async def _keepalive_loop(self) -> None:
        while True:
            await asyncio.sleep(MISC_PERIOD)
            for link in self.links:
                link.client.loop_misc()

    async def _shut_down(self) -> None:
        for link in self.links:
            link.go_offline()
        closing = [link.closed.wait() for link in self.links]
        try:
            await asyncio.wait_for(asyncio.gather(*closing), SHUTDOWN_TIMEOUT)
        except TimeoutError:
            logger.warning(
                "%d clients did not close in time", sum(not link.closed.is_set() for link in self.links)
            )


def read_available(client: mqtt.Client) -> None:
    """Read what the socket has. TLS decrypts a whole record at once: bytes of it that paho has not taken
    yet wait in the TLS layer, where the event loop's selector cannot see them, so read those too."""
    client.loop_read()
    while hasattr(sock := client.socket(), "pending") and sock.pending():  # as paho's own loop does
        client.loop_read()


def raise_file_limit(robot_count: int) -> None:
    """Each client needs a socket: lift the soft RLIMIT_NOFILE to the hard limit if needed."""
    needed = robot_count * FDS_PER_ROBOT + 64
    soft, hard = resource.getrlimit(resource.RLIMIT_NOFILE)
    if soft >= needed:
        return
    target = needed if hard == resource.RLIM_INFINITY else min(hard, needed)
    resource.setrlimit(resource.RLIMIT_NOFILE, (target, hard))
    if target < needed:
        logger.warning("open-file limit %d is below the %d that %d robots need", target, needed, robot_count)

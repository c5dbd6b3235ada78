"""How a simulated robot's messages go out: topics, header ids, QoS and retain flags, and when each is due.

A state goes out on every change of what it reports (``state_changed``) and otherwise every
``state_period``; a visualization every ``visualization_period``; the factsheet when asked for.
"""

from __future__ import annotations

from dataclasses import InitVar, dataclass, field
from datetime import UTC, datetime

import orjson

from simulator.config import RobotConfig, SimulationSettings
from simulator.factsheet import factsheet_content
from vda5050.codec import encode, header_for
from vda5050.models import AgvClass, ConnectionContent, ConnectionState, Content
from vda5050.topics import RobotAddress, Topic, topic_for
from vda5050.versions import MAJOR_3, major_of

STANDARD_AGV_CLASSES = frozenset(agv_class.value for agv_class in AgvClass)
PUBLISH_OPTIONS: dict[Topic, tuple[int, bool]] = {  # (QoS, retained) per the document
    Topic.STATE: (0, False),
    Topic.VISUALIZATION: (0, False),
    Topic.CONNECTION: (1, True),
    Topic.FACTSHEET: (0, True),
}


@dataclass(frozen=True)
class Publication:
    """One message to publish."""

    kind: Topic
    topic: str
    payload: bytes
    qos: int
    retain: bool


@dataclass(eq=False)
class Outbox:
    """The robot's side of publishing: builds each message and says which ones are due."""

    config: RobotConfig
    settings: SimulationSettings
    version: str
    address: RobotAddress  # who the robot is in headers
    topic_address: RobotAddress  # its topic levels
    now: InitVar[float]
    state_changed: bool = field(default=True, init=False)  # the next state reports a change: out at once
    factsheet_requested: bool = field(default=False, init=False)
    _header_ids: dict[Topic, int] = field(default_factory=dict, init=False)
    _state_due: float = field(init=False)
    _visualization_due: float = field(init=False)

    def __post_init__(self, now: float) -> None:
        self._state_due = now
        self._visualization_due = now

    def topic(self, kind: Topic) -> str:
        return topic_for(self.topic_address, kind)

    def factsheet_due(self) -> bool:
        due = self.factsheet_requested
        self.factsheet_requested = False
        return due

    def state_due(self, now: float) -> bool:
        """On a change or every state_period (half a tick early, so it does not slip a tick)."""
        if self.state_changed or now >= self._state_due - self.settings.tick_period / 2:
            self.state_changed = False
            self._state_due = now + self.settings.state_period
            return True
        return False

    def visualization_due(self, now: float) -> bool:
        period = self.settings.visualization_period
        if period > 0 and now >= self._visualization_due - self.settings.tick_period / 2:
            self._visualization_due = now + period
            return True
        return False

    def last_state_header_id(self) -> int:
        """The headerId of the last state sent (3.0's visualization refers to it)."""
        return max(self._header_ids.get(Topic.STATE, 0) - 1, 0)

    def message(self, kind: Topic, content: Content, now: float) -> Publication:
        header_id = self._header_ids.get(kind, 0)
        self._header_ids[kind] = header_id + 1
        header = header_for(self.address, header_id=header_id, at=datetime.fromtimestamp(now, UTC))
        qos, retain = PUBLISH_OPTIONS[kind]
        return Publication(kind, self.topic(kind), encode(content, header), qos, retain)

    def connection(self, connection_state: ConnectionState, now: float) -> Publication:
        return self.message(Topic.CONNECTION, ConnectionContent(connection_state=connection_state), now)

    def factsheet(self, now: float) -> Publication:
        message = self.message(
            Topic.FACTSHEET, factsheet_content(self.config, self.settings, self.version), now
        )
        agv_class = self.config.robot_type.value
        if agv_class in STANDARD_AGV_CLASSES or major_of(self.version) >= MAJOR_3:  # 3.0: free text
            return message
        # Isaac's MANIPULATOR/HUMANOID are outside the 2.x enum; publish them as Isaac's robots do.
        body = orjson.loads(message.payload)
        body["typeSpecification"]["agvClass"] = agv_class
        return Publication(message.kind, message.topic, orjson.dumps(body), message.qos, message.retain)

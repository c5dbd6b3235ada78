"""The bridge's status writer: the robots' reported columns (their status: pose, battery, errors, ...)
kept in memory as states arrive, and written to PostgreSQL by a thread of its own, coalesced.

The database sees one batched UPDATE per flush period (`FLEET_BRIDGE_FLUSH_SECONDS`) for the robots whose
status changed; with it go the orders robots took without needing a step (`dispatch.held.takes_order_only`),
so that the sweep does not send them again.
"""

import logging
import queue
import threading
import time
import zlib
from dataclasses import dataclass, field
from datetime import UTC, datetime
from typing import Any

import orjson
from django.conf import settings
from django.db import DatabaseError, connections

from kit.db import drop_broken_connections, jsonb
from missions.services import mission_orders_accepted
from robots.status import robot_status_write
from vda5050.codec import nested_deeper
from vda5050.maps import reported_maps
from vda5050.models import State
from vda5050.zones import reported_zone_sets
from workers import metrics, tuning
from workers.bridge.gate import holds_nul

logger = logging.getLogger(__name__)

STATUS_COLUMNS = (
    "battery_level",
    "operating_mode",
    "pose_x",
    "pose_y",
    "pose_theta",
    "pose_map_id",
    "position_initialized",
    "hardware_version",
    "errors",
    "info_messages",
    "maps",
    "zone_sets",
)
JSON_COLUMNS = frozenset({"hardware_version", "errors", "info_messages", "maps", "zone_sets"})


@dataclass
class RobotStatus:
    """A robot's status as last written to PostgreSQL, and what is waiting to be written."""

    last_state_at_period: float  # s between writes of an unchanged status's newer last_state_at
    heard_at: float  # monotonic s of the robot's last message
    written: dict[str, Any] = field(default_factory=dict)
    pending: dict[str, Any] = field(default_factory=dict)
    written_at: float = 0.0
    last_state_at: datetime | None = None
    last_state_at_written: datetime | None = None


@dataclass
class Flush:
    """One status write: robot -> (orderId, orderUpdateId) it took, and columns -> rows of values + name."""

    orders: dict[str, tuple[str, int]]
    statuses: dict[tuple[str, ...], list[tuple[Any, ...]]] = field(default_factory=dict)


class StatusWriter:
    """The robots' statuses and taken orders, collected by the bridge's processing thread (`remember_state`,
    `pending`, `remember_order_taken`) and handed to the writer thread once a flush is due
    (`hand_off_if_due`)."""

    def __init__(self) -> None:
        self.statuses: dict[str, RobotStatus] = {}
        self.accepted_orders: dict[str, tuple[str, int]] = {}  # robot -> (orderId, orderUpdateId) it took
        self._last_flush = time.monotonic()
        self._writes: queue.SimpleQueue[Flush | None] = queue.SimpleQueue()  # to the writer; None: end
        self._thread: threading.Thread | None = None
        self._written = threading.Event()  # no flush is being written
        self._written.set()
        self._skipped: queue.SimpleQueue[str] = queue.SimpleQueue()  # robots whose status a write skipped

    # --- processing thread ---

    def remember_state(self, name: str, state: State) -> None:
        """Take the robot's status from its state, to be written with the next flush if it changed."""
        status = self._status(name)
        position = state.agv_position
        values: dict[str, Any] = {
            "battery_level": state.battery_state.battery_charge,
            "operating_mode": state.operating_mode.value,
            "hardware_version": {"manufacturer": state.manufacturer, "serial_number": state.serial_number},
            "errors": {
                error.error_type: {
                    "level": error.error_level.value,
                    "description": error.error_description,
                    "references": {r.reference_key: r.reference_value for r in error.error_references or ()},
                }
                for error in state.errors
            },
            "info_messages": _user_info(state),
            "maps": reported_maps(state),
            "zone_sets": reported_zone_sets(state),
        }
        if position is not None:
            values.update(
                pose_x=position.x,
                pose_y=position.y,
                pose_theta=position.theta,
                pose_map_id=position.map_id,
                position_initialized=position.position_initialized,
            )
        status.pending.update(values)
        status.last_state_at = datetime.now(UTC)

    def pending(self, name: str) -> dict[str, Any]:
        """The robot's columns waiting for the next flush (it is heard from now)."""
        return self._status(name).pending

    def remember_order_taken(self, name: str, order: tuple[str, int]) -> None:
        """The robot took this (orderId, orderUpdateId) and needs no step for it: the next flush marks it."""
        self.accepted_orders[name] = order

    def hand_off_if_due(self) -> None:
        """When a flush is due and the last one is written, hand the next to the writer thread (`start`;
        without it flushes wait here)."""
        due = time.monotonic() - self._last_flush >= settings.BRIDGE_STATUS_FLUSH_SECONDS
        if due and self._written.is_set():
            self._written.clear()
            self._writes.put(self._collect())

    def flush(self) -> None:
        """Write the orders robots took and the robots' changed statuses now, in this thread."""
        self._write(self._collect())

    def _status(self, name: str) -> RobotStatus:
        """The robot's status, now heard from."""
        status = self.statuses.get(name)
        if status is None:
            # A period of its own, from 1/2 to 1 LAST_STATE_AT_PERIOD: robots that came online together (a
            # fleet starting) would otherwise rewrite their unchanged statuses together for ever after.
            spread = 0.5 + (zlib.crc32(name.encode()) % 1024) / 2048
            status = self.statuses[name] = RobotStatus(tuning.LAST_STATE_AT_PERIOD * spread, time.monotonic())
        else:
            status.heard_at = time.monotonic()
        return status

    def _collect(self) -> Flush:
        """Take what the next write holds: the orders robots took, and each robot's status that changed or
        whose newer last_state_at is due; unchanged robots cost nothing, and robots long silent are
        forgotten (a deleted one would stay for ever)."""
        self._restore_skipped()
        now = time.monotonic()
        flush = Flush(orders=self.accepted_orders)
        self.accepted_orders = {}
        silent = []
        for name, status in self.statuses.items():
            changed = {
                key: value for key, value in status.pending.items() if status.written.get(key) != value
            }
            due = (
                status.last_state_at != status.last_state_at_written
                and now - status.written_at >= status.last_state_at_period
            )
            if not changed and not due:
                if now - status.heard_at >= tuning.FORGET_STATUS_SECONDS:
                    silent.append(name)
                continue
            status.written.update(status.pending)
            status.pending = {}
            status.written_at = now
            status.last_state_at_written = status.last_state_at
            columns = tuple(column for column in STATUS_COLUMNS if column in status.written)
            values = [jsonb(status.written[c]) if c in JSON_COLUMNS else status.written[c] for c in columns]
            if status.last_state_at is not None:  # a robot only seen on visualization keeps its time
                columns += ("last_state_at",)
                values.append(status.last_state_at)
            flush.statuses.setdefault(columns, []).append((*values, name))
        for name in silent:
            del self.statuses[name]
        self._last_flush = now
        return flush

    def _restore_skipped(self) -> None:
        """What the last write skipped is pending again, under what changed since."""
        while True:
            try:
                name = self._skipped.get_nowait()
            except queue.Empty:
                return
            status = self.statuses.get(name)
            if status is not None:
                status.pending = {**status.written, **status.pending}
                status.written, status.written_at, status.last_state_at_written = {}, 0.0, None

    # --- writer thread ---

    def start(self) -> None:
        """The thread that writes the flushes `hand_off_if_due` collects, so that the processing thread goes
        on handling states while a flush waits for PostgreSQL (it stopped them for every write)."""
        self._thread = threading.Thread(target=self._write_forever, name="status-writer", daemon=True)
        self._thread.start()

    def stop(self) -> None:
        """Let the writer thread write what it holds, and end with its database connection closed."""
        if self._thread is not None:
            self._writes.put(None)
            self._thread.join(timeout=30)
            self._thread = None

    def _write_forever(self) -> None:
        while (flush := self._writes.get()) is not None:
            try:
                drop_broken_connections()
                self._write(flush)
            except Exception:  # PostgreSQL away for a moment: statuses are rewritten once they change
                logger.exception("status flush failed")
            finally:
                self._written.set()
        connections.close_all()  # this thread's

    def _write(self, flush: Flush) -> None:
        """Each group of statuses in one statement; robots a step holds are skipped and rewritten in full by
        the next flush (`_restore_skipped`)."""
        if flush.orders:
            try:
                mission_orders_accepted(orders=flush.orders)
            except DatabaseError:  # harmless: the sweep's step finds the order taken instead of resending it
                logger.exception("acceptance of %d orders not written", len(flush.orders))
        for columns, rows in flush.statuses.items():
            try:
                skipped = robot_status_write(columns=columns, rows=rows)
            except DatabaseError:
                # One robot's value the database refuses (a NUL in an error text, say) must not hold back
                # the others': row by row, dropping what fails (rewritten once it changes).
                logger.warning("status flush of %d robots failed; writing them one by one", len(rows))
                skipped = set()
                for row in rows:
                    try:
                        skipped |= robot_status_write(columns=columns, rows=[row])
                    except DatabaseError:
                        logger.exception("status of robot %s not written", row[-1])
                        metrics.count(metrics.STATUS_WRITES_FAILED)
            for name in skipped:
                self._skipped.put(name)


def _user_info(state: State) -> Any:
    """The reference's `info_messages`: the JSON of the robot's `user_info` information entry; its text if
    that is no JSON PostgreSQL can store and the flush can serialize (NUL, nested too deep)."""
    for info in state.information or ():
        if info.info_type == "user_info" and info.info_description:
            try:
                value = orjson.loads(info.info_description)
            except orjson.JSONDecodeError:
                return info.info_description
            return info.info_description if nested_deeper(value) or holds_nul(value) else value
    return None

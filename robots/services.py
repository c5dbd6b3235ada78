"""Changes to robots. Each runs in one transaction, locks the row it changes, and wakes the dispatch engine
for the robot (after commit) so that the engine reacts to the change. What robots report is written by
`robots.status`."""

from collections.abc import Mapping
from typing import Any

from django.conf import settings
from django.db import IntegrityError, connection, transaction

from access.choices import WriteAction
from access.services import write_record
from dispatch.vocabulary import MissionState
from kit.api.errors import ObjectError, UsageError
from kit.api.names import object_name_for_create
from kit.api.rows import lock_row
from kit.wake import request_assignment, request_steps
from missions.models import Mission
from robots import livestate
from robots.choices import (
    TELEOP_ALLOWED_STATES,
    Lifecycle,
    MapAction,
    RobotState,
    SettingSource,
    TeleopAction,
)
from robots.models import InstantAction, Robot
from vda5050.errors import ProtocolError
from vda5050.maps import has_maps, map_action_parameters
from vda5050.models import ActionType
from vda5050.orders import new_action_id

FACTSHEET_REQUEST = ActionType.FACTSHEET_REQUEST.value
START_TELEOP = ActionType.START_TELEOP.value
STOP_TELEOP = ActionType.STOP_TELEOP.value

SPEC_KEYS = frozenset({"labels", "battery", "heartbeat_timeout", "switch_teleop", "vda5050"})


def robot_create(*, actor: str, name: str | None, prefix: str | None, spec: Mapping[str, Any]) -> Robot:
    """A new robot from a spec in the API's shape; omitted spec fields take their defaults. `actor` (who
    asks, as in every service here) is recorded with the write.

    Without a name the robot is named `<prefix>-<random id>` or a random id. A duplicate name raises the
    reference's ObjectError; a VDA 5050 identity another robot already uses raises a UsageError.
    """
    robot_name = object_name_for_create(name=name, prefix=prefix, what="Robot name")
    fields = _robot_spec_fields(spec, robot_name=robot_name, current=None)
    robot = Robot(name=robot_name, **fields)
    try:
        with transaction.atomic():
            robot.save(force_insert=True)
            write_record(actor=actor, action=WriteAction.ROBOT_CREATE, object_name=robot.name)
            if settings.DISPATCH_REQUEST_FACTSHEET:
                _queue_instant_action(robot, FACTSHEET_REQUEST)
            request_steps([robot.name])
            request_assignment()
    except IntegrityError as error:
        if Robot.objects.filter(name=robot_name).exists():
            raise ObjectError.exists("robot", robot_name) from error
        raise _identity_taken(fields) from error
    return robot


def robot_update_spec(*, actor: str, robot: Robot, spec: Mapping[str, Any]) -> Robot:
    """Replace the robot's whole spec (PUT): fields the spec omits go back to their defaults."""
    try:
        with transaction.atomic():
            locked = lock_row(robot)
            fields = _robot_spec_fields(spec, robot_name=robot.name, current=locked)
            for field, value in fields.items():
                setattr(locked, field, value)
            locked.save(update_fields=[*fields, "updated_at"])
            write_record(actor=actor, action=WriteAction.ROBOT_UPDATE, object_name=locked.name)
            request_steps([locked.name])
            request_assignment()  # its new labels may be what an unbound mission waits for
    except IntegrityError as error:
        raise _identity_taken(fields) from error
    return locked


def robot_delete(*, actor: str, robot: Robot) -> Robot | None:
    """Mark the robot PENDING_DELETE and remove it, at once unless a mission of it is RUNNING: then the
    engine fails that mission and removes the robot. Returns the robot while it remains, else None.

    Queued missions of the robot stay PENDING, as in the reference.
    """
    with transaction.atomic():
        locked = lock_row(robot)
        write_record(actor=actor, action=WriteAction.ROBOT_DELETE, object_name=locked.name)
        request_steps([locked.name])
        request_assignment()  # the missions assignment bound to it go back to the pool
        if Mission.objects.filter(robot=locked.name, state=MissionState.RUNNING).exists():
            locked.lifecycle = Lifecycle.PENDING_DELETE
            locked.save(update_fields=["lifecycle", "updated_at"])
            return locked
        name = locked.name
        robot_rows_delete(name)
        transaction.on_commit(lambda: livestate.forget(name))
    return None


# Plain SQL: the dispatch step deletes robots inside `kit.db.pipelined_transaction`, where the ORM's
# delete (a transaction block of its own) is not allowed. A robot's instant actions go with it; its
# missions stay (a mission names its robot, and fails with it).
ROBOT_DELETE_SQL = f"""
    WITH actions AS (DELETE FROM {InstantAction._meta.db_table} WHERE robot_id = %(name)s)
    DELETE FROM {Robot._meta.db_table} WHERE name = %(name)s
"""


def robot_rows_delete(name: str) -> None:
    """Delete the robot's rows; its live state is the caller's to forget once this is committed."""
    with connection.cursor() as cursor:
        cursor.execute(ROBOT_DELETE_SQL, {"name": name})


def robot_teleop(*, actor: str, robot: Robot, action: TeleopAction) -> Robot:
    """Ask for teleop to start or stop; the engine sends the robot startTeleop or stopTeleop."""
    with transaction.atomic():
        locked = lock_row(robot)
        if action == TeleopAction.START and locked.state not in TELEOP_ALLOWED_STATES:
            allowed = ", ".join(sorted(TELEOP_ALLOWED_STATES))
            raise UsageError(
                f"Robot {locked.name} is in {locked.state} and request cannot be satisfied: "
                f"teleop can only start from {allowed}."
            )
        locked.switch_teleop = action == TeleopAction.START
        locked.save(update_fields=["switch_teleop", "updated_at"])
        _queue_instant_action(locked, START_TELEOP if locked.switch_teleop else STOP_TELEOP)
        write_record(actor=actor, action=WriteAction.ROBOT_TELEOP, object_name=locked.name)
        request_steps([locked.name])
    return locked


def robot_charge(*, actor: str, robot: Robot) -> Robot:
    """Ask the robot to charge now, whatever its battery: the station plan (`missions.trips`) reserves it
    the nearest free charger and sends it there, or records why it waits (`charging_waiting_reason`).
    Refused for a robot that cannot: offline, charging already, or without startCharging in its factsheet.
    """
    with transaction.atomic():
        locked = lock_row(robot)
        if not locked.online:
            raise UsageError(f"Robot {locked.name} is offline: it cannot be sent to charge.")
        if locked.state == RobotState.CHARGING:
            raise UsageError(f"Robot {locked.name} is charging already.")
        if ActionType.START_CHARGING not in _factsheet_action_types(locked.factsheet):
            raise UsageError(
                f"Robot {locked.name} cannot be sent to charge: its factsheet lists no startCharging."
            )
        locked.charge_requested = True
        locked.save(update_fields=["charge_requested", "updated_at"])
        write_record(actor=actor, action=WriteAction.ROBOT_CHARGE, object_name=locked.name)
        request_assignment()  # the run that plans the stations
    return locked


def _factsheet_action_types(factsheet: Mapping[str, Any] | None) -> set[str]:
    """The action types a stored factsheet lists (protocolFeatures.agvActions; mobileRobotActions in 3.0)."""
    features = (factsheet or {}).get("protocolFeatures") or {}
    actions = features.get("agvActions") or features.get("mobileRobotActions") or []
    return {action.get("actionType") for action in actions if isinstance(action, Mapping)}


def robot_map_action(
    *,
    actor: str,
    robot: Robot,
    action: MapAction,
    map_id: str,
    map_version: str,
    map_download_link: str | None = None,
    map_hash: str | None = None,
) -> InstantAction:
    """Ask the robot to download, enable or delete a map: an instant action its next step sends and
    tracks until the robot reports it FINISHED or FAILED. Only robots of VDA 5050 2.1 and later have maps."""
    with transaction.atomic():
        locked = lock_row(robot)
        if not has_maps(locked.protocol_version):
            raise UsageError(
                f"Robot {locked.name} speaks VDA 5050 {locked.protocol_version}, which has no map actions "
                "(maps came with 2.1.0)."
            )
        try:
            parameters = map_action_parameters(
                action,
                map_id=map_id,
                map_version=map_version,
                map_download_link=map_download_link,
                map_hash=map_hash,
            )
        except ProtocolError as error:
            raise UsageError(error.reason) from error
        queued = _queue_instant_action(locked, action, parameters)
        write_record(actor=actor, action=WriteAction.ROBOT_MAP, object_name=locked.name)
        request_steps([locked.name])
    return queued


def _queue_instant_action(
    robot: Robot, action_type: str, parameters: dict[str, Any] | None = None
) -> InstantAction:
    """Put an instant action in the robot's outbox; the robot's next step sends it and tracks it."""
    action = instant_action(robot.name, action_type, parameters)
    action.save(force_insert=True)
    return action


def instant_action(robot: str, action_type: str, parameters: dict[str, Any] | None = None) -> InstantAction:
    return InstantAction(
        action_id=new_action_id(f"{robot}-{action_type}"),
        robot_id=robot,
        action_type=action_type,
        parameters=parameters,
    )


def _robot_spec_fields(spec: Mapping[str, Any], *, robot_name: str, current: Robot | None) -> dict[str, Any]:
    """Robot model fields from a spec in the API's shape, with the defaults of the fields it omits.

    A protocol setting (version, instant actions key) the spec omits keeps what the robot showed it
    speaks (LEARNED); one it gives is the operator's, which nothing learned overrides."""
    unknown = set(spec) - SPEC_KEYS
    if unknown:
        raise UsageError(f"Unknown robot spec fields {sorted(unknown)}; allowed: {sorted(SPEC_KEYS)}.")
    battery = spec.get("battery") or {}
    vda5050 = spec.get("vda5050") or {}
    return {
        "labels": list(spec.get("labels", _default("labels"))),
        "battery_critical_level": battery.get("critical_level", _default("battery_critical_level")),
        "battery_recommended_minimum": battery.get(
            "recommended_minimum", _default("battery_recommended_minimum")
        ),
        "battery_recommended_maximum": battery.get(
            "recommended_maximum", _default("battery_recommended_maximum")
        ),
        "heartbeat_timeout": spec.get("heartbeat_timeout", _default("heartbeat_timeout")),
        "switch_teleop": spec.get("switch_teleop", _default("switch_teleop")),
        "interface_name": vda5050.get("interface_name", _default("interface_name")),
        "manufacturer": vda5050.get("manufacturer", _default("manufacturer")),
        # The reference's topics use the robot name as serial number.
        "serial_number": vda5050.get("serial_number", robot_name),
        **_protocol_setting(vda5050, "version", "protocol_version", current),
        **_protocol_setting(vda5050, "instant_actions_key", "instant_actions_key", current),
    }


def _protocol_setting(
    vda5050: Mapping[str, Any], key: str, field: str, current: Robot | None
) -> dict[str, Any]:
    """`field` and `<field>_source` from the spec's `key`, or what the robot has learned, or the default."""
    source = f"{field}_source"
    if key in vda5050:
        return {field: vda5050[key], source: SettingSource.OPERATOR}
    if current is not None and getattr(current, source) == SettingSource.LEARNED:
        return {field: getattr(current, field), source: SettingSource.LEARNED}
    return {field: _default(field), source: SettingSource.DEFAULT}


def _default(field: str) -> Any:
    return Robot._meta.get_field(field).get_default()


def _identity_taken(fields: Mapping[str, Any]) -> UsageError:
    return UsageError(
        f"Another robot already uses the VDA 5050 identity interface_name={fields['interface_name']}, "
        f"manufacturer={fields['manufacturer']}, serial_number={fields['serial_number']}."
    )

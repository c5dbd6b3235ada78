"""Changes to stations, each in one transaction with its write record. The reservations (status) are the
dispatch core's: these only refuse a spec or a deletion that would strand robots holding the station."""

from collections.abc import Mapping
from typing import Any

from django.db import IntegrityError, transaction

from access.choices import WriteAction
from access.services import write_record
from kit.api.errors import ObjectError, UsageError
from kit.api.names import object_name_for_create
from kit.api.rows import lock_row
from stations.models import Station


def station_create(*, actor: str, name: str | None, prefix: str | None, spec: Mapping[str, Any]) -> Station:
    """A new station from a spec in the API's shape (StationSpecSerializer's validated data). Without a name
    it is named `<prefix>-<random id>` or a random id; a duplicate name raises the reference's ObjectError."""
    station_name = object_name_for_create(name=name, prefix=prefix, what="Station name")
    station = Station(name=station_name, **_station_spec_fields(spec))
    try:
        with transaction.atomic():
            station.save(force_insert=True)
            write_record(actor=actor, action=WriteAction.STATION_CREATE, object_name=station.name)
    except IntegrityError as error:
        raise ObjectError.exists("station", station_name) from error
    return station


def station_update_spec(*, actor: str, station: Station, spec: Mapping[str, Any]) -> Station:
    """Replace the station's whole spec (PUT). Its capacity may not fall below the robots holding it."""
    fields = _station_spec_fields(spec)
    with transaction.atomic():
        locked = lock_row(station)
        if fields["capacity"] < len(locked.reservations):
            raise UsageError(
                f"Station {locked.name} is held by {len(locked.reservations)} robots "
                f"({', '.join(locked.reservations)}): its capacity cannot fall below that."
            )
        for field, value in fields.items():
            setattr(locked, field, value)
        locked.save(update_fields=[*fields, "updated_at"])
        write_record(actor=actor, action=WriteAction.STATION_UPDATE, object_name=locked.name)
    return locked


def station_delete(*, actor: str, station: Station) -> None:
    """Delete the station, unless robots hold or reserve it (they would be left on their way to nothing)."""
    with transaction.atomic():
        locked = lock_row(station)
        if locked.reservations:
            raise UsageError(
                f"Station {locked.name} is held by {', '.join(locked.reservations)}: it can be deleted "
                "once they have left it."
            )
        write_record(actor=actor, action=WriteAction.STATION_DELETE, object_name=locked.name)
        locked.delete()


def _station_spec_fields(spec: Mapping[str, Any]) -> dict[str, Any]:
    """Station model fields from a validated spec in the API's shape."""
    pose = spec["pose"]
    return {
        "kind": spec["kind"],
        "pose_x": pose["x"],
        "pose_y": pose["y"],
        "pose_theta": pose["theta"],
        "pose_map_id": pose["map_id"],
        "robot_types": list(spec["robot_types"]),
        "capacity": spec["capacity"],
    }

"""Changes to zone sets, each in one transaction with its write record. A zone set's content is immutable
(VDA 5050: per zoneSetId); what changes is which set of its map is enabled, at most one."""

from collections.abc import Mapping
from typing import Any

from django.db import IntegrityError, transaction
from django.utils import timezone

from access.choices import WriteAction
from access.services import write_record
from kit.api.errors import ObjectError, UsageError
from kit.api.names import object_name_for_create
from kit.api.rows import lock_row
from kit.wake import request_zones_plan
from zones.models import ZoneGrant, ZoneSet
from zones.selectors import zone_set_enabled_on


def zone_set_create(*, actor: str, name: str | None, prefix: str | None, spec: Mapping[str, Any]) -> ZoneSet:
    """A new, disabled zone set from a spec in the API's shape (ZoneSetSpecSerializer's validated data).
    Without a name it is named `<prefix>-<random id>` or a random id; a duplicate name raises the
    reference's ObjectError."""
    zone_set_name = object_name_for_create(name=name, prefix=prefix, what="Zone set name")
    zone_set = ZoneSet(
        name=zone_set_name,
        map_id=spec["map_id"],
        description=spec["description"],
        zones=[dict(zone) for zone in spec["zones"]],
    )
    try:
        with transaction.atomic():
            zone_set.save(force_insert=True)
            write_record(actor=actor, action=WriteAction.ZONE_SET_CREATE, object_name=zone_set.name)
    except IntegrityError as error:
        raise ObjectError.exists("zone_set", zone_set_name) from error
    return zone_set


def zone_set_enable(*, actor: str, zone_set: ZoneSet) -> ZoneSet:
    """Make the zone set its map's enabled one; the set enabled before on that map is disabled in the same
    transaction. The map's sets are locked in name order, so concurrent enables of one map take turns."""
    with transaction.atomic():
        map_sets = list(ZoneSet.objects.select_for_update().filter(map_id=zone_set.map_id).order_by("name"))
        locked = next((each for each in map_sets if each.name == zone_set.name), None)
        if locked is None:
            raise ObjectError.not_found_to_change(zone_set.name)
        for other in map_sets:
            if other.enabled and other.name != locked.name:
                other.enabled = False
                other.save(update_fields=["enabled", "updated_at"])
        if not locked.enabled:
            locked.enabled = True
            locked.save(update_fields=["enabled", "updated_at"])
        write_record(actor=actor, action=WriteAction.ZONE_SET_ENABLE, object_name=locked.name)
        request_zones_plan()  # its RELEASE zones are minded from now on
    return locked


def zone_set_disable(*, actor: str, zone_set: ZoneSet) -> ZoneSet:
    """Disable the zone set: its map then has no zones until another set is enabled."""
    with transaction.atomic():
        locked = lock_row(zone_set)
        if locked.enabled:
            locked.enabled = False
            locked.save(update_fields=["enabled", "updated_at"])
        write_record(actor=actor, action=WriteAction.ZONE_SET_DISABLE, object_name=locked.name)
        request_zones_plan()  # its grants go, and what orders held back for them is released
    return locked


def zone_set_delete(*, actor: str, zone_set: ZoneSet) -> None:
    """Delete a disabled zone set; the enabled one of a map is refused (its map would lose its zones
    unnoticed: enable another set or disable it first)."""
    with transaction.atomic():
        locked = lock_row(zone_set)
        if locked.enabled:
            raise UsageError(
                f"Zone set {locked.name} is enabled on map {locked.map_id}: disable it or enable another set "
                "of the map before deleting it."
            )
        write_record(actor=actor, action=WriteAction.ZONE_SET_DELETE, object_name=locked.name)
        locked.delete()


def zone_grant_revoke(*, actor: str, zone_set: ZoneSet, robot: str, zone_id: str) -> None:
    """Take back the grant of zone `zone_id` of the enabled `zone_set` that `robot` holds; the next zone plan
    run (asked for here) applies it (`dispatch.zones.decide`): a robot not yet in the zone loses it and waits,
    one already in it (or whose released base crosses it) keeps it until it has left, 3.0 robots are answered
    REVOKED. A zone set not enabled (its map's grants are the enabled set's), a zone the set lacks, or one
    the robot holds no grant of, is refused."""
    if not zone_set.enabled:
        raise UsageError(
            f"Zone set {zone_set.name} is not enabled: "
            f"the grants of map {zone_set.map_id} are its enabled set's."
        )
    if not any(zone["zone_id"] == zone_id for zone in zone_set.zones):
        raise UsageError(f"Zone set {zone_set.name} has no zone {zone_id}.")
    with transaction.atomic():
        revoked = ZoneGrant.objects.filter(
            map_id=zone_set.map_id, zone_id=zone_id, robot=robot, revoked_at__isnull=True
        ).update(revoked_at=timezone.now())
        if not revoked:
            raise UsageError(f"Robot {robot} holds no grant of zone {zone_id} of zone set {zone_set.name}.")
        write_record(actor=actor, action=WriteAction.ZONE_GRANT_REVOKE, object_name=zone_set.name)
        request_zones_plan()


def zone_grant_revoke_for(*, actor: str, grant: ZoneGrant) -> None:
    """`zone_grant_revoke` of a grant as stored (the admin's action), through its map's enabled zone set."""
    zone_set = zone_set_enabled_on(map_id=grant.map_id)
    if zone_set is None:
        raise UsageError(f"Map {grant.map_id} has no enabled zone set: the grant of {grant} goes by itself.")
    zone_grant_revoke(actor=actor, zone_set=zone_set, robot=grant.robot, zone_id=grant.zone_id)

"""Operator view of zone sets: a new set's content is checked by the API's own spec serializer; a set's
content never changes afterwards (VDA 5050), so an existing set is read-only here; enabling, disabling and
deleting go through the services."""

from collections.abc import Iterable
from typing import Any

from django.contrib import admin
from django.db.models import QuerySet
from django.http import HttpRequest
from django.utils.safestring import SafeString

from access.authentication import request_actor
from kit.admin import ServiceAdmin, SpecAdminForm, call_service_for_each, html_table, spec_validated
from zones.api.serializers import ZoneSetSpecSerializer
from zones.models import ZoneGrant, ZoneSet
from zones.selectors import zone_grants
from zones.services import (
    zone_grant_revoke_for,
    zone_set_create,
    zone_set_delete,
    zone_set_disable,
    zone_set_enable,
)

SPEC_FIELDS = ("map_id", "description", "zones")


class ZoneSetAdminForm(SpecAdminForm):
    """A new zone set, checked by ZoneSetSpecSerializer so that the admin accepts exactly what the API
    accepts; `spec` then holds it in the services' shape."""

    class Meta:
        model = ZoneSet
        fields = ("name", *SPEC_FIELDS)

    def clean(self) -> dict[str, Any]:
        cleaned_data = super().clean()
        if self.errors or not self.instance._state.adding:  # an existing set's content is read-only
            return cleaned_data
        self.spec = spec_validated(self, ZoneSetSpecSerializer, {f: cleaned_data[f] for f in SPEC_FIELDS})
        return cleaned_data


@admin.register(ZoneSet)
class ZoneSetAdmin(ServiceAdmin):
    form = ZoneSetAdminForm
    list_display = ("name", "map_id", "enabled", "zone_count", "description", "updated_at")
    list_filter = ("enabled", "map_id")
    search_fields = ("name", "description")
    ordering = ("name",)
    list_per_page = 50
    actions = ("enable", "disable")
    fieldsets = (
        (None, {"fields": ("name",)}),
        ("Content", {"fields": SPEC_FIELDS}),
        ("Status", {"fields": ("enabled", "grants")}),
        ("Timestamps", {"fields": ("created_at", "updated_at")}),
    )

    def get_readonly_fields(self, request: HttpRequest, obj: ZoneSet | None = None) -> tuple[str, ...]:
        content = ("name", *SPEC_FIELDS) if obj is not None else ()
        return (*content, "enabled", "grants", "created_at", "updated_at")

    @admin.display(description="grants")
    def grants(self, zone_set: ZoneSet) -> SafeString | str:
        """Who holds its RELEASE zones (Zone grants: revoke one there)."""
        grants = list(zone_grants(map_id=zone_set.map_id)) if zone_set.enabled else []
        if not grants:
            return "none"
        return html_table(
            ("zone", "robot", "granted at", "revoked at"),
            ((g.zone_id, g.robot, g.granted_at, g.revoked_at or "") for g in grants),
        )

    @admin.display(description="zones")
    def zone_count(self, zone_set: ZoneSet) -> int:
        return len(zone_set.zones)

    def save_model(self, request: HttpRequest, obj: ZoneSet, form: ZoneSetAdminForm, change: bool) -> None:
        if not change:  # an existing set is read-only: nothing of it can have changed
            zone_set_create(actor=request_actor(request), name=obj.name, prefix=None, spec=form.spec)

    def delete_queryset(self, request: HttpRequest, queryset: Iterable[ZoneSet]) -> None:
        # An enabled set is refused (a warning), the others deleted.
        call_service_for_each(
            self,
            request,
            queryset,
            lambda zone_set: zone_set_delete(actor=request_actor(request), zone_set=zone_set),
            "Deleted",
        )

    @admin.action(description="Enable on its map (disables the map's other set)")
    def enable(self, request: HttpRequest, queryset: QuerySet[ZoneSet]) -> None:
        call_service_for_each(
            self,
            request,
            queryset,
            lambda zone_set: zone_set_enable(actor=request_actor(request), zone_set=zone_set),
            "Enabled",
        )

    @admin.action(description="Disable")
    def disable(self, request: HttpRequest, queryset: QuerySet[ZoneSet]) -> None:
        call_service_for_each(
            self,
            request,
            queryset,
            lambda zone_set: zone_set_disable(actor=request_actor(request), zone_set=zone_set),
            "Disabled",
        )


@admin.register(ZoneGrant)
class ZoneGrantAdmin(admin.ModelAdmin):
    """Who holds which RELEASE zone, as the zone plan decided; an operator may take a grant back (the
    same service as POST /zone_set/{name}/revoke), nothing else is the operator's to edit."""

    list_display = ("robot", "map_id", "zone_id", "granted_at", "revoked_at")
    list_filter = ("map_id", "zone_id")
    search_fields = ("robot",)
    ordering = ("map_id", "zone_id", "granted_at")
    list_per_page = 50
    actions = ("revoke",)
    readonly_fields = list_display

    def has_add_permission(self, request: HttpRequest) -> bool:
        return False

    def has_change_permission(self, request: HttpRequest, obj: ZoneGrant | None = None) -> bool:
        return obj is None and super().has_change_permission(request)  # the list's action, no edits

    def has_delete_permission(self, request: HttpRequest, obj: ZoneGrant | None = None) -> bool:
        return False

    @admin.action(
        description="Revoke (a robot already inside keeps it until it has left)", permissions=["change"]
    )
    def revoke(self, request: HttpRequest, queryset: QuerySet[ZoneGrant]) -> None:
        call_service_for_each(
            self,
            request,
            queryset,
            lambda grant: zone_grant_revoke_for(actor=request_actor(request), grant=grant),
            "Revoked",
        )

"""Operator view of stations: the spec is editable (checked by the API's own spec serializer), the
reservations are the dispatch core's; creating, changing and deleting go through the services."""

from collections.abc import Iterable
from typing import Any

from django.contrib import admin
from django.http import HttpRequest

from access.authentication import request_actor
from kit.admin import ServiceAdmin, SpecAdminForm, call_service_for_each, pose_text, spec_validated
from stations.api.serializers import StationSpecSerializer
from stations.models import Station
from stations.services import station_create, station_delete, station_update_spec

POSE_FIELDS = ("pose_x", "pose_y", "pose_theta", "pose_map_id")
SPEC_FIELDS = ("kind", POSE_FIELDS, "robot_types", "capacity")


def station_spec(values: dict[str, Any]) -> dict[str, Any]:
    """Spec fields (by model field name) in the API's spec shape, as the station services take them."""
    return {
        "kind": values["kind"],
        "pose": {field.removeprefix("pose_"): values[field] for field in POSE_FIELDS},
        "robot_types": values["robot_types"],
        "capacity": values["capacity"],
    }


class StationAdminForm(SpecAdminForm):
    """The spec of a station, checked by StationSpecSerializer so that the admin accepts exactly what the
    API accepts; `spec` then holds it in the services' shape."""

    class Meta:
        model = Station
        fields = ("name", "kind", *POSE_FIELDS, "robot_types", "capacity")

    def clean(self) -> dict[str, Any]:
        cleaned_data = super().clean()
        if self.errors:
            return cleaned_data
        self.spec = spec_validated(self, StationSpecSerializer, station_spec(cleaned_data))
        return cleaned_data


@admin.register(Station)
class StationAdmin(ServiceAdmin):
    form = StationAdminForm
    list_display = ("name", "kind", "pose", "robot_types", "capacity", "reservations", "updated_at")
    list_filter = ("kind", "pose_map_id")
    search_fields = ("name",)
    ordering = ("name",)
    list_per_page = 50
    fieldsets = (
        (None, {"fields": ("name",)}),
        ("Spec", {"fields": SPEC_FIELDS}),
        ("Status", {"fields": ("reservations",)}),
        ("Timestamps", {"fields": ("created_at", "updated_at")}),
    )

    def get_readonly_fields(self, request: HttpRequest, obj: Station | None = None) -> tuple[str, ...]:
        changing = ("name",) if obj is not None else ()
        return (*changing, "reservations", "created_at", "updated_at")

    @admin.display(description="pose")
    def pose(self, station: Station) -> str:
        return pose_text(station)

    def save_model(self, request: HttpRequest, obj: Station, form: StationAdminForm, change: bool) -> None:
        if not change:
            station_create(actor=request_actor(request), name=obj.name, prefix=None, spec=form.spec)
        elif form.changed_data:
            station_update_spec(actor=request_actor(request), station=obj, spec=form.spec)

    def delete_queryset(self, request: HttpRequest, queryset: Iterable[Station]) -> None:
        # A station robots hold is refused (a warning), the others deleted.
        call_service_for_each(
            self,
            request,
            queryset,
            lambda station: station_delete(actor=request_actor(request), station=station),
            "Deleted",
        )
